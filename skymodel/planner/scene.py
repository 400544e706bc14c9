"""What a picture needs from the sky, as the planner reads it: :class:`CameraView` (one
camera's altitude and the view elevations it covers) and :class:`SceneDescription` (the
cameras, the sun, the farthest visible object, the image and the tolerance).

Validation happens here, at the planner's public boundary: every field is checked
(:mod:`skymodel.errors`) and normalised when the description is made.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymodel.errors import SkymodelInputError, check_choice, check_range
from skymodel.scene import parameter

#: The image metrics a tolerance may be given in (:class:`SceneDescription`).
TOLERANCE_KINDS = ("de2000", "radiance_rel")
#: Top of the atmosphere, m: the highest camera, and the top of the planned volume shells.
TOP_ALTITUDE_M = 100_000.0


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
    sun_elevation_deg : degrees, in the registry's ``sun_elevation`` range (-18..90).
    farthest_object_m : distance from the cameras to the farthest visible object, metres
        (0: nothing but the sky).
    sky_visible : True when the sky is seen directly; False when it only lights the scene
        (e.g. a transparent film background).
    image_width, image_height : the target image in pixels.
    tolerance_kind : ``"de2000"`` (mean CIEDE2000 of the tone-mapped sky) or
        ``"radiance_rel"`` (mean relative luminance error); ``tolerance`` its value.
    time_budget_s : the most seconds the sky may cost (None: no limit): the environment's
        build, or the volume shells' Cycles render of one frame; a choice predicted to take
        longer is not made (the plan says so).
    samples : Cycles samples per pixel of the user's render (the volume shells' cost).
    quality : the renderer's quality preset the environment is built at (the registry's
        ``quality`` choices; default ``final``, the plans' reference build): the predicted
        time is the accuracy table's time of that preset.
    """

    cameras: tuple = (CameraView(),)
    sun_elevation_deg: float = 30.0
    farthest_object_m: float = 0.0
    sky_visible: bool = True
    image_width: int = 1920
    image_height: int = 1080
    tolerance_kind: str = "de2000"
    tolerance: float = 1.0
    time_budget_s: float | None = None
    samples: int = 64
    quality: str = "final"

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
        sun = parameter("sun_elevation")
        set_("sun_elevation_deg", check_range("sun_elevation_deg", self.sun_elevation_deg, sun.minimum, sun.maximum,
                                              "degrees"))
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
        if self.time_budget_s is not None:
            budget = check_range("time_budget_s", self.time_budget_s, 0.0, 1e7, "seconds")
            if budget <= 0.0:
                raise SkymodelInputError("time_budget_s", self.time_budget_s, "seconds > 0, or None (no limit)")
            set_("time_budget_s", budget)
        v = self.samples
        if isinstance(v, bool) or not float(v).is_integer() or not 1 <= int(v) <= 1_000_000:
            raise SkymodelInputError("samples", v, "a whole number of samples per pixel in 1..1000000")
        set_("samples", int(v))
        set_("quality", check_choice("quality", self.quality, parameter("quality").choices))

    @property
    def elevation_range_deg(self) -> tuple[float, float]:
        return (min(c.min_elevation_deg for c in self.cameras), max(c.max_elevation_deg for c in self.cameras))

    @property
    def max_fov_deg(self) -> float:
        return max(c.fov_deg for c in self.cameras)
