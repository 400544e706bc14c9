"""Everything the add-on computes, without ``bpy``: validated parameters, the sky image,
the sun lamp, the exposure and (volumetric mode) the RGB volume layers.

Every number that ends up in a Blender node comes from the physics core
(:mod:`skymodel`); this module only converts units and colours, and the conventions it
uses are stated once here (and in ``docs/blender.md``).

Colour scale ("Blender units")
    Scene-linear Rec.709 (Blender's working space) computed from spectra with the CIE 1931
    2-degree observer: ``RGB = M_709 @ integral(L(lambda) * (xbar, ybar, zbar) dlambda)``
    with L in W m^-2 sr^-1 nm^-1 (:func:`skymodel.colorimetry.spectral_to_rgb`). The
    luminance channel of that RGB (0.2126 R + 0.7152 G + 0.0722 B, Blender's own) is
    therefore ``Y = integral(L ybar dlambda)`` in W m^-2 sr^-1 of ybar-weighted radiance:
    **1.0 in an emission / environment pixel = 683 cd m^-2**. The sun lamp uses the same
    scale for irradiance: strength ``E_Y = integral(E ybar dlambda)`` in W m^-2 (Blender's
    "W/m^2" sun strength), so **1.0 of sun strength = 683 lux**, and a white Lambertian
    plate facing the sun renders at ``E_Y / pi``, the same scale as the sky around it.
    The lamp colour is ``RGB(E) / E_Y`` (luminance 1).

Orientation
    Blender's +X is east, +Y north, +Z up. Sun azimuth is clockwise from north (east 90).
    The environment image is rendered with the core's equirectangular camera centred on
    azimuth 90 (east), which is where Blender's Environment Texture puts the image centre
    (+X), with azimuth increasing to the right in both: no texture rotation is needed.

Exposure (the "incident-light meter" rule)
    ``exposure = log2(pi / E_h)`` where ``E_h`` is the horizontal illuminance at the
    observer in the scale above (direct sun ``E_Y sin(elevation)`` plus the sky's diffuse
    ``sum(Y cos(zenith) dOmega)`` over the upper hemisphere of the rendered sky, sun disc
    excluded). A white horizontal Lambertian surface then displays at scene value 1.0 and
    an 18 % grey card at 0.18 under the view transform (AgX), at noon and at dusk alike.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .core import core, input_error_class

#: Bump when the meaning of a cached file changes.
CACHE_FORMAT = 1

#: Environment image width by quality (height = width / 2).
IMAGE_WIDTH = {"preview": 512, "final": 1024, "reference": 2048}
#: Wavelength step (nm) of the spectral render by quality.
WAVELENGTH_STEP_NM = {"preview": 10.0, "final": 5.0, "reference": 5.0}
#: Lowest sun elevation the add-on accepts (the core CLI's rule: below it the sky is night).
MIN_SUN_ELEVATION_DEG = -12.0
#: Rec.709 luminance weights (Blender's scene-linear luminance).
LUMA_709 = np.array([0.2126, 0.7152, 0.0722])
#: Sky models the Environment can come from (names of ``skymodel.models``, and "blender":
#: Blender's own Sky Texture node): only models with an absolute radiance (the CIE skies
#: are relative and not offered).
SKY_MODELS = ("ours", "preetham", "openspace_earth", "blender")


def _err(parameter, value, allowed):
    return input_error_class()(parameter, value, allowed)


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class SkyParams:
    """The user's choices, plain Python (what the World panel holds), angles in degrees.

    ``location`` None means custom ``latitude_deg``/``longitude_deg`` (then ``aerosol``
    must be given). ``time_utc`` = (year, month, day, hour, minute) places the sun from
    the date (and the month comes from it); otherwise ``sun_elevation_deg`` /
    ``sun_azimuth_deg`` are used. ``aerosol`` None = the location's type.
    """

    location: str | None = "rural"
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    month: int = 6
    time_utc: tuple | None = None
    sun_elevation_deg: float = 25.0
    sun_azimuth_deg: float = 180.0
    aerosol: str | None = None
    aod550: float | None = None
    turbidity: float | None = None
    stratospheric: str = "background"
    ozone_du: float | None = None
    albedo: float | None = None
    observer_altitude_m: float = 0.0
    quality: str = "preview"
    image_width: int = 0
    mode: str = "ENVIRONMENT"
    n_layers: int = 8
    sky_model: str = "ours"  # one of SKY_MODELS (Environment mode)
    # set by Auto mode's effect plan (skymodel.planner); None / True = the quality's own
    wavelength_step_nm: float | None = None
    orders: int | None = None  # highest scattering order; 0 = until converged
    earth_shadow: bool = True


@dataclass(frozen=True)
class Plan:
    """Validated parameters: the core's :class:`~skymodel.Atmosphere` and the sun."""

    params: SkyParams
    atmosphere: object
    sun_elevation_deg: float
    sun_azimuth_deg: float
    earth_sun_distance_au: float
    time_iso: str | None

    def profile(self, wavelengths_nm):
        """The atmosphere's optical profile, solar spectrum scaled to the date's distance."""
        prof = self.atmosphere.optical_profile(wavelengths_nm)
        if self.earth_sun_distance_au != 1.0:
            prof = dataclasses.replace(prof, solar_irradiance=prof.solar_irradiance / self.earth_sun_distance_au**2)
        return prof

    def sun_angular_diameter_deg(self) -> float:
        return 2.0 * float(core("sun").sun_angular_radius_deg(self.earth_sun_distance_au))


def _time_iso(t) -> str:
    try:
        year, month, day, hour, minute = (int(v) for v in t)
    except (TypeError, ValueError):
        raise _err("time_utc", t, "(year, month, day, hour, minute)") from None
    if not 1900 <= year <= 2100:
        raise _err("year", year, "a year in 1900..2100")
    if not 1 <= month <= 12:
        raise _err("month", month, "an integer 1..12")
    import calendar

    last = calendar.monthrange(year, month)[1]
    if not 1 <= day <= last:
        raise _err("day", day, f"a day 1..{last} for {year}-{month:02d}")
    if not 0 <= hour <= 23:
        raise _err("hour", hour, "an hour 0..23 (UTC)")
    if not 0 <= minute <= 59:
        raise _err("minute", minute, "a minute 0..59")
    return _dt.datetime(year, month, day, hour, minute).strftime("%Y-%m-%dT%H:%M:00Z")


def resolve(params: SkyParams) -> Plan:
    """Validate everything through the core (raises ``SkymodelInputError`` naming the
    parameter) and place the sun."""
    p = params
    month = p.month
    iso = None
    if p.time_utc is not None:
        iso = _time_iso(p.time_utc)
        month = int(p.time_utc[1])
    if str(p.quality).lower() not in IMAGE_WIDTH:
        raise _err("quality", p.quality, "one of: " + ", ".join(IMAGE_WIDTH))
    Atmosphere = core("optics.atmosphere").Atmosphere
    atm = Atmosphere(location=p.location, month=month, latitude=p.latitude_deg, longitude=p.longitude_deg,
                     aerosol=p.aerosol, aod550=p.aod550, turbidity=p.turbidity, stratospheric=p.stratospheric,
                     ozone_du=p.ozone_du, albedo=p.albedo)
    check_range = core("errors").check_range
    if iso is not None:
        pos = core("sun").solar_position(atm.latitude, atm.longitude, iso)
        elev, az = float(np.asarray(pos.elevation_deg)), float(np.asarray(pos.azimuth_deg))
        dist = float(np.asarray(pos.earth_sun_distance_au))
        if elev < MIN_SUN_ELEVATION_DEG:
            raise _err("time_utc", iso, f"a time when the sun is above {MIN_SUN_ELEVATION_DEG:g} degrees "
                                        f"(it is at {elev:.1f} degrees: night)")
    else:
        elev, az, dist = p.sun_elevation_deg, p.sun_azimuth_deg, 1.0
    elev = check_range("sun_elevation", elev, MIN_SUN_ELEVATION_DEG, 90.0,
                       "degrees (below -12 the sky is night)")
    az = check_range("sun_azimuth", az, -360.0, 360.0, "degrees") % 360.0
    check_range("observer_altitude", p.observer_altitude_m, 0.0, 100_000.0, "metres")
    if p.mode not in ("ENVIRONMENT", "VOLUMETRIC"):
        raise _err("mode", p.mode, "ENVIRONMENT or VOLUMETRIC")
    if isinstance(p.image_width, bool) or int(p.image_width) < 0 or int(p.image_width) > 8192:
        raise _err("image_width", p.image_width, "0 (by quality) or 16..8192 pixels")
    if not 1 <= int(p.n_layers) <= 24:
        raise _err("n_layers", p.n_layers, "an integer 1..24")
    if p.sky_model not in SKY_MODELS:
        raise _err("sky_model", p.sky_model, "one of: " + ", ".join(SKY_MODELS))
    if p.sky_model != "ours" and p.mode != "ENVIRONMENT":
        raise _err("sky_model", p.sky_model, "ours in Volumetric mode (the other models make environment images only)")
    if p.sky_model not in ("ours", "blender") and p.observer_altitude_m != 0.0:
        raise _err("observer_altitude", p.observer_altitude_m, f"0 m with the {p.sky_model} sky model (a ground observer)")
    return Plan(p, atm, float(elev), float(az), dist, iso)


def image_width(params: SkyParams) -> int:
    w = int(params.image_width) or IMAGE_WIDTH[params.quality]
    w = max(16, w)
    return w + (w % 2)


def _atmosphere_dict(atm) -> dict:
    out = {}
    for f in dataclasses.fields(atm):
        v = getattr(atm, f.name)
        out[f.name] = round(v, 9) if isinstance(v, float) else v
    return out


def cache_key(plan: Plan, kind: str, **extra) -> str:
    """SHA-256 (first 20 hex digits) of every input that changes the result."""
    p = plan.params
    desc = {
        "format": CACHE_FORMAT,
        "kind": kind,
        "core_version": getattr(core(), "__version__", "?"),
        "atmosphere": _atmosphere_dict(plan.atmosphere),
        "sun_elevation_deg": round(plan.sun_elevation_deg, 6),
        "sun_azimuth_deg": round(plan.sun_azimuth_deg, 6),
        "earth_sun_distance_au": round(plan.earth_sun_distance_au, 7),
        "observer_altitude_m": round(float(p.observer_altitude_m), 3),
        "quality": p.quality,
        **extra,
    }
    text = json.dumps(desc, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:20]


# --------------------------------------------------------------------------- colour


def spectrum_rgb(spectrum, wavelengths_nm) -> np.ndarray:
    """Scene-linear Rec.709 of spectra (last axis wavelength) in the scale of the module doc."""
    return np.asarray(core("colorimetry").spectral_to_rgb(spectrum, wavelengths_nm, "rec709"), dtype=float)


def fit_into_gamut(rgb: np.ndarray) -> np.ndarray:
    """Move colours with a negative channel toward the grey of the same luminance just
    enough to make every channel >= 0 (luminance is kept; negative light would make
    Cycles subtract energy). Colours already in gamut are unchanged."""
    rgb = np.asarray(rgb, dtype=float)
    y = rgb @ LUMA_709
    lo = rgb.min(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(lo < 0.0, y / (y - lo), 1.0)
    s = np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0)
    out = y[..., None] + (rgb - y[..., None]) * s[..., None]
    return np.where((y > 0.0)[..., None], np.maximum(out, 0.0), 0.0)


def sun_lamp(irradiance, wavelengths_nm) -> tuple[float, tuple]:
    """(strength W m^-2 (ybar-weighted), colour with luminance 1) of a spectral irradiance."""
    rgb = fit_into_gamut(spectrum_rgb(irradiance, wavelengths_nm))
    y = float(rgb @ LUMA_709)
    if not y > 0.0:
        return 0.0, (1.0, 1.0, 1.0)
    return y, tuple(float(c) for c in rgb / y)


def horizontal_illuminance(rgb_image, camera, sun_strength: float, sun_elevation_deg: float) -> float:
    """E_h: direct sun on a horizontal plane plus the sky's diffuse part (upper hemisphere)."""
    dirs, valid = camera.directions()
    omega = camera.pixel_solid_angles()
    y = np.asarray(rgb_image, float) @ LUMA_709
    cos_z = dirs[..., 2]
    up = valid & (cos_z > 0)
    diffuse = float(np.sum(np.where(up, y * cos_z * omega, 0.0)))
    return diffuse + sun_strength * max(math.sin(math.radians(sun_elevation_deg)), 0.0)


def exposure_from_illuminance(e_h: float) -> float:
    """Blender exposure (stops) of the incident-light rule: ``log2(pi / E_h)``, in [-32, 32]."""
    if not e_h > 0.0 or not math.isfinite(e_h):
        return 0.0
    return float(min(max(math.log2(math.pi / e_h), -32.0), 32.0))


# --------------------------------------------------------------------------- environment


@dataclass
class SkyResult:
    """What the scene builder needs; ``info`` is shown in the panel and written as JSON."""

    mode: str
    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_strength: float
    sun_colour: tuple
    sun_angle_deg: float
    exposure: float
    image_path: str | None = None
    cache_hit: bool = False
    layers: list = field(default_factory=list)  # volumetric: dicts per ball, outermost first
    ground_albedo_rgb: tuple | None = None
    info: dict = field(default_factory=dict)


def default_cache_dir() -> Path:
    env = os.environ.get("SKYMODEL_CACHE_DIR")
    if env:
        return Path(env)
    import tempfile

    return Path(tempfile.gettempdir()) / "skymodel-cache"


def _write_json_atomic(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=1, sort_keys=True)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


class _Orders:
    """Adapts the marcher's per-order callback to a text progress callback."""

    def __init__(self, progress):
        self.progress = progress

    def __call__(self, n, size):
        if self.progress:
            self.progress(f"scattering order {n} (adds {size:.2%})")


def model_environment(plan: Plan, camera, wavelengths_nm, include_sun=False):
    """``(radiance (H, W, n_wl), direct sun irradiance (n_wl,))`` of the camera's pixels from
    the alternative sky model ``plan.params.sky_model`` (:mod:`skymodel.models`), its own
    sun (Preetham's transmittance; OpenSpace's marcher), scaled to the date's distance."""
    models = core("models")
    scene = models.SkyScene(plan.atmosphere, plan.sun_elevation_deg, plan.sun_azimuth_deg, wavelengths_nm,
                            plan.params.quality)
    dirs, valid = camera.directions()
    radiance = np.zeros(valid.shape + (len(wavelengths_nm),))
    res = models.get_model(plan.params.sky_model, "sky_model")(scene, dirs[valid])
    scale = 1.0 / plan.earth_sun_distance_au**2
    radiance[valid] = np.asarray(res.values) * scale
    sun_irr = np.asarray(res.info["sun_irradiance"], dtype=float) * scale
    if include_sun:
        render_sky = core("render.sky")
        render_sky.add_sun_disc(radiance, dirs, valid, camera.pixel_solid_angles(), scene.sun_direction, sun_irr,
                                wavelengths_nm, limb_darkening=getattr(core("sun"), "limb_darkening", None))
    return radiance, sun_irr


def blender_sky_texture(plan: Plan, cache_dir=None, progress=None):
    """Sky model "blender": Blender's own Sky Texture node (Multiple Scattering) with air,
    aerosol and ozone densities matched to the atmosphere
    (:func:`skymodel.models.blender_sky.scene_parameters`); the sun lamp and the exposure
    come from our model at 64x32 (``SkyResult.image_path`` is None, the node settings are in
    ``info["sky_texture"]``). Sky Texture ``sun_rotation`` is the azimuth clockwise from
    north (+Y), as ours (measured with bpy 5.0.1: 0 puts the sun at +Y, 90 degrees at +X)."""
    small = dataclasses.replace(plan, params=dataclasses.replace(plan.params, sky_model="ours", image_width=64))
    _, res = render_environment(small, cache_dir, progress)
    scene = core("models").SkyScene(plan.atmosphere, plan.sun_elevation_deg, plan.sun_azimuth_deg, [550.0])
    prm = core("models.blender_sky").scene_parameters(scene)
    tex = {"sky_type": "MULTIPLE_SCATTERING", "sun_elevation_deg": plan.sun_elevation_deg,
           "sun_rotation_deg": plan.sun_azimuth_deg, "altitude_m": float(plan.params.observer_altitude_m),
           "air_density": prm["air_density"], "aerosol_density": prm["aerosol_density"],
           "ozone_density": prm["ozone_density"]}
    res.image_path = None
    res.info = dict(res.info, sky_model="blender", sky_texture=tex)
    return None, res


def render_environment(plan: Plan, cache_dir=None, progress=None, include_sun=False):
    """Render (or reuse) the equirectangular sky for ``plan``.

    Returns ``(rgb (H, W, 3) float32 or None on a cache hit, SkyResult)``; the EXR and a
    JSON with the lamp and exposure numbers are in ``cache_dir`` under the cache key.
    """
    p = plan.params
    if p.sky_model == "blender":
        return blender_sky_texture(plan, cache_dir, progress)
    width = image_width(p)
    step = float(p.wavelength_step_nm or WAVELENGTH_STEP_NM[p.quality])
    planned = {"orders": p.orders, "earth_shadow": p.earth_shadow} if (p.orders is not None or not p.earth_shadow) else {}
    key = cache_key(plan, "environment", width=width, wavelength_step_nm=step, include_sun=bool(include_sun),
                    **({"sky_model": p.sky_model} if p.sky_model != "ours" else {}), **planned)
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    exr = folder / f"sky-{key}.exr"
    meta = folder / f"sky-{key}.json"
    if exr.is_file() and meta.is_file():
        try:
            with open(meta, encoding="utf-8") as f:
                m = json.load(f)
            res = SkyResult(mode="ENVIRONMENT", image_path=str(exr), cache_hit=True, **m["result"])
            res.info = dict(m.get("info", {}), cache="hit")
            if progress:
                progress(f"reusing cached sky {exr.name}")
            return None, res
        except (OSError, ValueError, KeyError, TypeError):
            pass  # a damaged cache entry is rebuilt
    t0 = time.perf_counter()
    wl = core("wavelengths").default_wavelengths(step)
    if progress:
        progress(f"optical profile: {len(wl)} wavelengths")
    prof = plan.profile(wl)
    # Our sky without the disc is rendered band by band straight to RGB, so only three
    # values per pixel are kept (a 2048x1024 image at 81 wavelengths would otherwise hold
    # a 1.4 GB spectral cube plus its working copies); the memory guard counts that.
    banded = p.sky_model == "ours" and not include_sun
    cam = core("render.cameras").make_camera("equirectangular", width, center_azimuth_deg=90.0,
                                             n_wavelengths=3 if banded else wl.size)
    if progress:
        progress(f"spectral render {cam.width}x{cam.height}, quality {p.quality}")
    if p.sky_model == "ours":
        quality = p.quality
        if planned:  # Auto mode: the plan's orders and Earth's shadow on the quality's settings
            quality = dataclasses.replace(core("render.sky").quality_settings(p.quality),
                                          orders=int(p.orders) or None if p.orders is not None else None,
                                          earth_shadow=bool(p.earth_shadow))
        sky = core("render.sky")
        if banded:
            rgb, sun_irradiance, _ = sky.render_sky_reduced(
                prof, cam, plan.sun_elevation_deg, lambda rad, w: fit_into_gamut(spectrum_rgb(rad, w)), 3,
                plan.sun_azimuth_deg, p.observer_altitude_m, quality, progress=_Orders(progress))
        else:
            img = sky.render_sky(prof, cam, plan.sun_elevation_deg, plan.sun_azimuth_deg,
                                 p.observer_altitude_m, quality, include_sun=include_sun, progress=_Orders(progress))
            rgb, sun_irradiance = fit_into_gamut(spectrum_rgb(img.radiance, wl)), img.sun_irradiance
    else:
        radiance, sun_irradiance = model_environment(plan, cam, wl, include_sun)
        rgb = fit_into_gamut(spectrum_rgb(radiance, wl))
    strength, colour = sun_lamp(sun_irradiance, wl)
    e_h = horizontal_illuminance(rgb, cam, strength, plan.sun_elevation_deg)
    ev = exposure_from_illuminance(e_h)
    if not np.all(np.isfinite(rgb)):
        raise FloatingPointError("sky image: non-finite values")
    luma = rgb @ LUMA_709
    h = rgb.shape[0]
    result = {
        "sun_elevation_deg": plan.sun_elevation_deg,
        "sun_azimuth_deg": plan.sun_azimuth_deg,
        "sun_strength": strength,
        "sun_colour": list(colour),
        "sun_angle_deg": plan.sun_angular_diameter_deg(),
        "exposure": ev,
    }
    info = {
        "render_s": round(time.perf_counter() - t0, 3),
        "size": f"{cam.width}x{cam.height}",
        "wavelengths": int(wl.size),
        "horizontal_illuminance_Y": e_h,
        "zenith_Y": float(luma[0].mean()),
        "horizon_Y": float(luma[h // 2 - 1].mean()),
        "atmosphere": {k: v for k, v in prof.metadata.items() if isinstance(v, (str, int, float, type(None)))},
        "time_utc": plan.time_iso,
        "cache_key": key,
        "sky_model": p.sky_model,
    }
    write_exr = core("render.image_io").write_exr
    chroma = core("render.image_io").CHROMATICITIES["rec709"]
    if progress:
        progress(f"writing {exr}")
    write_exr(exr, rgb.astype(np.float32), chromaticities=chroma,
              attributes={"skymodel": json.dumps({"cache_key": key, "units": "Y = 1 <=> 683 cd/m2"})})
    _write_json_atomic(meta, {"result": result, "info": info})
    res = SkyResult(mode="ENVIRONMENT", image_path=str(exr), cache_hit=False, **result)
    res.info = dict(info, cache="miss")
    return rgb.astype(np.float32), res
