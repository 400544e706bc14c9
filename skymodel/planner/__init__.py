"""The effect planner: simulate only what a scene calls for.

>>> from skymodel.planner import CameraView, SceneDescription, plan
>>> scene = SceneDescription(cameras=[CameraView(altitude_m=1.7, min_elevation_deg=-10, max_elevation_deg=30)],
...                          sun_elevation_deg=60, farthest_object_m=200, tolerance=2.0)
>>> p = plan(scene)
>>> p.mode, p["ozone"].on, p["ozone"].reason                                    # doctest: +SKIP

A :class:`SceneDescription` says what the picture needs (cameras, how far the farthest
visible object is, whether the sky is seen or only lights the scene, the sun elevation,
the image size, the tolerance). :func:`plan` returns a :class:`Plan`: one
:class:`Decision` per effect (multiple scattering and its orders, aerosols, ozone, the
Earth's shadow, ground reflection, the sun disc, aerial perspective through volume
shells, spectral and angular resolution), each with a one-sentence reason and the
predicted error and time, **read from measured tables**, never guessed:

* ``skymodel/data/presets/planner/effects.json`` (``benchmarks/bench_planner.py --write``): for sun
  elevations -6..90 degrees, the error of switching each effect off or simplifying it,
  for the sky seen directly (by view-elevation band) and for the sky as lighting, the
  aerial-perspective error vs distance, and each render's time;
* ``skymodel/data/presets/accuracy/measured.json`` (the renderer's accuracy benchmark, issue 3), when
  it exists: its ``wavelengths`` rows replace the effect table's spectral rows (and add
  5 nm), its ``orders`` rows add the counts the effect table lacks (5..8), its ``layers``
  rows replace the effect table's counts up to :data:`MAX_LAYERS`; its errors are against
  its own converged reference (so they include its baseline's error: the predictions should
  err high; docs/planner.md's proof says where they do not), and its ``final`` preset time is
  the time scale.
  It measures three scenes; values between them are interpolated linearly in the sun
  elevation of the scenes (``scenes[name].sun_elevation_deg``), and held constant beyond
  the first and last scene.

The modules, one job each:

* :mod:`skymodel.planner.scene`: :class:`CameraView`, :class:`SceneDescription` (the input,
  validated);
* :mod:`skymodel.planner.tables`: reading the measured tables and the look-ups in them;
* :mod:`skymodel.planner.decisions`: :func:`plan` and its steps, how the tolerance is
  shared between them (:data:`SHARES`), :class:`Decision` and :class:`Plan`;
* :mod:`skymodel.planner.apply`: carrying a plan out, the one way the add-on and the
  benchmark share (the atmosphere without what the plan leaves out, the marcher settings).

User overrides (:func:`plan`'s ``overrides``) are honoured as given and their measured
error is counted in the prediction.
"""

from skymodel.planner.apply import NO_OZONE_DU, apply_to_atmosphere, atmosphere_changes, march_settings
from skymodel.planner.decisions import (EFFECT_NAMES, MAX_ENV_WIDTH, MAX_LAYERS, MIN_ENV_WIDTH, OVERRIDABLE, PHYSICAL,
                                        PHYSICAL_SHARE, SHARES, USER, Decision, Plan, check_overrides, plan)
from skymodel.planner.scene import TOLERANCE_KINDS, TOP_ALTITUDE_M, CameraView, SceneDescription
from skymodel.planner.tables import ACCURACY_PATH, BANDS_DEG, EFFECTS_PATH, load_table, visible_bands

__all__ = ["ACCURACY_PATH", "BANDS_DEG", "EFFECTS_PATH", "EFFECT_NAMES", "MAX_ENV_WIDTH", "MAX_LAYERS",
           "MIN_ENV_WIDTH", "NO_OZONE_DU", "OVERRIDABLE", "PHYSICAL", "PHYSICAL_SHARE", "SHARES", "TOLERANCE_KINDS",
           "TOP_ALTITUDE_M", "USER", "CameraView", "Decision", "Plan", "SceneDescription", "apply_to_atmosphere",
           "atmosphere_changes", "check_overrides", "load_table", "march_settings", "plan", "visible_bands"]
