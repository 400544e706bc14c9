"""The plan: one decision per effect, each within its share of the tolerance.

Errors are those of one image metric: ``de2000`` = mean CIEDE2000 of the tone-mapped sky,
``radiance_rel`` = mean relative luminance error. The error of an effect in a scene is
the worst over the view-elevation bands the cameras see (sky seen directly) and the
error of the light on a horizontal surface (always: the sky lights the scene); in the
effect table, values at the scene's sun elevation are interpolated linearly between the
two nearest measured elevations. The tolerance is a budget split in fixed shares
(:data:`SHARES`), and errors are added (a conservative bound when errors behave like
distances); each decision spends only its own share, so tightening the tolerance can only
turn effects on and refine the knobs. :func:`plan` takes these steps, in this order:

1. :func:`decide_aerial_perspective` (35 %): if leaving out the air between the camera
   and the farthest object costs more than its share, volume shells are needed;
2. :func:`decide_physical_effects` (35 %): the Earth's shadow, ground reflection, ozone
   and aerosols are left out in order of increasing measured error while their sum fits
   the share: the simplest atmosphere that looks the same;
3. numerical knobs: :func:`decide_scattering_orders` (the fewest orders, 15 %),
   :func:`decide_spectral_resolution` (the coarsest spectral grid, 10 %) and, with
   shells, :func:`decide_volume_layers` (the fewest layers, 5 %) whose measured error fits;
4. :func:`decide_sun_disc` (drawn when the sky is seen and the sun is above the horizon
   within the cameras' elevation range) and :func:`decide_angular_resolution` (one
   environment pixel no larger than a camera pixel; a sky seen only as lighting gets a
   small image).

User overrides are honoured as given and their measured error is counted in the
prediction. How a plan is carried out (the atmosphere and the marcher's settings it
implies) is :mod:`skymodel.planner.apply`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from skymodel.errors import SkymodelInputError
from skymodel.optics.shells import TWILIGHT_MIN_LAYERS  # the add-on's floor below the horizon
from skymodel.planner import apply
from skymodel.planner.scene import TOP_ALTITUDE_M, SceneDescription
from skymodel.planner.tables import (_METRIC, _WL_COUNT_STEP, ACCURACY_PATH, EFFECTS_PATH, _AccuracyTable,
                                     _EffectTable, load_table, visible_bands)
from skymodel.render.skyview import TABLE_MIN_PIXELS  # images this large resample the sky-view table

#: Physical effects the planner may leave out, with the effect-table row that measures it.
PHYSICAL = {"earth_shadow": "earth_shadow_off", "ground_reflection": "ground_albedo_0", "ozone": "ozone_off",
            "aerosols": "aerosols_off"}
#: Most volume layers the Blender add-on builds.
MAX_LAYERS = 24
#: Fixed shares of the tolerance: each decision spends only its own share, so a tighter
#: tolerance can only turn effects on and refine the knobs (no decision loosens because
#: another one changed), and the shares add up to the whole tolerance.
SHARES = {"aerial_perspective": 0.35, "physical": 0.35, "orders": 0.15, "spectral": 0.1, "layers": 0.05}
PHYSICAL_SHARE = SHARES["physical"]
#: Environment image widths the planner picks from (height = width / 2).
MIN_ENV_WIDTH, MAX_ENV_WIDTH = 256, 8192
#: Build time of an environment image per pixel (s/px), by quality, beyond the pixels of the
#: render whose measured time the prediction starts from, for images that march every pixel
#: (fewer than :data:`TABLE_MIN_PIXELS`): the add-on's build reduced to RGB
#: (``render_sky_reduced``). Measured: ``python benchmarks/bench_planner.py --pixels``
#: (rural, June, 5 nm, sun 30, the solve reused; median CPU seconds of 3 at 256 and 512 px
#: wide, fitted; b6e4cde, 2026-11-26, load 6-7). The accuracy table's preset render marches
#: full spectra, 1.25e-5 s/px at final: its 512x256 pixels cost 1.3 s more than the constant
#: says, 5 % of a final render. ``reference`` was not measured: final's.
ENV_SECONDS_PER_PIXEL = {"preview": 2.4e-6, "final": 2.7e-6, "reference": 2.7e-6}
#: The same for images of :data:`TABLE_MIN_PIXELS` pixels or more, which resample the sky-view
#: table (:mod:`skymodel.render.skyview`): each pixel costs only its lookup and reduction
#: (the same run at 1024, 2048 and 4096 px wide).
ENV_SECONDS_PER_PIXEL_TABLE = {"preview": 7.4e-7, "final": 5.8e-7, "reference": 5.8e-7}
#: The sky-view table's own march (s), by quality, paid once by images of
#: :data:`TABLE_MIN_PIXELS` pixels or more (the intercept of their times less that of the
#: marched sizes; the same run).
ENV_TABLE_FIXED_S = {"preview": 0.35, "final": 1.65, "reference": 1.65}
#: Width (px) of the render whose time the effect table records (64x32).
EFFECT_TABLE_WIDTH = 64
#: Width (px) of the accuracy table's preset renders when the table does not say (512x256).
PRESET_WIDTH = 512
#: The add-on's environment build costs this many times the effect table's render (its fixed
#: part: the add-on's marcher settings and 41 wavelengths against the table's): 5.3 s (the fixed
#: part of the widths above) against the table's 2.37 s at sun 10 degrees. Used only when the
#: accuracy table (whose ``final`` preset time sets the scale) is absent.
ENV_FIXED_PER_TABLE = 2.2
#: Cycles CPU render time of the volume shells, s per pixel, sample and layer (volume bounces 8):
#: measured 64x32 px, rural, sun 10 degrees, 2-core machine, bpy 5.0.1: 7.5 s at 8 layers and
#: 15.5 s at 16 layers with 32 samples (time grows with the layers; 1.15e-4 s per pixel and
#: sample at 8 layers). docs/planner.md.
VOLUME_SECONDS_PER_PIXEL_SAMPLE_LAYER = 1.44e-5

#: The effects a plan decides, in the order a plan lists them.
EFFECT_NAMES = ("multiple_scattering", "aerosols", "ozone", "earth_shadow", "ground_reflection", "sun_disc",
                "aerial_perspective", "spectral_resolution", "angular_resolution")


@dataclass(frozen=True)
class Decision:
    """One effect: on/off, its value, why, and the measured error and time it implies.

    ``predicted_error`` is the error this choice adds (tolerance units) and
    ``predicted_time_s`` the measured time of the table's render with this choice
    (``None`` where the choice changes no render time); ``source`` names the table row."""

    name: str
    on: bool
    value: object
    reason: str
    predicted_error: float = 0.0
    predicted_time_s: float | None = None
    source: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "on": self.on, "value": self.value, "reason": self.reason,
                "predicted_error": self.predicted_error, "predicted_time_s": self.predicted_time_s,
                "source": self.source}


@dataclass(frozen=True)
class Plan:
    """The plan: one :class:`Decision` per effect (``plan["ozone"]``) and the totals."""

    scene: SceneDescription
    decisions: dict
    predicted_error: float
    predicted_time_s: float
    predicted_time_everything_s: float
    time_basis: str
    tables: dict = field(default_factory=dict)
    #: what :attr:`predicted_time_s` stands for: ``time_fixed_scale`` times it is the time of a
    #: render ``time_base_width`` x ``time_base_width / 2`` (:func:`environment_build_time`)
    time_fixed_scale: float = 1.0
    time_base_width: int = 64

    def __getitem__(self, name) -> Decision:
        return self.decisions[name]

    def __iter__(self):
        return iter(self.decisions.values())

    @property
    def mode(self) -> str:
        """``"volumetric"`` when aerial perspective needs volume shells, else ``"environment"``."""
        return "volumetric" if self["aerial_perspective"].on else "environment"

    @property
    def wavelength_step_nm(self) -> float:
        return float(self["spectral_resolution"].value)

    @property
    def orders(self) -> int | None:
        """Scattering orders for :class:`~skymodel.render.marcher.MarchSettings` (None: until converged)."""
        ms = self["multiple_scattering"]
        return 1 if not ms.on else ms.value

    @property
    def n_layers(self) -> int | None:
        ap = self["aerial_perspective"]
        return ap.value["n_layers"] if ap.on else None

    @property
    def environment_width(self) -> int:
        """The width the add-on builds (what :func:`decide_angular_resolution` chose within the time budget)."""
        return int(self["angular_resolution"].value)

    @property
    def within_tolerance(self) -> bool:
        return self.predicted_error <= self.scene.tolerance

    @property
    def predicted_build_s(self) -> float:
        """Predicted seconds of the sky's build: the environment at its width, or the shells'
        Cycles render of one frame (the largest of the decisions' times)."""
        d = self["aerial_perspective"] if self.mode == "volumetric" else self["angular_resolution"]
        return float(d.predicted_time_s) if d.predicted_time_s is not None else float(self.predicted_time_s)

    def predicted_environment_s(self, width: int, everything_on: bool = False) -> float:
        """Predicted seconds to build this plan's environment (or, ``everything_on``, the
        build with every effect on) at the scene's quality, ``width`` x ``width / 2``: the
        planner's own :func:`environment_build_time`, as :func:`decide_angular_resolution`
        uses it. A cold build: the multiple-scattering solve is included."""
        t = self.predicted_time_everything_s if everything_on else self.predicted_time_s
        return environment_build_time(t, width, self.time_fixed_scale, self.time_base_width, self.scene.quality)

    def warnings(self) -> list[str]:
        """What the user must be told before this plan is built ([] when nothing)."""
        out = []
        if not self.within_tolerance:
            out.append(f"predicted error {self.predicted_error:.2g} exceeds the tolerance "
                       f"{self.scene.tolerance:g} {self.scene.tolerance_kind}")
        b = self.scene.time_budget_s
        if b is not None and self.predicted_build_s > b:
            out.append(f"predicted {self.predicted_build_s:.0f} s exceeds the time budget {b:g} s")
        return out

    def march_settings(self, base=None):
        """``base`` (default: the ``final`` quality) with the plan's orders and Earth's
        shadow (:func:`skymodel.planner.apply.march_settings`)."""
        return apply.march_settings(self, base)

    def atmosphere_changes(self) -> dict:
        """The :class:`~skymodel.optics.atmosphere.Atmosphere` choices that leave out what
        the plan leaves out (:func:`skymodel.planner.apply.atmosphere_changes`)."""
        return apply.atmosphere_changes(self)

    def apply_to_atmosphere(self, atmosphere):
        """``atmosphere`` without the effects the plan leaves out (ozone, aerosols, ground
        reflection; :func:`skymodel.planner.apply.apply_to_atmosphere`)."""
        return apply.apply_to_atmosphere(self, atmosphere)

    def summary(self) -> list[str]:
        """One line per decision (the add-on's panel shows them)."""
        lines = []
        for d in self:
            state = "on" if d.on else "off"
            val = "" if d.value in (None, True, False) else f" ({_fmt_value(d.value)})"
            lines.append(f"{d.name.replace('_', ' ')}: {state}{val}: {d.reason}")
        return lines

    def as_dict(self) -> dict:
        return {"mode": self.mode, "predicted_error": self.predicted_error,
                "within_tolerance": self.within_tolerance, "warnings": self.warnings(),
                "predicted_build_s": self.predicted_build_s, "predicted_time_s": self.predicted_time_s,
                "predicted_time_everything_s": self.predicted_time_everything_s, "time_basis": self.time_basis,
                "tolerance": {"kind": self.scene.tolerance_kind, "value": self.scene.tolerance},
                "decisions": {k: d.as_dict() for k, d in self.decisions.items()}, "tables": self.tables}


def _fmt_value(v):
    if isinstance(v, dict):
        return ", ".join(f"{k} {_fmt_value(x)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return "-".join(_fmt_value(x) for x in v)
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


# --------------------------------------------------------------------------- overrides


OVERRIDABLE = ("multiple_scattering", "aerosols", "ozone", "earth_shadow", "ground_reflection", "sun_disc",
               "aerial_perspective")
USER = "set by the user: "


def check_overrides(overrides) -> dict:
    """The user's decisions, validated: ``{effect: bool}`` for any of :data:`OVERRIDABLE`
    and ``{"n_layers": 1..MAX_LAYERS}``; entries that are None (the planner's choice) dropped."""
    out = {}
    for k, v in dict(overrides or {}).items():
        if k == "n_layers":
            if v is None:
                continue
            if isinstance(v, bool) or not float(v).is_integer() or not 1 <= int(v) <= MAX_LAYERS:
                raise SkymodelInputError("n_layers", v, f"an integer 1..{MAX_LAYERS} (or None: the planner's)")
            out[k] = int(v)
        elif k in OVERRIDABLE:
            if v is None:
                continue
            if not isinstance(v, (bool, np.bool_)):
                raise SkymodelInputError(k, v, "True (on), False (off) or None (the planner's choice)")
            out[k] = bool(v)
        else:
            raise SkymodelInputError("overrides", k, "one of: " + ", ".join(OVERRIDABLE + ("n_layers",)))
    return out


# --------------------------------------------------------------------------- the steps


@dataclass(frozen=True)
class _Planning:
    """What every step reads: the scene, the user's overrides, the tables and the
    scene's units (``unit`` names the tolerance in reasons, ``acc_metric`` the accuracy
    table's column for the sky seen, ``light_metric`` its lighting entry's), the reference
    render's time ``t_ref`` (s) at the sun elevation, and ``where`` the sky is used ("sky
    and lighting" or "lighting")."""

    scene: SceneDescription
    forced: dict
    eff: _EffectTable
    acc: _AccuracyTable | None
    unit: str
    acc_metric: str
    light_metric: str
    t_ref: float
    where: str

    @property
    def el(self) -> float:
        return self.scene.sun_elevation_deg

    @property
    def tol(self) -> float:
        return self.scene.tolerance

    @property
    def bands(self) -> list[str]:
        """The view-elevation bands the cameras see (none when the sky is only lighting)."""
        return visible_bands(self.scene)

    def acc_knob(self, knob) -> dict:
        """The accuracy table's {value: (error, time_s)} of ``knob`` for this scene (its
        sun, the bands its cameras see, the sky as its lighting)."""
        return self.acc.knob(knob, self.el, self.acc_metric, self.bands, self.light_metric)


def read_tables(effects, accuracy) -> tuple[_EffectTable, _AccuracyTable | None]:
    """The measured effect table (required) and accuracy table (optional), as paths or dicts."""
    eff_data = load_table(effects)
    if eff_data is None:
        raise SkymodelInputError("effects", effects, "the measured effect table (skymodel/data/presets/planner/effects.json: "
                                 "python benchmarks/bench_planner.py --write)")
    acc_data = load_table(accuracy)
    return _EffectTable(eff_data), (_AccuracyTable(acc_data) if acc_data else None)


def decide_aerial_perspective(ctx: _Planning) -> tuple[bool, float, Decision | None]:
    """Step 1: are volume shells needed? (needed, error of leaving out the air between
    the cameras and the farthest object, the decision when they are not needed; with
    shells the decision waits for :func:`decide_volume_layers`)."""
    d = ctx.scene.farthest_object_m
    ap_err = ctx.eff.aerial_error(ctx.el, d, ctx.scene.tolerance_kind)
    needed = ap_err > SHARES["aerial_perspective"] * ctx.tol
    t_vol = volume_render_time(ctx.scene, TWILIGHT_MIN_LAYERS if ctx.el < 0 else 8)
    budget = ctx.scene.time_budget_s
    too_slow = budget is not None and t_vol > budget
    shells = ctx.forced.get("aerial_perspective", needed and not too_slow)
    if shells:
        return True, ap_err, None
    share = SHARES["aerial_perspective"] * ctx.tol
    if d > 0 and needed and too_slow and "aerial_perspective" not in ctx.forced:
        reason = (f"objects {d / 1000:g} km away miss {ap_err:.2g} {ctx.unit} of haze without the air in between "
                  f"(its share of the tolerance: {share:.2g}), but volume shells would take about {t_vol:.0f} s a "
                  f"frame in Cycles ({ctx.scene.image_width}x{ctx.scene.image_height}, {ctx.scene.samples} samples), "
                  f"over the time budget of {budget:g} s: environment only")
    elif d > 0:
        reason = (f"nothing is farther than {d / 1000:g} km, where leaving out the air in between changes an "
                  f"object's colour by {ap_err:.2g} {ctx.unit} (its share of the tolerance: "
                  f"{share:.2g}): environment only, no volume shells")
    else:
        reason = "no object is visible, only the sky: environment only, no volume shells"
    reason = USER * ("aerial_perspective" in ctx.forced) + reason
    return False, ap_err, Decision("aerial_perspective", False, None, reason, ap_err, None,
                                   "effects.json aerial_perspective")


_PHYSICAL_TEXTS = {
    "earth_shadow": ("the Earth's shadow", "no visible part of the atmosphere is in it"),
    "ground_reflection": ("light reflected by the ground", "it barely brightens the sky"),
    "ozone": ("ozone absorption", "it barely tints the sky at this sun elevation"),
    "aerosols": ("aerosols", "the haze barely changes the sky"),
}


def decide_physical_effects(ctx: _Planning) -> list[Decision]:
    """Step 2: the Earth's shadow, ground reflection, ozone and aerosols, taken in order of
    increasing measured error and left out while the sum of the errors left out fits the
    physical share of the tolerance (the user's overrides honoured and counted)."""
    eff, el, scene, forced = ctx.eff, ctx.el, ctx.scene, ctx.forced
    phys = sorted(PHYSICAL, key=lambda k: eff.error(PHYSICAL[k], el, scene))
    phys_budget = PHYSICAL_SHARE * ctx.tol
    phys_spent = 0.0
    out = []
    for name in phys:
        e = eff.error(PHYSICAL[name], el, scene)
        what, why_off = _PHYSICAL_TEXTS[name]
        user = USER if name in forced else ""
        if forced.get(name, not phys_spent + e <= phys_budget) is False:
            phys_spent += e
            out.append(Decision(name, False, None,
                                f"{user}leaving out {what} changes the {ctx.where} by {e:.2g} {ctx.unit} at sun "
                                f"{el:g} degrees: {why_off}", e, eff.time(PHYSICAL[name], el),
                                f"effects.json {PHYSICAL[name]}"))
        else:
            extra = {"ozone": " (ozone's Chappuis absorption sets the blue of the twilight sky)" if el < 2 else "",
                     "earth_shadow": " (the shadow's edge crosses the sky)" if el < 2 else ""}.get(name, "")
            why = ("kept on" if user else "more than the share of the tolerance allows")
            out.append(Decision(name, True, None,
                                f"{user}leaving out {what} would change the {ctx.where} by {e:.2g} {ctx.unit} at sun "
                                f"{el:g} degrees: {why}{extra}", 0.0, ctx.t_ref, f"effects.json {PHYSICAL[name]}"))
    return out


def scattering_order_options(ctx: _Planning) -> dict:
    """{orders: (error, time_s or None, source)}: the effect table's orders_1..4, and
    the accuracy table's counts it lacks, their time scaled to the effect table's by the
    ratio to the accuracy table's own converged row (``orders=tolerance``, measured in the
    same run at the same size: its ``final`` preset time is another run's, at another size
    and load)."""
    eff, acc, el, t_ref = ctx.eff, ctx.acc, ctx.el, ctx.t_ref
    orders = {int(v): (eff.error(n, el, ctx.scene), eff.time(n, el), f"effects.json {n}")
              for v, n in eff.knob_rows("orders_").items()}
    if acc is not None:
        for v, (e, _) in ctx.acc_knob("orders").items():
            if isinstance(v, (int, float)) and float(v).is_integer():
                ratio = acc.time_ratio("orders", v, "tolerance")
                orders.setdefault(int(v), (e, t_ref * ratio if ratio else None, f"measured.json orders={v}"))
    return orders


def decide_scattering_orders(ctx: _Planning) -> tuple[Decision, float]:
    """Step 3a: the fewest scattering orders whose measured error fits their share (1:
    single scattering; none fits: until converged). Returns the decision and the time
    it saves against the reference render (s)."""
    orders = scattering_order_options(ctx)
    forced, tol, t_ref, unit, where = ctx.forced, ctx.tol, ctx.t_ref, ctx.unit, ctx.where
    chosen = None
    ms_user = USER if "multiple_scattering" in forced else ""
    if forced.get("multiple_scattering") is False:
        chosen = 1
    else:
        for n in sorted(orders):
            e, t, src = orders[n]
            if n == 1 and forced.get("multiple_scattering"):
                continue
            if e <= SHARES["orders"] * tol:
                chosen = n
                break
    n_conv = ctx.eff.reference_orders(ctx.el)
    if chosen == 1:
        e, t, src = orders[1]
        return Decision(
            "multiple_scattering", False, 1, f"{ms_user}light scattered more than once changes the {where} by only "
            f"{e:.2g} {unit}: single scattering", e, t, src), max(0.0, t_ref - t)
    if chosen is not None:
        e, t, src = orders[chosen]
        return Decision(
            "multiple_scattering", True, chosen, f"{ms_user}single scattering would be off by {orders[1][0]:.2g} "
            f"{unit}; {chosen} orders come within {e:.2g} of the converged {n_conv}", e, t, src), \
            (max(0.0, t_ref - t) if t is not None else 0.0)
    worst = orders[max(orders)][0] if orders else float("nan")
    return Decision(
        "multiple_scattering", True, None, f"{ms_user}even {max(orders) if orders else 0} orders leave "
        f"{worst:.2g} {unit}, so scattering is followed until it converges (about {n_conv} orders measured)",
        0.0, t_ref,
        "effects.json reference"), 0.0


def spectral_step_options(ctx: _Planning) -> dict:
    """{wavelength step (nm): (error, time_s or None, source)}: the reference's 10 nm,
    the effect table's steps and the accuracy table's wavelength counts."""
    eff, acc, el, t_ref = ctx.eff, ctx.acc, ctx.el, ctx.t_ref
    steps = {10.0: (0.0, t_ref, "effects.json reference (10 nm)")}
    for v, n in eff.knob_rows("wavelength_step_").items():
        steps[float(v)] = (eff.error(n, el, ctx.scene), eff.time(n, el), f"effects.json {n}")
    if acc is not None:
        for v, (e, _) in ctx.acc_knob("wavelengths").items():
            if v in _WL_COUNT_STEP:
                ratio = acc.time_ratio("wavelengths", v, 81)
                steps[_WL_COUNT_STEP[v]] = (e, t_ref * ratio if ratio else None, f"measured.json wavelengths={v}")
    return steps


def decide_spectral_resolution(ctx: _Planning) -> tuple[Decision, float]:
    """Step 3b: the coarsest wavelength step whose measured error fits its share (else
    the finest measured). Returns the decision and the time it saves (s)."""
    steps = spectral_step_options(ctx)
    best = min(steps)
    for s in sorted(steps, reverse=True):
        if steps[s][0] <= SHARES["spectral"] * ctx.tol:
            best = s
            break
    e, t, src = steps[best]
    # against the everything-on build's grid (the finest: the reference's 10 nm, or 5 nm from
    # the accuracy table), whose time is the reference's
    saved = max(0.0, ctx.t_ref - t) if t is not None else 0.0
    n_wl = int(round(400.0 / best)) + 1
    finer = [s for s in steps if s < best]
    return Decision(
        "spectral_resolution", True, best, f"a {best:g} nm grid ({n_wl} wavelengths) is off by {e:.2g} {ctx.unit}"
        + (", within its share of the tolerance" if finer else ", the finest measured"), e, t, src), saved


def volume_render_time(scene: SceneDescription, n_layers: int) -> float:
    """Predicted Cycles CPU seconds of one frame with ``n_layers`` volume shells
    (:data:`VOLUME_SECONDS_PER_PIXEL_SAMPLE_LAYER`)."""
    return float(VOLUME_SECONDS_PER_PIXEL_SAMPLE_LAYER * int(n_layers) * scene.image_width * scene.image_height
                 * scene.samples)


def environment_pixel_time(width: int, quality: str = "final") -> float:
    """Predicted seconds the pixels of a ``width`` x ``width / 2`` environment add to its
    build at ``quality``: :data:`ENV_SECONDS_PER_PIXEL` each when every pixel is marched (fewer
    than :data:`TABLE_MIN_PIXELS`), else the sky-view table's march (:data:`ENV_TABLE_FIXED_S`)
    and :data:`ENV_SECONDS_PER_PIXEL_TABLE` each."""
    px = int(width) * (int(width) // 2)
    if px < TABLE_MIN_PIXELS:
        return float(ENV_SECONDS_PER_PIXEL[quality] * px)
    return float(ENV_TABLE_FIXED_S[quality] + ENV_SECONDS_PER_PIXEL_TABLE[quality] * px)


def environment_build_time(t_table: float, width: int, fixed_scale: float = ENV_FIXED_PER_TABLE,
                           base_width: int = EFFECT_TABLE_WIDTH, quality: str = "final") -> float:
    """Predicted seconds to build an environment ``width`` x ``width / 2`` at ``quality`` from
    ``t_table``, the measured (or ratio-scaled) time of a render ``base_width`` x
    ``base_width / 2`` (the effect table's 64x32, or the accuracy table's preset at 512x256):
    that time times ``fixed_scale`` (:data:`ENV_FIXED_PER_TABLE` for the effect table's
    preview renders, 1 for the accuracy table's), less what that render's pixels cost, plus
    what the environment's pixels cost (:func:`environment_pixel_time`; the part that does
    not depend on the size is never taken below 0)."""
    fixed = max(0.0, fixed_scale * float(t_table) - environment_pixel_time(base_width, quality))
    return float(fixed + environment_pixel_time(width, quality))


def decide_volume_layers(ctx: _Planning, ap_err: float) -> Decision:
    """Step 3c (with volume shells only): the fewest layers whose measured error fits
    their share, at most :data:`MAX_LAYERS` (or the user's count); ``ap_err`` the error
    the shells remove (for the reason)."""
    eff, acc, el = ctx.eff, ctx.acc, ctx.el
    forced, d = ctx.forced, ctx.scene.farthest_object_m
    layers = {int(v): (eff.error(n, el, ctx.scene), eff.time(n, el), f"effects.json {n}")
              for v, n in eff.knob_rows("layers_").items()}
    if acc is not None:
        for v, (e, t) in ctx.acc_knob("layers").items():
            if isinstance(v, (int, float)) and float(v).is_integer() and int(v) <= MAX_LAYERS:
                layers[int(v)] = (e, t, f"measured.json layers={v}")
    floor = TWILIGHT_MIN_LAYERS if el < 0 else 1
    n_ok = [n for n in sorted(layers) if layers[n][0] <= SHARES["layers"] * ctx.tol and floor <= n <= MAX_LAYERS]
    n_l = n_ok[0] if n_ok else max(n for n in layers if n <= MAX_LAYERS)
    note = "" if n_ok else " (the most measured; its layering error exceeds the share of the tolerance)"
    if el < 0 and not n_ok and n_l < TWILIGHT_MIN_LAYERS:
        n_l = TWILIGHT_MIN_LAYERS
    if el < 0:
        note += (f" (the sun is below the horizon: at least {TWILIGHT_MIN_LAYERS} layers carry the sunlit upper "
                 "air within 10 %)")
    if "n_layers" in forced:
        n_l = forced["n_layers"]
        note = " (layer count set by the user)"
        if n_l not in layers:  # the nearest measured count at or below it (a fewer-layer error bounds it)
            below = [n for n in layers if n <= n_l]
            layers[n_l] = layers[max(below)] if below else layers[min(layers)]
    if n_l not in layers:
        below = [n for n in layers if n <= n_l]
        layers[n_l] = layers[max(below)] if below else layers[min(layers)]
    e, _, src = layers[n_l]
    t = volume_render_time(ctx.scene, n_l)
    top = TOP_ALTITUDE_M
    cam_lo = min(c.altitude_m for c in ctx.scene.cameras)
    return Decision(
        "aerial_perspective", True, {"n_layers": n_l, "altitude_range_m": (0.0, top)},
        USER * ("aerial_perspective" in forced) + f"objects {d / 1000:g} km away would be off by {ap_err:.2g} "
        f"{ctx.unit} without the air in between, so "
        f"{n_l} volume shells (edges at equal shares of extinction^0.3 from the ground to {top / 1000:g} km, "
        f"cameras from {cam_lo:g} m) carry the aerial perspective{note}; about {t:.0f} s a frame in Cycles "
        f"({ctx.scene.image_width}x{ctx.scene.image_height}, {ctx.scene.samples} samples)", e, t, src)


def decide_sun_disc(scene: SceneDescription, forced: dict) -> Decision:
    """Step 4a: the sun disc is drawn when the sky is seen and the sun is above the
    horizon (its upper limb: -0.27 degrees) inside the cameras' elevation range."""
    el = scene.sun_elevation_deg
    lo, hi = scene.elevation_range_deg
    sun_in_view = scene.sky_visible and el > -0.27 and lo <= el <= hi
    disc_on = forced.get("sun_disc", sun_in_view)
    if sun_in_view:
        where_sun = f"the sun is above the horizon and inside the cameras' view (elevations {lo:.1f}..{hi:.1f} degrees)"
    else:
        where_sun = "the sun is not in view (" + (
            "the sky only lights the scene" if not scene.sky_visible else "below the horizon" if el <= -0.27
            else f"outside the view elevations {lo:.1f}..{hi:.1f} degrees") + ")"
    disc = (", so its limb-darkened disc is drawn" if disc_on else ", so the sun lamp alone carries its light")
    return Decision("sun_disc", disc_on, None, USER * ("sun_disc" in forced) + where_sun + disc, 0.0, None, "geometry")


def decide_angular_resolution(scene: SceneDescription, t_table: float = 0.0,
                              fixed_scale: float = ENV_FIXED_PER_TABLE,
                              base_width: int = EFFECT_TABLE_WIDTH) -> Decision:
    """Step 4b: the environment image's width (pixels, a power of 2 in
    :data:`MIN_ENV_WIDTH`..:data:`MAX_ENV_WIDTH`, height = width / 2) such that one of its
    pixels is no larger than a camera pixel (the smallest when the sky only lights the
    scene), and no wider than the time budget allows; its predicted time is the build's at
    that width (:func:`environment_build_time` from the plan's time ``t_table`` of a render
    ``base_width`` wide)."""

    def build_time(w):
        return environment_build_time(t_table, w, fixed_scale, base_width, scene.quality)

    if not scene.sky_visible:
        return Decision("angular_resolution", True, MIN_ENV_WIDTH,
                        f"the sky only lights the scene, so a {MIN_ENV_WIDTH}x{MIN_ENV_WIDTH // 2} "
                        "environment carries its light (irradiance is a smooth integral over the sky)",
                        0.0, build_time(MIN_ENV_WIDTH), "geometry")
    px_deg = scene.max_fov_deg / max(scene.image_width, scene.image_height)
    need = 360.0 / px_deg
    w = int(min(MAX_ENV_WIDTH, max(MIN_ENV_WIDTH, 2 ** math.ceil(math.log2(need)))))
    sharp = w
    budget = scene.time_budget_s
    while budget is not None and w > MIN_ENV_WIDTH and build_time(w) > budget:
        w //= 2
    t = build_time(w)
    reason = (f"a camera pixel spans {px_deg:.3g} degrees ({scene.max_fov_deg:g} degree view over "
              f"{max(scene.image_width, scene.image_height)} px), so a {sharp}x{sharp // 2} environment keeps the sky "
              "at least as sharp as the picture" + (" (the largest the planner makes)" if sharp == MAX_ENV_WIDTH
                                                    else ""))
    if w < sharp:
        reason += (f"; it would take about {build_time(sharp):.0f} s, over the time budget of "
                   f"{budget:g} s, so {w}x{w // 2} (softer than the picture by {sharp // w}x)")
    reason += f"; about {t:.0f} s to build"
    return Decision("angular_resolution", True, w, reason, 0.0, t, "geometry")


def time_scale(ctx: _Planning, from_accuracy_table: bool) -> tuple[float, int]:
    """(fixed_scale, base_width) of :func:`environment_build_time` for the plan's times: the
    accuracy table's preset time (``from_accuracy_table``, as :func:`predicted_times` says)
    is a render of its preset camera's width (1x), the effect table's a 64-px preview render
    (:data:`ENV_FIXED_PER_TABLE`)."""
    if ctx.acc is not None and from_accuracy_table:
        return 1.0, int(ctx.acc.table.get("preset_camera", {}).get("width", PRESET_WIDTH))
    return ENV_FIXED_PER_TABLE, int(ctx.eff.table.get("camera", {}).get("width", EFFECT_TABLE_WIDTH))


def combined_saving(t_ref: float, *saved: float) -> float:
    """Seconds saved against ``t_ref`` by several knobs, each ``saved`` measured alone against the
    same reference: their time ratios multiply (the fewer orders are solved at the fewer
    wavelengths: a coarser grid leaves less for fewer orders to save). Summed, the savings counted
    that share twice: `product_noon` of docs/planner.md, 4 orders at 40 nm, predicted 0.22 of the
    reference's time, measured 0.43 (2.05x); multiplied, 0.34."""
    if t_ref <= 0:
        return 0.0
    kept = 1.0
    for s in saved:
        kept *= max(0.0, 1.0 - s / t_ref)
    return t_ref * (1.0 - kept)


def predicted_times(ctx: _Planning, saved: float) -> tuple[float, float, str, bool]:
    """(planned time, everything-on time, what they are, whether the accuracy table set them):
    the reference render's time less what the decisions save, on the effect table's machine
    and size, or scaled to the accuracy table's preset time of the scene's quality when that
    table has it."""
    eff, acc, el, t_ref = ctx.eff, ctx.acc, ctx.el, ctx.t_ref
    basis = (f"marcher time at the effect table's size ({eff.table.get('camera', {}).get('width', '?')}x"
             f"{eff.table.get('camera', {}).get('height', '?')}, preview tables) on its machine")
    t_plan = max(0.0, t_ref - saved)
    q = ctx.scene.quality
    from_accuracy_table = bool(acc is not None and acc.preset_time(q, el))
    if from_accuracy_table:
        scale = acc.preset_time(q, el) / t_ref
        t_plan, t_all = t_plan * scale, acc.preset_time(q, el)
        basis = f"the accuracy table's '{q}' preset time, scaled by the effect table's time ratios"
    else:
        t_all = t_ref
    return t_plan, t_all, basis, from_accuracy_table


# --------------------------------------------------------------------------- the plan


def plan(scene: SceneDescription, effects=EFFECTS_PATH, accuracy=ACCURACY_PATH, overrides=None) -> Plan:
    """Decide, effect by effect, what ``scene`` needs (see the module documentation).

    ``effects`` / ``accuracy``: the measured tables, as paths or dicts (defaults: the
    files in ``presets/``; the accuracy table is optional). ``overrides``: the user's
    decisions, ``{effect: True | False}`` for any of :data:`OVERRIDABLE` and
    ``{"n_layers": n}``; they are honoured as given, their measured error is counted, and
    the planner fits the remaining decisions into what is left of the tolerance.

    The predicted error is the sum of the decisions' errors, in the order they are made."""
    if not isinstance(scene, SceneDescription):
        raise SkymodelInputError("scene", type(scene).__name__, "a SceneDescription")
    forced = check_overrides(overrides)
    eff, acc = read_tables(effects, accuracy)
    de2000 = scene.tolerance_kind == "de2000"
    ctx = _Planning(scene, forced, eff, acc, unit="dE2000" if de2000 else "relative luminance error",
                    acc_metric="de2000_mean" if de2000 else "radiance_rel_rms",
                    light_metric=_METRIC[scene.tolerance_kind][1],  # the effect table's lighting key
                    t_ref=eff.time("reference", scene.sun_elevation_deg),
                    where="sky and lighting" if scene.sky_visible else "lighting")
    made: list[Decision] = []
    shells, ap_err, environment_only = decide_aerial_perspective(ctx)
    if environment_only is not None:
        made.append(environment_only)
    made += decide_physical_effects(ctx)
    orders, saved_orders = decide_scattering_orders(ctx)
    spectral, saved_spectral = decide_spectral_resolution(ctx)
    made += [orders, spectral]
    if shells:
        made.append(decide_volume_layers(ctx, ap_err))
    spent = 0.0
    for d in made:
        spent += d.predicted_error
    t_plan, t_all, basis, from_accuracy_table = predicted_times(
        ctx, combined_saving(ctx.t_ref, saved_orders, saved_spectral))
    fixed_scale, base_width = time_scale(ctx, from_accuracy_table)
    made += [decide_sun_disc(scene, forced), decide_angular_resolution(scene, t_plan, fixed_scale, base_width)]
    rank = {k: i for i, k in enumerate(EFFECT_NAMES)}
    decisions = {d.name: d for d in sorted(made, key=lambda d: rank[d.name])}
    tables = {"effects": eff.table.get("command", ""), "accuracy": acc.table.get("command", "") if acc else None}
    return Plan(scene, decisions, float(spent), float(t_plan), float(t_all), basis, tables, fixed_scale, base_width)
