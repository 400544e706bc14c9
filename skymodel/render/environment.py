"""Equirectangular environment maps: the sky rendered for a renderer's world background.

An environment map is the sky of one atmosphere and sun as a scene-linear Rec.709 image
(an OpenEXR file), with the numbers a renderer needs next to it: the strength and colour
of a sun lamp and the exposure of the incident-light rule. The Blender add-on uses it for
its Environment mode; nothing here is specific to Blender.

Colour scale
    Scene-linear Rec.709 computed from spectra with the CIE 1931 2-degree observer:
    ``RGB = M_709 @ integral(L(lambda) * (xbar, ybar, zbar) dlambda)`` with L in
    W m^-2 sr^-1 nm^-1 (:func:`skymodel.colorimetry.spectral_to_rgb`). The luminance of that
    RGB (0.2126 R + 0.7152 G + 0.0722 B) is therefore ``Y = integral(L ybar dlambda)`` in
    W m^-2 sr^-1 of ybar-weighted radiance: **1.0 in a pixel = 683 cd m^-2**. A sun lamp
    uses the same scale for irradiance: strength ``E_Y = integral(E ybar dlambda)`` in
    W m^-2, so **1.0 of sun strength = 683 lux**, and a white Lambertian plate facing the
    sun renders at ``E_Y / pi``, the same scale as the sky around it. The lamp colour is
    ``RGB(E) / E_Y`` (luminance 1).

Orientation
    +X east, +Y north, +Z up; azimuth clockwise from north (east 90). The image is
    rendered with the equirectangular camera centred on azimuth 90 (east, +X), azimuth
    increasing to the right (:func:`environment_camera`): where Blender's Environment
    Texture puts the image centre, so no texture rotation is needed there.

Exposure
    :func:`render_environment` records the exposure of the one display rule of
    :mod:`skymodel.render.exposure` (the darker of the incident-light rule and the sky meter,
    whose key falls with the light, day and night; the moon lamp's light counted in the
    incident meter), the same rule ``skymodel render`` and ``skymodel timelapse`` use for
    their PNGs. A user offset is added by the renderer (the
    Blender add-on's Exposure Offset).

Cache
    :func:`render_environment` writes ``sky-<key>.exr`` and ``sky-<key>.json`` (the lamp and
    exposure numbers) into a cache folder, ``<key>`` being a hash of every input that changes
    the image and of the package's code and data (:func:`cache_key`,
    :func:`skymodel.render.provenance.package_tag`); a second call with the same inputs reads them back. The
    JSON records the EXR's size in bytes and SHA-256; an entry whose EXR does not match them
    (truncated, overwritten, damaged on disk) or whose JSON cannot be read is deleted and
    rendered again (:func:`verify_cached`). :func:`clear_cache` empties a cache folder.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import skymodel
from skymodel import colorimetry
from skymodel import sun as sun_module
from skymodel.render import image_io, provenance
from skymodel.render import sky as render_sky
from skymodel.render.cameras import make_camera
from skymodel.render.exposure import LUMA_709, display_exposure
from skymodel.render.memory import check_render_memory
from skymodel.render.quality import QUALITIES
from skymodel.render.skyview import rgb_reduction
from skymodel.wavelengths import default_wavelengths

#: Bump when the meaning of a cached file changes (2: the exposure of display_exposure; 3: its
#: night branch, skymodel.render.exposure).
CACHE_FORMAT = 3
#: Image width by quality (height = width / 2): the quality registry's.
IMAGE_WIDTH = {name: q.environment_width_px for name, q in QUALITIES.items()}
#: Wavelength step (nm) of the spectral render by quality: the quality registry's.
WAVELENGTH_STEP_NM = {name: q.wavelength_step_nm for name, q in QUALITIES.items()}
#: Azimuth (degrees clockwise from north) at the centre of the image: east, +X.
CENTER_AZIMUTH_DEG = 90.0
#: The sky model rendered by this module's own marcher; others come through ``model_radiance``.
OWN_MODEL = "ours"


# --------------------------------------------------------------------------- colour and exposure


def spectrum_rgb(spectrum, wavelengths_nm) -> np.ndarray:
    """Scene-linear Rec.709 of spectra (last axis wavelength) in the scale of the module doc."""
    return np.asarray(colorimetry.spectral_to_rgb(spectrum, wavelengths_nm, "rec709"), dtype=float)


def fit_into_gamut(rgb: np.ndarray) -> np.ndarray:
    """Move colours with a negative channel toward the grey of the same luminance just
    enough to make every channel >= 0 (luminance is kept; negative light would make a
    renderer subtract energy). Colours already in gamut are unchanged."""
    rgb = np.asarray(rgb, dtype=float)
    y = rgb @ LUMA_709
    lo = rgb.min(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(lo < 0.0, y / (y - lo), 1.0)
    s = np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0)
    out = y[..., None] + (rgb - y[..., None]) * s[..., None]
    return np.where((y > 0.0)[..., None], np.maximum(out, 0.0), 0.0)


def reduce_to_rgb(radiance, wavelengths_nm) -> np.ndarray:
    """Spectral radiance (..., n_wl) -> in-gamut scene-linear Rec.709 (..., 3)."""
    return fit_into_gamut(spectrum_rgb(radiance, wavelengths_nm))


def sun_lamp(irradiance, wavelengths_nm) -> tuple[float, tuple]:
    """(strength W m^-2 (ybar-weighted), colour with luminance 1) of a spectral irradiance."""
    rgb = reduce_to_rgb(irradiance, wavelengths_nm)
    y = float(rgb @ LUMA_709)
    if not y > 0.0:
        return 0.0, (1.0, 1.0, 1.0)
    return y, tuple(float(c) for c in rgb / y)


# --------------------------------------------------------------------------- inputs


def environment_camera(width: int, n_wavelengths: int | None = None):
    """The equirectangular camera of an environment map, centred on azimuth 90 (east)."""
    return make_camera("equirectangular", int(width), center_azimuth_deg=CENTER_AZIMUTH_DEG,
                       n_wavelengths=n_wavelengths)


def image_width(width: int, quality: str) -> int:
    """The image width: ``width`` or, when 0, the quality's; at least 16 and even."""
    w = int(width) or IMAGE_WIDTH[quality]
    w = max(16, w)
    return w + (w % 2)


def profile_at_distance(atmosphere, wavelengths_nm, earth_sun_distance_au: float = 1.0):
    """The atmosphere's optical profile, its solar spectrum scaled to the Earth-sun distance."""
    prof = atmosphere.optical_profile(wavelengths_nm)
    if earth_sun_distance_au != 1.0:
        prof = dataclasses.replace(prof, solar_irradiance=prof.solar_irradiance / earth_sun_distance_au**2)
    return prof


def sun_angular_diameter_deg(earth_sun_distance_au: float = 1.0) -> float:
    """Apparent diameter of the sun (degrees) at that distance."""
    return 2.0 * float(sun_module.sun_angular_radius_deg(earth_sun_distance_au))


def _atmosphere_dict(atm) -> dict:
    out = {}
    for f in dataclasses.fields(atm):
        v = getattr(atm, f.name)
        out[f.name] = round(v, 9) if isinstance(v, float) else v
    return out


def cache_key(atmosphere, sun_elevation_deg: float, sun_azimuth_deg: float, earth_sun_distance_au: float,
              observer_altitude_m: float, quality: str, kind: str, **extra) -> str:
    """SHA-256 (first 20 hex digits) of every input that changes the result."""
    desc = {
        "format": CACHE_FORMAT,
        "kind": kind,
        "core_version": getattr(skymodel, "__version__", "?"),
        "package": provenance.package_tag(),  # the code and data that render it (skymodel.render.provenance)
        "atmosphere": _atmosphere_dict(atmosphere),
        "sun_elevation_deg": round(sun_elevation_deg, 6),
        "sun_azimuth_deg": round(sun_azimuth_deg, 6),
        "earth_sun_distance_au": round(earth_sun_distance_au, 7),
        "observer_altitude_m": round(float(observer_altitude_m), 3),
        "quality": quality,
        **extra,
    }
    text = json.dumps(desc, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:20]


def default_cache_dir() -> Path:
    """``$SKYMODEL_CACHE_DIR``, else ``<temp>/skymodel-cache``."""
    env = os.environ.get("SKYMODEL_CACHE_DIR")
    if env:
        return Path(env)
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


#: Pixels whose spectra the environment build marches at once (render_sky_reduced's band_pixels).
ENV_BAND_PIXELS = 1 << 20
#: Multiple-scattering solutions kept in memory per cache folder (a final one is ~150 MB).
SOLUTIONS_IN_MEMORY = 2
_SOLUTION_CACHES: dict = {}


def solution_cache(folder):
    """The process's :class:`~skymodel.render.sequence.SolutionCache` for a cache folder:
    solutions in memory (:data:`SOLUTIONS_IN_MEMORY`) and on disk in ``folder/solutions``,
    keyed by the optical profile's hash, so a build where only the sun or the time changed
    skips the multiple-scattering solve, within a session and across sessions."""
    from skymodel.render.sequence import SolutionCache

    key = str(Path(folder).resolve())
    if key not in _SOLUTION_CACHES:
        _SOLUTION_CACHES[key] = SolutionCache(Path(folder) / SOLUTIONS_FOLDER, keep=SOLUTIONS_IN_MEMORY)
    return _SOLUTION_CACHES[key]


class _Orders:
    """Adapts the marcher's per-order callback to a text progress callback."""

    def __init__(self, progress):
        self.progress = progress

    def __call__(self, n, size):
        if self.progress:
            self.progress(f"scattering order {n} (adds {size:.2%})")


# --------------------------------------------------------------------------- the map


@dataclass
class EnvironmentMap:
    """A rendered (or cached) environment map: the EXR's path and the lamp and exposure numbers.

    ``sun_strength`` [W m^-2, ybar-weighted], ``sun_colour`` (luminance 1), ``sun_angle_deg``
    (apparent diameter), ``exposure`` [stops]; ``info`` holds the render's statistics."""

    image_path: str
    cache_hit: bool
    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_strength: float
    sun_colour: tuple
    sun_angle_deg: float
    exposure: float
    info: dict = field(default_factory=dict)

    def lamp(self) -> dict:
        """The sun lamp and exposure numbers (what the cache's JSON holds as ``result``)."""
        return {k: getattr(self, k) for k in ("sun_elevation_deg", "sun_azimuth_deg", "sun_strength",
                                              "sun_colour", "sun_angle_deg", "exposure")}


def file_digest(path) -> dict:
    """``{"bytes": size, "sha256": hex digest}`` of a file (read in 1 MiB chunks)."""
    h = hashlib.sha256()
    n = 0
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
            n += len(chunk)
    return {"bytes": n, "sha256": h.hexdigest()}


def verify_cached(exr, meta) -> tuple[dict | None, str]:
    """``(the cache entry's JSON, "")`` when ``exr`` matches the size and SHA-256 its JSON
    ``meta`` records, else ``(None, why)`` (missing, unreadable JSON, no digest: an entry
    written before digests were kept, wrong size, wrong hash)."""
    exr, meta = Path(exr), Path(meta)
    if not (exr.is_file() and meta.is_file()):
        return None, "missing"
    try:
        with open(meta, encoding="utf-8") as f:
            m = json.load(f)
        want = m["exr"]
        if exr.stat().st_size != int(want["bytes"]):
            return None, f"size {exr.stat().st_size} B, recorded {int(want['bytes'])} B"
        if file_digest(exr)["sha256"] != str(want["sha256"]):
            return None, "SHA-256 differs from the recorded one"
        if not isinstance(m["result"], dict):
            raise TypeError("result")
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as ex:
        return None, f"unreadable record ({type(ex).__name__})"
    return m, ""


def _read_cached(exr: Path, meta: Path, progress) -> EnvironmentMap | None:
    m, why = verify_cached(exr, meta)
    if m is None:
        if why != "missing" or exr.exists() or meta.exists():  # a damaged entry: delete it, render again
            if progress:
                progress(f"cached sky {exr.name} is damaged ({why}): rendering it again")
            for f in (exr, meta):
                try:
                    f.unlink()
                except FileNotFoundError:
                    pass
        return None
    try:
        env = EnvironmentMap(image_path=str(exr), cache_hit=True, **m["result"])
    except TypeError:
        return None
    env.info = dict(m.get("info", {}), cache="hit")
    if progress:
        progress(f"reusing cached sky {exr.name}")
    return env


#: The files a cache folder holds: :func:`render_environment`'s entries and their
#: temporaries, and in :data:`SOLUTIONS_FOLDER` the multiple-scattering solutions that
#: :func:`solution_cache` stores (``SolutionCache.path``: ``solution-v<format>-<version>-<package tag>-<key>.pickle``)
#: and their temporaries (``<that name>.<random>.tmp``); a test checks the names still match.
CACHE_PATTERNS = ("sky-*.exr", "sky-*.json", ".sky-*.tmp")
#: The sub-folder of a cache folder where :func:`solution_cache` keeps solutions on disk.
SOLUTIONS_FOLDER = "solutions"
SOLUTION_PATTERNS = ("solution-v*.pickle", "solution-v*.pickle.*.tmp")


def _cache_files(folder):
    """The files of a cache folder named as :data:`CACHE_PATTERNS` and, in its
    :data:`SOLUTIONS_FOLDER`, as :data:`SOLUTION_PATTERNS` (no others)."""
    folder = Path(folder)
    found = {f for pat in CACHE_PATTERNS for f in folder.glob(pat)}
    found |= {f for pat in SOLUTION_PATTERNS for f in (folder / SOLUTIONS_FOLDER).glob(pat)}
    return sorted(f for f in found if f.is_file() and not f.is_symlink())


def cache_size(folder) -> tuple[int, int]:
    """``(files, bytes)`` of the cache entries in ``folder``, solutions included (0, 0 when
    it does not exist)."""
    files = _cache_files(folder)
    return len(files), sum(f.stat().st_size for f in files)


def clear_cache(folder, keep=()) -> tuple[int, int]:
    """Delete the cache entries in ``folder``: the sky images and their records
    (:data:`CACHE_PATTERNS`) and the multiple-scattering solutions on disk
    (:data:`SOLUTION_PATTERNS` in :data:`SOLUTIONS_FOLDER`, removed too when that leaves
    it empty); anything else stays, and so do the paths in ``keep``. Returns ``(files,
    bytes)`` freed. Solutions the running process holds in memory (:func:`solution_cache`)
    are not files and stay until it ends."""
    keep = {Path(k).resolve() for k in keep}
    n = size = 0
    for f in _cache_files(folder):
        if f.resolve() in keep:
            continue
        b = f.stat().st_size
        try:
            f.unlink()
        except OSError:
            continue
        n, size = n + 1, size + b
    try:
        (Path(folder) / SOLUTIONS_FOLDER).rmdir()  # only when empty
    except OSError:
        pass
    return n, size


def render_environment(atmosphere, sun_elevation_deg: float, sun_azimuth_deg: float, *,
                       earth_sun_distance_au: float = 1.0, observer_altitude_m: float = 0.0,
                       quality: str = "preview", width: int = 0, wavelength_step_nm: float | None = None,
                       orders: int | None = None, earth_shadow: bool = True, include_sun: bool = False,
                       time_iso: str | None = None, sky_model: str = OWN_MODEL, model_radiance=None,
                       cache_dir=None, progress=None, solutions=None, night: str = "auto"):
    """Render (or reuse) the equirectangular sky of ``atmosphere`` and the sun.

    Parameters
    ----------
    atmosphere : skymodel.optics.atmosphere.Atmosphere
    sun_elevation_deg, sun_azimuth_deg : float
        Sun position [degrees], azimuth clockwise from north.
    earth_sun_distance_au : float
        Scales the solar spectrum [AU].
    observer_altitude_m : float
        [m] above the ground.
    quality : str
        ``preview``, ``final`` or ``reference`` (the marcher's preset, and the default
        width and wavelength step: :data:`IMAGE_WIDTH`, :data:`WAVELENGTH_STEP_NM`).
    width : int
        Image width [px]; 0 = by quality.
    wavelength_step_nm, orders, earth_shadow
        Override the quality's wavelength step [nm], highest scattering order (0 = until
        converged) and Earth's shadow (the effect planner's choices); None = the quality's.
    include_sun : bool
        Draw the sun disc into the image.
    time_iso : str or None
        Recorded in ``info``; with ``night`` it places the moon and the stars (at the
        atmosphere's latitude and longitude).
    night : str
        ``auto`` (default; the registry's ``night``): with ``time_iso`` and our model, the
        night's light of :mod:`skymodel.render.night` is added before the gamut fit (the
        moonlit sky, stars and glow while the sun is below the horizon; the moon's disc only
        with ``include_sun``, since a renderer that draws the sun as a lamp draws the moon as
        one too: ``info["moon"]`` holds :func:`skymodel.render.night.moon_lamp`'s numbers);
        a sun below the registry's lowest elevation (-18) then renders no sunlit sky.
        ``off``: the sunlit sky only, as before. A daytime map without ``include_sun`` is
        the same image either way (nothing is added).
    sky_model, model_radiance
        Another sky model than ours: its name (part of the cache key) and
        ``model_radiance(camera, wavelengths_nm, include_sun) -> (radiance (H, W, n_wl),
        direct sun irradiance (n_wl,))`` in W m^-2 sr^-1 nm^-1 and W m^-2 nm^-1.
    cache_dir : path or None
        Where the EXR and its JSON go (:func:`default_cache_dir` when None).
    progress : callable or None
        Called with one line of text per stage.
    solutions : skymodel.render.sequence.SolutionCache or None
        Where the multiple-scattering solve comes from (our model): the frames of a
        sequence share it (the add-on's Bake Time of Day); None: :func:`solution_cache` of
        the cache folder (memory and disk), so a rebuild where only the sun or the time
        changed reuses the solve.

    Returns
    -------
    (rgb, EnvironmentMap)
        ``rgb`` (H, W, 3) float32 scene-linear Rec.709, None on a cache hit.
    """
    if sky_model != OWN_MODEL and model_radiance is None:
        raise ValueError(f"sky model {sky_model!r} needs model_radiance")
    from skymodel.render import night as night_module

    width = image_width(width, quality)
    step = float(wavelength_step_nm or WAVELENGTH_STEP_NM[quality])
    planned = {"orders": orders, "earth_shadow": earth_shadow} if (orders is not None or not earth_shadow) else {}
    # the night's light: only where it adds something (a daytime map without the discs is unchanged)
    night_on = (night_module.night_active(night, time_iso) and sky_model == OWN_MODEL
                and (include_sun or sun_elevation_deg < night_module.NIGHT_SUN_BELOW_DEG))
    sunlit = night_module.sunlit(sun_elevation_deg) or not night_on
    key = cache_key(atmosphere, sun_elevation_deg, sun_azimuth_deg, earth_sun_distance_au, observer_altitude_m,
                    quality, "environment", width=width, wavelength_step_nm=step, include_sun=bool(include_sun),
                    **({"sky_model": sky_model} if sky_model != OWN_MODEL else {}), **planned,
                    **({"night": {"time_utc": time_iso, "lat": atmosphere.latitude, "lon": atmosphere.longitude}}
                       if night_on else {}))
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    exr = folder / f"sky-{key}.exr"
    meta = folder / f"sky-{key}.json"
    cached = _read_cached(exr, meta, progress)
    if cached is not None:
        return None, cached
    t0 = time.perf_counter()
    wl = default_wavelengths(step)
    if progress:
        progress(f"optical profile: {len(wl)} wavelengths")
    prof = profile_at_distance(atmosphere, wl, earth_sun_distance_au)
    # Our sky is rendered band by band straight to RGB (the disc, if asked for, added before
    # the gamut fit), so only three values per pixel are kept (a 2048x1024 image at 81
    # wavelengths would otherwise hold a 1.4 GB spectral cube plus its working copies); the
    # memory guard counts that. Large images resample the sky-view table (skymodel.render.skyview).
    banded = sky_model == OWN_MODEL
    cam = environment_camera(width, n_wavelengths=3 if banded else wl.size)
    if progress:
        progress(f"spectral render {cam.width}x{cam.height}, quality {quality}")
    if sky_model == OWN_MODEL:
        settings = quality
        if planned:  # the planner's orders and Earth's shadow on the quality's settings
            settings = dataclasses.replace(render_sky.quality_settings(quality),
                                           orders=int(orders) or None if orders is not None else None,
                                           earth_shadow=bool(earth_shadow))
        # the memory guard of render_sky_reduced, before the solve rather than after it
        check_render_memory(cam.width, cam.height, wl.size, settings, wavelengths_nm=wl, image_channels=3,
                            band_pixels=ENV_BAND_PIXELS, sun_elevation_deg=sun_elevation_deg,
                            camera=cam)
        # only the sun or the time changed since the last build: the multiple-scattering
        # solution of this atmosphere is reused (memory, then the cache folder's solutions/)
        if solutions is None:
            solutions = solution_cache(folder)
        t_solve = time.perf_counter()
        solution = None
        # the moon's lamp numbers (info["moon"], the incident meter) also decide the solve
        moon = (night_module.moon_lamp(prof, atmosphere.latitude, atmosphere.longitude, time_iso, observer_altitude_m)
                if night_on else None)
        if sunlit or night_module.moonlit(moon.elevation_deg, sun_elevation_deg):  # a moonless night needs no solve
            solution = solutions.get(prof, settings, progress=_Orders(progress))
        solve_s = time.perf_counter() - t_solve
        if not night_on:
            rgb, sun_irradiance, render_info = render_sky.render_sky_reduced(
                prof, cam, sun_elevation_deg, rgb_reduction(wl, finish=fit_into_gamut), 3, sun_azimuth_deg,
                observer_altitude_m, settings, band_pixels=ENV_BAND_PIXELS, progress=_Orders(progress),
                solution=solution, include_sun=include_sun)
        else:  # sunlit (when the sun is above its bound) + the night's light, then the gamut fit
            linear = rgb_reduction(wl)
            rgb, sun_irradiance, render_info = np.zeros(cam.shape + (3,)), np.zeros(wl.size), {"method": None}
            if sunlit:
                rgb, sun_irradiance, render_info = render_sky.render_sky_reduced(
                    prof, cam, sun_elevation_deg, linear, 3, sun_azimuth_deg, observer_altitude_m, settings,
                    band_pixels=ENV_BAND_PIXELS, progress=_Orders(progress), solution=solution,
                    include_sun=include_sun)
            add, night_info = night_module.night_light(
                prof, cam, atmosphere.latitude, atmosphere.longitude, time_iso, linear.matrix,
                sun_elevation_deg=sun_elevation_deg, observer_altitude_m=observer_altitude_m, quality=settings,
                solution=solution, include_moon_disc=include_sun, band_pixels=ENV_BAND_PIXELS)
            rgb = fit_into_gamut(rgb + add)
    else:
        radiance, sun_irradiance = model_radiance(cam, wl, include_sun)
        rgb = reduce_to_rgb(radiance, wl)
    strength, colour = sun_lamp(sun_irradiance, wl)
    moon_h = 0.0
    if night_on and not include_sun:  # the moon lamp lights the scene as the sun lamp does
        moon_h = moon.strength * max(math.sin(math.radians(moon.elevation_deg)), 0.0)
    meter = display_exposure(rgb, cam, 0.0 if include_sun else strength, sun_elevation_deg, moon_h)  # disc: in rgb
    if not np.all(np.isfinite(rgb)):
        raise FloatingPointError("sky image: non-finite values")
    luma = rgb @ LUMA_709
    h = rgb.shape[0]
    env = EnvironmentMap(image_path=str(exr), cache_hit=False, sun_elevation_deg=sun_elevation_deg,
                         sun_azimuth_deg=sun_azimuth_deg, sun_strength=strength, sun_colour=list(colour),
                         sun_angle_deg=sun_angular_diameter_deg(earth_sun_distance_au),
                         exposure=meter["exposure"])
    info = {
        "render_s": round(time.perf_counter() - t0, 3),
        **({"solution_s": round(solve_s, 3), "method": render_info.get("method")} if sky_model == OWN_MODEL else {}),
        "size": f"{cam.width}x{cam.height}",
        "wavelengths": int(wl.size),
        **{k: v for k, v in meter.items() if k != "exposure"},
        "zenith_Y": float(luma[0].mean()),
        "horizon_Y": float(luma[h // 2 - 1].mean()),
        "atmosphere": {k: v for k, v in prof.metadata.items() if isinstance(v, (str, int, float, type(None)))},
        "time_utc": time_iso,
        "cache_key": key,
        "sky_model": sky_model,
        **({"night": {k: v for k, v in night_info.as_dict().items() if k != "timings"}, "moon": moon.lamp()}
           if night_on else {}),
    }
    if progress:
        progress(f"writing {exr}")
    image_io.write_exr(exr, rgb.astype(np.float32), chromaticities=image_io.CHROMATICITIES["rec709"],
                       attributes={"skymodel": json.dumps({"cache_key": key, "units": "Y = 1 <=> 683 cd/m2"})})
    _write_json_atomic(meta, {"result": env.lamp(), "info": info, "exr": file_digest(exr)})
    env.info = dict(info, cache="miss")
    return rgb.astype(np.float32), env
