"""Carrying out a plan: the atmosphere and the marcher settings a
:class:`~skymodel.planner.decisions.Plan` implies.

This is the one place that says how a plan changes what is simulated; the Blender
add-on (``blender_addon/scene_description.py::params_from_plan``) and
``benchmarks/bench_planner.py`` (which proves that plans pay) both go through it, so the
benchmark measures what the product builds:

* :func:`atmosphere_changes` / :func:`apply_to_atmosphere`: the effects the plan leaves
  out, as :class:`~skymodel.optics.atmosphere.Atmosphere` choices (aerosols, ozone,
  ground reflection);
* :func:`march_settings`: the marcher's scattering orders and Earth's shadow;
* the plan's numerical choices are read from the plan itself:
  :attr:`~skymodel.planner.decisions.Plan.wavelength_step_nm`, ``n_layers`` (volume
  shells, :func:`skymodel.optics.shells.volume_shells`), ``mode`` and ``environment_width``.

The planner does not import the renderer: the quality registry is read inside
:func:`march_settings` only.
"""

from __future__ import annotations

import dataclasses

#: Ozone column (Dobson units) standing for "no ozone": the atmosphere needs a positive
#: column. 1e-6 DU is 3e-9 of an ordinary 300 DU column, so its absorption (optical
#: depth < 1e-10 at the Chappuis peak) is below anything the renderer resolves.
NO_OZONE_DU = 1e-6


def atmosphere_changes(plan) -> dict:
    """Keyword arguments of :class:`~skymodel.optics.atmosphere.Atmosphere` (and of the
    add-on's ``SkyParams``, which names them alike) that leave out what ``plan`` leaves
    out; empty when it keeps everything.

    * aerosols off: no tropospheric (``aerosol="none"``, no ``aod550`` or
      ``turbidity``) and no stratospheric aerosol;
    * ozone off: a column of :data:`NO_OZONE_DU`;
    * ground reflection off: albedo 0.
    """
    changes = {}
    if not plan["aerosols"].on:
        changes.update(aerosol="none", aod550=None, turbidity=None, stratospheric="none")
    if not plan["ozone"].on:
        changes["ozone_du"] = NO_OZONE_DU
    if not plan["ground_reflection"].on:
        changes["albedo"] = 0.0
    return changes


def apply_to_atmosphere(plan, atmosphere):
    """``atmosphere`` (an :class:`~skymodel.optics.atmosphere.Atmosphere`) without the
    effects ``plan`` leaves out (:func:`atmosphere_changes`); the same object when it
    keeps them all."""
    changes = atmosphere_changes(plan)
    return dataclasses.replace(atmosphere, **changes) if changes else atmosphere


def march_settings(plan, base=None):
    """``base`` (a :class:`~skymodel.render.marcher.MarchSettings`; default: the
    ``final`` quality) with ``plan``'s scattering orders and Earth's shadow."""
    from skymodel.render.quality import QUALITY

    s = base or QUALITY["final"]
    return dataclasses.replace(s, orders=plan.orders, earth_shadow=bool(plan["earth_shadow"].on))
