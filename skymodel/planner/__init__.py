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

How the planner reasons
-----------------------
Errors are those of one image metric: ``de2000`` = mean CIEDE2000 of the tone-mapped sky,
``radiance_rel`` = mean relative luminance error. The error of an effect in a scene is
the worst over the view-elevation bands the cameras see (sky seen directly) and the
error of the light on a horizontal surface (always: the sky lights the scene); in the
effect table, values at the scene's sun elevation are interpolated linearly between the
two nearest measured elevations. The tolerance is a budget split in fixed shares
(:data:`SHARES`), and errors are added (a conservative bound when errors behave like
distances); each decision spends only its own share, so tightening the tolerance can only
turn effects on and refine the knobs:

1. aerial perspective (35 %): if leaving out the air between the camera and the farthest
   object costs more than its share, volume shells are needed;
2. physical effects (35 %): the Earth's shadow, ground reflection, ozone and aerosols are
   left out in order of increasing measured error while their sum fits the share: the
   simplest atmosphere that looks the same;
3. numerical knobs: the fewest scattering orders (15 %), the coarsest spectral grid
   (10 %) and, with shells, the fewest layers (5 %) whose measured error fits;
4. the sun disc is drawn when the sky is seen and the sun is above the horizon within the
   cameras' elevation range; the environment image is sized so that one of its pixels is
   no larger than a camera pixel (a sky seen only as lighting gets a small image).

User overrides (:func:`plan`'s ``overrides``) are honoured as given and their measured
error is counted in the prediction.
"""

from __future__ import annotations

import functools
import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from skymodel.data import DATA_DIR
from skymodel.errors import SkymodelInputError, check_choice, check_range

EFFECTS_PATH = str(DATA_DIR / "presets" / "planner" / "effects.json")
ACCURACY_PATH = str(DATA_DIR / "presets" / "accuracy" / "measured.json")

TOLERANCE_KINDS = ("de2000", "radiance_rel")
#: Metric names in the tables for each tolerance kind: (sky band key, lighting key, aerial key).
_METRIC = {"de2000": ("de2000_mean", "de2000", "de2000_max"),
           "radiance_rel": ("radiance_rel_mean", "illuminance_rel", "radiance_rel_max")}
#: View-elevation bands of the effect table, degrees.
BANDS_DEG = {"ground": (-90.0, 0.0), "horizon": (0.0, 10.0), "low": (10.0, 30.0), "high": (30.0, 90.0)}
#: Physical effects the planner may leave out, with the effect-table row that measures it.
PHYSICAL = {"earth_shadow": "earth_shadow_off", "ground_reflection": "ground_albedo_0", "ozone": "ozone_off",
            "aerosols": "aerosols_off"}
#: Wavelength counts of the accuracy table's ``wavelengths`` knob -> step on 380..780 nm.
_WL_COUNT_STEP = {81: 5.0, 41: 10.0, 21: 20.0, 11: 40.0}
#: Most volume layers the Blender add-on builds.
MAX_LAYERS = 24
#: Fixed shares of the tolerance: each decision spends only its own share, so a tighter
#: tolerance can only turn effects on and refine the knobs (no decision loosens because
#: another one changed), and the shares add up to the whole tolerance.
SHARES = {"aerial_perspective": 0.35, "physical": 0.35, "orders": 0.15, "spectral": 0.1, "layers": 0.05}
PHYSICAL_SHARE = SHARES["physical"]
#: Environment image widths the planner picks from (height = width / 2).
MIN_ENV_WIDTH, MAX_ENV_WIDTH = 256, 8192
TOP_ALTITUDE_M = 100_000.0

EFFECT_NAMES = ("multiple_scattering", "aerosols", "ozone", "earth_shadow", "ground_reflection", "sun_disc",
                "aerial_perspective", "spectral_resolution", "angular_resolution")


# --------------------------------------------------------------------------- the scene


@dataclass(frozen=True)
class CameraView:
    """One camera: altitude above the ground (m), what it looks at and its field of view.

    Give either ``view_directions`` (unit vectors x east, y north, z up; the camera's
    view axis or several) or ``min_elevation_deg`` / ``max_elevation_deg`` (the range of
    view elevations the picture covers). With directions, the range is each direction's
    elevation plus or minus half of ``fov_deg`` (the larger field of view of the image).
    Neither: the camera may look anywhere (-90..90 degrees)."""

    altitude_m: float = 0.0
    min_elevation_deg: float | None = None
    max_elevation_deg: float | None = None
    view_directions: tuple | None = None
    fov_deg: float = 50.0

    def __post_init__(self):
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("altitude_m", check_range("altitude_m", self.altitude_m, 0.0, TOP_ALTITUDE_M, "metres"))
        set_("fov_deg", check_range("fov_deg", self.fov_deg, 0.01, 360.0, "degrees"))
        if self.fov_deg <= 0.01:
            raise SkymodelInputError("fov_deg", self.fov_deg, "a field of view in (0.01, 360] degrees")
        lo, hi = -90.0, 90.0
        if self.view_directions is not None:
            d = np.asarray(self.view_directions, dtype=float).reshape(-1, 3) if np.size(self.view_directions) else None
            if d is None or d.shape[0] == 0 or not np.all(np.isfinite(d)) or np.any(np.linalg.norm(d, axis=1) < 1e-12):
                raise SkymodelInputError("view_directions", self.view_directions,
                                         "one or more non-zero (x, y, z) vectors")
            el = np.degrees(np.arcsin(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1.0, 1.0)))
            half = 0.5 * min(self.fov_deg, 180.0)
            lo, hi = float(max(-90.0, el.min() - half)), float(min(90.0, el.max() + half))
            set_("view_directions", tuple(tuple(float(c) for c in v) for v in d))
        if self.min_elevation_deg is not None:
            lo = check_range("min_elevation_deg", self.min_elevation_deg, -90.0, 90.0, "degrees")
        if self.max_elevation_deg is not None:
            hi = check_range("max_elevation_deg", self.max_elevation_deg, -90.0, 90.0, "degrees")
        if lo > hi:
            raise SkymodelInputError("min_elevation_deg", lo, f"at most max_elevation_deg = {hi:g} degrees")
        set_("min_elevation_deg", float(lo))
        set_("max_elevation_deg", float(hi))


@dataclass(frozen=True)
class SceneDescription:
    """What the picture needs from the sky.

    cameras : one or more :class:`CameraView` (or dicts of their fields).
    sun_elevation_deg : -12..90 degrees.
    farthest_object_m : distance from the cameras to the farthest visible object, metres
        (0: nothing but the sky).
    sky_visible : True when the sky is seen directly; False when it only lights the scene
        (e.g. a transparent film background).
    image_width, image_height : the target image in pixels.
    tolerance_kind : ``"de2000"`` (mean CIEDE2000 of the tone-mapped sky) or
        ``"radiance_rel"`` (mean relative luminance error); ``tolerance`` its value.
    """

    cameras: tuple = (CameraView(),)
    sun_elevation_deg: float = 30.0
    farthest_object_m: float = 0.0
    sky_visible: bool = True
    image_width: int = 1920
    image_height: int = 1080
    tolerance_kind: str = "de2000"
    tolerance: float = 1.0

    def __post_init__(self):
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        cams = self.cameras
        if isinstance(cams, (CameraView, dict)):
            cams = (cams,)
        try:
            cams = tuple(c if isinstance(c, CameraView) else CameraView(**dict(c)) for c in cams)
        except TypeError:
            raise SkymodelInputError("cameras", self.cameras,
                                     "one or more CameraView (or dicts of its fields)") from None
        if not cams:
            raise SkymodelInputError("cameras", self.cameras, "at least one camera")
        set_("cameras", cams)
        set_("sun_elevation_deg", check_range("sun_elevation_deg", self.sun_elevation_deg, -12.0, 90.0,
                                              "degrees (below -12 the sky is night)"))
        set_("farthest_object_m", check_range("farthest_object_m", self.farthest_object_m, 0.0, 1_000_000.0, "metres"))
        set_("sky_visible", bool(self.sky_visible))
        for name in ("image_width", "image_height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not float(v).is_integer() or not 1 <= int(v) <= 65_536:
                raise SkymodelInputError(name, v, "a whole number of pixels in 1..65536")
            set_(name, int(v))
        set_("tolerance_kind", check_choice("tolerance_kind", self.tolerance_kind, TOLERANCE_KINDS))
        high = 100.0 if self.tolerance_kind == "de2000" else 1.0
        tol = check_range("tolerance", self.tolerance, 0.0, high)
        if tol <= 0.0:
            raise SkymodelInputError("tolerance", self.tolerance, f"a number in (0, {high:g}]")
        set_("tolerance", tol)

    @property
    def elevation_range_deg(self) -> tuple[float, float]:
        return (min(c.min_elevation_deg for c in self.cameras), max(c.max_elevation_deg for c in self.cameras))

    @property
    def max_fov_deg(self) -> float:
        return max(c.fov_deg for c in self.cameras)


# --------------------------------------------------------------------------- the plan


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
        return int(self["angular_resolution"].value)

    def march_settings(self, base=None):
        """``base`` (default: the ``final`` quality) with the plan's orders and Earth's shadow."""
        from dataclasses import replace

        from skymodel.render.quality import QUALITY

        s = base or QUALITY["final"]
        return replace(s, orders=self.orders, earth_shadow=bool(self["earth_shadow"].on))

    def apply_to_profile(self, profile):
        """The medium without the effects the plan leaves out (ozone, aerosols, ground)."""
        changes = {}
        if not self["ozone"].on:
            changes["ozone_absorption"] = np.zeros_like(profile.ozone_absorption)
        if not self["aerosols"].on:
            changes["aerosol_scattering_by_regime"] = np.zeros_like(profile.aerosol_scattering_by_regime)
            changes["aerosol_absorption"] = np.zeros_like(profile.aerosol_absorption)
        if not self["ground_reflection"].on:
            changes["ground_albedo"] = np.zeros_like(profile.ground_albedo)
        return profile.with_(**changes) if changes else profile

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
                "predicted_time_s": self.predicted_time_s,
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


# --------------------------------------------------------------------------- tables


@functools.lru_cache(maxsize=8)
def _load_json(path: str, mtime: float) -> dict:
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def load_table(path_or_dict):
    """A table given as a dict, a path, or None (-> None)."""
    if path_or_dict is None or isinstance(path_or_dict, dict):
        return path_or_dict
    p = os.fspath(path_or_dict)
    if not os.path.isfile(p):
        return None
    return _load_json(p, os.path.getmtime(p))


class _EffectTable:
    """Look-ups in ``skymodel/data/presets/planner/effects.json`` at a sun elevation."""

    def __init__(self, table: dict):
        self.table = table
        rows = sorted(table["rows"], key=lambda r: r["sun_elevation_deg"])
        if not rows:
            raise ValueError("effect table has no rows")
        self.rows = rows
        self.elev = np.array([r["sun_elevation_deg"] for r in rows], float)

    def _interp(self, el, fn):
        vals = np.array([fn(r) for r in self.rows], float)
        return float(np.interp(el, self.elev, vals))

    def has(self, effect) -> bool:
        return all(effect in r["effects"] for r in self.rows)

    def error(self, effect, el, scene) -> float:
        band_key, light_key, _ = _METRIC[scene.tolerance_kind]
        bands = visible_bands(scene)

        def one(r):
            e = r["effects"][effect]
            light = e["lighting"][light_key]
            if not scene.sky_visible or not bands:
                return light
            return max([light] + [e["sky"][b][band_key] for b in bands])

        return max(0.0, self._interp(el, one))

    def time(self, effect, el) -> float:
        if effect == "reference":
            return self._interp(el, lambda r: r["reference"]["time_s"])
        return self._interp(el, lambda r: r["effects"][effect]["time_s"])

    def reference_orders(self, el) -> int:
        return int(round(self._interp(el, lambda r: r["reference"]["orders"])))

    def aerial_error(self, el, distance_m, kind) -> float:
        if distance_m <= 0:
            return 0.0
        key = _METRIC[kind][2]

        def one(r):
            ap = r["aerial_perspective"]
            d = np.array([x["distance_m"] for x in ap], float)
            v = np.array([x[key] for x in ap], float)
            # linear in log-distance inside the table; below its first distance the error
            # scales with the distance (optical depth ~ distance), beyond its last it is held
            if distance_m < d[0]:
                return float(v[0] * distance_m / d[0])
            return float(np.interp(np.log(distance_m), np.log(d), v))

        return self._interp(el, one)

    def knob_rows(self, prefix) -> dict:
        """{value: effect name} of the effects named ``prefix<value>`` (orders_2, layers_8...)."""
        out = {}
        for name in self.rows[0]["effects"]:
            if name.startswith(prefix) and self.has(name):
                try:
                    out[float(name[len(prefix):])] = name
                except ValueError:
                    pass
        return out


class _AccuracyTable:
    """Look-ups in ``skymodel/data/presets/accuracy/measured.json`` (issue 3's benchmark), interpolated
    linearly in the sun elevation of its scenes and held beyond the first and last."""

    def __init__(self, table: dict):
        self.table = table
        scenes = table.get("scenes", {})
        self.scenes = sorted(scenes, key=lambda s: float(scenes[s]["sun_elevation_deg"]))
        self.elev = np.array([float(scenes[s]["sun_elevation_deg"]) for s in self.scenes], float)

    def _interp(self, el, values: dict):
        names = [s for s in self.scenes if s in values]
        if not names:
            return None
        x = np.array([float(self.table["scenes"][s]["sun_elevation_deg"]) for s in names])
        y = np.array([float(values[s]) for s in names])
        return float(np.interp(el, x, y))

    def knob(self, knob, el, metric) -> dict:
        """{value: (error, time_s)} of one knob, interpolated to the sun elevation."""
        by_value: dict = {}
        for r in self.table.get("rows", []):
            if r.get("knob") != knob:
                continue
            by_value.setdefault(r["value"], {})[r["scene"]] = r
        out = {}
        for value, per_scene in by_value.items():
            err = self._interp(el, {s: r[metric] for s, r in per_scene.items() if r.get(metric) is not None})
            t = self._interp(el, {s: r["time_s"] for s, r in per_scene.items() if r.get("time_s") is not None})
            if err is not None:
                out[value] = (err, t)
        return out

    def preset_time(self, preset, el):
        p = self.table.get("presets", {}).get(preset, {})
        return self._interp(el, {s: v["time_s"] for s, v in p.items() if "time_s" in v})


def visible_bands(scene: SceneDescription) -> list[str]:
    """The effect table's view-elevation bands the cameras see."""
    lo, hi = scene.elevation_range_deg
    return [b for b, (a, z) in BANDS_DEG.items() if hi > a and lo < z] if scene.sky_visible else []


# --------------------------------------------------------------------------- planning


def _env_width(scene: SceneDescription) -> tuple[int, str]:
    if not scene.sky_visible:
        return MIN_ENV_WIDTH, (f"the sky only lights the scene, so a {MIN_ENV_WIDTH}x{MIN_ENV_WIDTH // 2} "
                               "environment carries its light (irradiance is a smooth integral over the sky)")
    px_deg = scene.max_fov_deg / max(scene.image_width, scene.image_height)
    need = 360.0 / px_deg
    w = int(min(MAX_ENV_WIDTH, max(MIN_ENV_WIDTH, 2 ** math.ceil(math.log2(need)))))
    return w, (f"a camera pixel spans {px_deg:.3g} degrees ({scene.max_fov_deg:g} degree view over "
               f"{max(scene.image_width, scene.image_height)} px), so a {w}x{w // 2} environment keeps the sky "
               "at least as sharp as the picture" + (" (the largest the planner makes)" if w == MAX_ENV_WIDTH else ""))


OVERRIDABLE = ("multiple_scattering", "aerosols", "ozone", "earth_shadow", "ground_reflection", "sun_disc",
               "aerial_perspective")
USER = "set by the user: "


def _check_overrides(overrides) -> dict:
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


def plan(scene: SceneDescription, effects=EFFECTS_PATH, accuracy=ACCURACY_PATH, overrides=None) -> Plan:
    """Decide, effect by effect, what ``scene`` needs (see the module documentation).

    ``effects`` / ``accuracy``: the measured tables, as paths or dicts (defaults: the
    files in ``presets/``; the accuracy table is optional). ``overrides``: the user's
    decisions, ``{effect: True | False}`` for any of :data:`OVERRIDABLE` and
    ``{"n_layers": n}``; they are honoured as given, their measured error is counted, and
    the planner fits the remaining decisions into what is left of the tolerance."""
    if not isinstance(scene, SceneDescription):
        raise SkymodelInputError("scene", type(scene).__name__, "a SceneDescription")
    forced = _check_overrides(overrides)
    eff_data = load_table(effects)
    if eff_data is None:
        raise SkymodelInputError("effects", effects, "the measured effect table (skymodel/data/presets/planner/effects.json: "
                                 "python benchmarks/bench_planner.py --write)")
    eff = _EffectTable(eff_data)
    acc_data = load_table(accuracy)
    acc = _AccuracyTable(acc_data) if acc_data else None
    el = scene.sun_elevation_deg
    tol = scene.tolerance
    unit = "dE2000" if scene.tolerance_kind == "de2000" else "relative luminance error"
    acc_metric = "de2000_mean" if scene.tolerance_kind == "de2000" else "radiance_rel_rms"
    t_ref = eff.time("reference", el)
    decisions: dict[str, Decision] = {}
    spent = 0.0
    saved = 0.0
    where = "sky and lighting" if scene.sky_visible else "lighting"

    # 1. aerial perspective -------------------------------------------------------
    d = scene.farthest_object_m
    ap_err = eff.aerial_error(el, d, scene.tolerance_kind)
    shells = forced.get("aerial_perspective", ap_err > SHARES["aerial_perspective"] * tol)
    if not shells:
        spent += ap_err
        if d > 0:
            reason = (f"nothing is farther than {d / 1000:g} km, where leaving out the air in between changes an "
                      f"object's colour by {ap_err:.2g} {unit} (its share of the tolerance: "
                      f"{SHARES['aerial_perspective'] * tol:.2g}): environment only, no volume shells")
        else:
            reason = "no object is visible, only the sky: environment only, no volume shells"
        reason = USER * ("aerial_perspective" in forced) + reason
        decisions["aerial_perspective"] = Decision("aerial_perspective", False, None, reason, ap_err, None,
                                                   "effects.json aerial_perspective")

    # 2. physical effects, cheapest error first, within their share of the tolerance
    phys = sorted(PHYSICAL, key=lambda k: eff.error(PHYSICAL[k], el, scene))
    phys_budget = PHYSICAL_SHARE * tol
    phys_spent = 0.0
    texts = {
        "earth_shadow": ("the Earth's shadow", "no visible part of the atmosphere is in it"),
        "ground_reflection": ("light reflected by the ground", "it barely brightens the sky"),
        "ozone": ("ozone absorption", "it barely tints the sky at this sun elevation"),
        "aerosols": ("aerosols", "the haze barely changes the sky"),
    }
    for name in phys:
        e = eff.error(PHYSICAL[name], el, scene)
        what, why_off = texts[name]
        user = USER if name in forced else ""
        if forced.get(name, not phys_spent + e <= phys_budget) is False:
            spent += e
            phys_spent += e
            decisions[name] = Decision(name, False, None,
                                       f"{user}leaving out {what} changes the {where} by {e:.2g} {unit} at sun "
                                       f"{el:g} degrees: {why_off}", e, eff.time(PHYSICAL[name], el),
                                       f"effects.json {PHYSICAL[name]}")
        else:
            extra = {"ozone": " (ozone's Chappuis absorption sets the blue of the twilight sky)" if el < 2 else "",
                     "earth_shadow": " (the shadow's edge crosses the sky)" if el < 2 else ""}.get(name, "")
            why = ("kept on" if user else "more than the share of the tolerance allows")
            decisions[name] = Decision(name, True, None,
                                       f"{user}leaving out {what} would change the {where} by {e:.2g} {unit} at sun "
                                       f"{el:g} degrees: {why}{extra}", 0.0, t_ref, f"effects.json {PHYSICAL[name]}")

    # 3. numerical knobs, each within its share -------------------------------
    # scattering orders: effect table orders_1..4 (or the accuracy table's rows)
    orders = {int(v): (eff.error(n, el, scene), eff.time(n, el), f"effects.json {n}")
              for v, n in eff.knob_rows("orders_").items()}
    if acc is not None:
        for v, (e, t) in acc.knob("orders", el, acc_metric).items():
            if isinstance(v, (int, float)) and float(v).is_integer():
                orders.setdefault(int(v), (e, t * t_ref / (acc.preset_time("final", el) or t) if t else None,
                                           f"measured.json orders={v}"))
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
    n_conv = eff.reference_orders(el)
    if chosen == 1:
        e, t, src = orders[1]
        spent += e
        saved += max(0.0, t_ref - t)
        decisions["multiple_scattering"] = Decision(
            "multiple_scattering", False, 1, f"{ms_user}light scattered more than once changes the {where} by only "
            f"{e:.2g} {unit}: single scattering", e, t, src)
    elif chosen is not None:
        e, t, src = orders[chosen]
        spent += e
        saved += max(0.0, t_ref - t) if t is not None else 0.0
        decisions["multiple_scattering"] = Decision(
            "multiple_scattering", True, chosen, f"{ms_user}single scattering would be off by {orders[1][0]:.2g} "
            f"{unit}; {chosen} orders come within {e:.2g} of the converged {n_conv}", e, t, src)
    else:
        worst = orders[max(orders)][0] if orders else float("nan")
        decisions["multiple_scattering"] = Decision(
            "multiple_scattering", True, None, f"{ms_user}even {max(orders) if orders else 0} orders leave "
            f"{worst:.2g} {unit}, so scattering is followed until it converges (about {n_conv} orders measured)",
            0.0, t_ref,
            "effects.json reference")

    # spectral resolution: coarsest step whose error fits
    steps = {10.0: (0.0, t_ref, "effects.json reference (10 nm)")}
    for v, n in eff.knob_rows("wavelength_step_").items():
        steps[float(v)] = (eff.error(n, el, scene), eff.time(n, el), f"effects.json {n}")
    if acc is not None:
        rows = acc.knob("wavelengths", el, acc_metric)
        ref_t = rows.get(81, (0, None))[1]
        for v, (e, t) in rows.items():
            if v in _WL_COUNT_STEP:
                tt = t_ref * t / ref_t if (t and ref_t) else None
                steps[_WL_COUNT_STEP[v]] = (e, tt, f"measured.json wavelengths={v}")
    best = min(steps)
    for s in sorted(steps, reverse=True):
        if steps[s][0] <= SHARES["spectral"] * tol:
            best = s
            break
    e, t, src = steps[best]
    spent += e
    if t is not None:
        saved += max(0.0, steps.get(10.0, (0, t_ref))[1] - t) if best > 10.0 else 0.0
    n_wl = int(round(400.0 / best)) + 1
    finer = [s for s in steps if s < best]
    decisions["spectral_resolution"] = Decision(
        "spectral_resolution", True, best, f"a {best:g} nm grid ({n_wl} wavelengths) is off by {e:.2g} {unit}"
        + (", within its share of the tolerance" if finer else ", the finest measured") , e, t, src)

    # volume shells (when needed): fewest layers that fit
    if shells:
        layers = {int(v): (eff.error(n, el, scene), eff.time(n, el), f"effects.json {n}")
                  for v, n in eff.knob_rows("layers_").items()}
        if acc is not None:
            for v, (e, t) in acc.knob("layers", el, acc_metric).items():
                if isinstance(v, (int, float)) and float(v).is_integer() and int(v) <= MAX_LAYERS:
                    layers[int(v)] = (e, t, f"measured.json layers={v}")
        n_ok = [n for n in sorted(layers) if layers[n][0] <= SHARES["layers"] * tol and n <= MAX_LAYERS]
        n_l = n_ok[0] if n_ok else max(n for n in layers if n <= MAX_LAYERS)
        note = "" if n_ok else f" (the most measured; its layering error exceeds the share of the tolerance)"
        if "n_layers" in forced:
            n_l = forced["n_layers"]
            note = " (layer count set by the user)"
            if n_l not in layers:  # the nearest measured count at or below it (a fewer-layer error bounds it)
                below = [n for n in layers if n <= n_l]
                layers[n_l] = layers[max(below)] if below else layers[min(layers)]
        e, t, src = layers[n_l]
        spent += e
        top = TOP_ALTITUDE_M
        cam_lo = min(c.altitude_m for c in scene.cameras)
        decisions["aerial_perspective"] = Decision(
            "aerial_perspective", True, {"n_layers": n_l, "altitude_range_m": (0.0, top)},
            USER * ("aerial_perspective" in forced) + f"objects {d / 1000:g} km away would be off by {ap_err:.2g} "
            f"{unit} without the air in between, so "
            f"{n_l} volume shells (edges at equal 550 nm optical depth from the ground to {top / 1000:g} km, cameras "
            f"from {cam_lo:g} m) carry the aerial perspective{note}", e, t, src)

    # 4. geometry-only decisions ----------------------------------------------------
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
    decisions["sun_disc"] = Decision("sun_disc", disc_on, None, USER * ("sun_disc" in forced) + where_sun + disc,
                                     0.0, None, "geometry")
    w, why = _env_width(scene)
    decisions["angular_resolution"] = Decision("angular_resolution", True, w, why, 0.0, None, "geometry")

    order = {k: i for i, k in enumerate(EFFECT_NAMES)}
    decisions = dict(sorted(decisions.items(), key=lambda kv: order[kv[0]]))
    basis = (f"marcher time at the effect table's size ({eff.table.get('camera', {}).get('width', '?')}x"
             f"{eff.table.get('camera', {}).get('height', '?')}, preview tables) on its machine")
    t_plan = max(0.0, t_ref - saved)
    if acc is not None and acc.preset_time("final", el):
        scale = acc.preset_time("final", el) / t_ref
        t_plan, t_all = t_plan * scale, acc.preset_time("final", el)
        basis = "the accuracy table's 'final' preset time, scaled by the effect table's time ratios"
    else:
        t_all = t_ref
    tables = {"effects": eff.table.get("command", ""), "accuracy": acc.table.get("command", "") if acc else None}
    return Plan(scene, decisions, float(spent), float(t_plan), float(t_all), basis, tables)
