"""Rendering a sky image: atmosphere + sun + camera -> spectral radiance per pixel.

Quality presets name a set of :class:`~skymodel.render.marcher.MarchSettings`
(:mod:`skymodel.render.quality`; ``quality=None`` is the default quality of
:mod:`skymodel.scene`). The sun disc is added to the pixels it covers, limb
darkened, with its total irradiance conserved: the disc radiance is spread over the
pixels whose centres fall inside it and normalised so that the sum of radiance x pixel
solid angle equals the direct solar irradiance at the observer; a disc smaller than a
pixel lands in the pixel that contains its centre.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from skymodel import scene
from skymodel.render.cameras import Camera
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES, QUALITY, quality_settings
from skymodel.render.sun_transmittance import SUN_ANGULAR_RADIUS_RAD

# The quality presets live in skymodel.render.quality (re-exported here for older callers).
__all__ = ["QUALITY", "QUALITIES", "quality_settings", "SkyImage", "add_sun_disc", "render_sky",
           "render_sky_reduced"]


def _quality_name(quality) -> str:
    """The name reported in ``info["quality"]``: the preset's (the default's for None) or "custom"."""
    if quality is None:
        return scene.default("quality")
    return str(quality).lower() if isinstance(quality, str) else "custom"


@dataclass
class SkyImage:
    """A rendered image: spectral radiance (H, W, n_wl) in W m^-2 sr^-1 nm^-1."""

    radiance: np.ndarray
    valid: np.ndarray
    directions: np.ndarray
    wavelengths_nm: np.ndarray
    camera: Camera
    sun_direction: np.ndarray
    sun_irradiance: np.ndarray  # direct solar irradiance at the observer, W m^-2 nm^-1
    info: dict = field(default_factory=dict)


def add_sun_disc(radiance, directions, valid, solid_angles, sun_dir, irradiance, wavelengths_nm,
                 angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD, limb_darkening=None) -> np.ndarray:
    """Add the solar disc to ``radiance`` (H, W, n_wl) in place; returns the pixel mask
    it touched. ``limb_darkening(wavelengths_nm, mu)`` -> I(mu)/I(1) shaped mu.shape + (n_wl,)."""
    if not np.any(irradiance > 0):
        return np.zeros(valid.shape, bool)
    cosang = np.clip(directions @ sun_dir, -1.0, 1.0)
    ang = np.arccos(cosang)
    inside = valid & (ang <= angular_radius_rad)
    if not np.any(inside):
        # the disc falls between pixel centres: the nearest valid pixel takes it all
        a = np.where(valid, ang, np.inf)
        idx = np.unravel_index(np.argmin(a), a.shape)
        if not np.isfinite(a[idx]) or a[idx] > 4 * angular_radius_rad + np.sqrt(solid_angles[idx]):
            return np.zeros(valid.shape, bool)
        inside = np.zeros(valid.shape, bool)
        inside[idx] = True
    rho = np.clip(ang[inside] / angular_radius_rad, 0.0, 1.0)
    mu = np.sqrt(1.0 - rho**2)
    if limb_darkening is None:
        profile = np.ones(mu.shape + (len(wavelengths_nm),))
    else:
        profile = np.asarray(limb_darkening(wavelengths_nm, mu), dtype=float)
    weight = profile * solid_angles[inside][:, None]
    total = weight.sum(axis=0)
    radiance[inside] += profile * (irradiance / np.where(total > 0, total, 1.0))
    return inside


def check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, quality=None):
    """Validate the arguments of a render before any work: the profile and camera types,
    the sun's elevation and azimuth and the observer's altitude against the registry
    (:mod:`skymodel.scene`: ``sun_elevation`` -12..90 deg, ``sun_azimuth``, finite) and the
    quality. Returns ``(sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings)``.
    Raises :class:`~skymodel.errors.SkymodelInputError` naming the parameter."""
    from skymodel.errors import SkymodelInputError
    from skymodel.optics.profile import LayeredProfile, OpticalProfile

    if not isinstance(profile, (OpticalProfile, LayeredProfile)):
        raise SkymodelInputError("profile", type(profile).__name__,
                                 "an OpticalProfile or LayeredProfile (Atmosphere(...).optical_profile())")
    if not isinstance(camera, Camera):
        raise SkymodelInputError("camera", type(camera).__name__, "a Camera from skymodel.render.cameras.make_camera")
    el = scene.check("sun_elevation", sun_elevation_deg)
    az = scene.check("sun_azimuth", sun_azimuth_deg)
    alt = scene.check("observer_altitude", observer_altitude_m)
    return el, az, alt, quality_settings(quality)


def render_sky(profile, camera: Camera, sun_elevation_deg: float, sun_azimuth_deg: float = 180.0,
               observer_altitude_m: float = 0.0, quality=None, include_sun: bool = True,
               progress=None, solution=None, max_memory_gib=None) -> SkyImage:
    """Render ``camera``'s pixels for the atmosphere ``profile`` (smooth or layered).

    ``sun_elevation_deg`` [deg] in -12..90 (below -12 is night: refused, not clamped),
    ``sun_azimuth_deg`` [deg], ``observer_altitude_m`` [m]; ``quality``: a preset name, a
    MarchSettings, or None for the default quality (:mod:`skymodel.scene`, ``quality``).
    Every argument is checked before the march (:func:`check_render_arguments`), and the
    render's estimated peak memory against ``max_memory_gib`` [GiB] (None: the registry's
    ``max_memory``; :func:`skymodel.render.memory.check_render_memory`).
    ``solution``: a :class:`~skymodel.render.marcher.SkySolution` of this profile to reuse
    instead of solving multiple scattering again (:mod:`skymodel.render.sequence`)."""
    from skymodel.render.memory import check_render_memory

    settings = check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m,
                                      quality)
    sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings = settings
    check_render_memory(camera.width, camera.height, profile.wavelengths_nm.size, settings, max_memory_gib,
                        wavelengths_nm=profile.wavelengths_nm)
    t0 = time.perf_counter()
    marcher = SkyMarcher(profile, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings,
                         progress=progress, solution=solution)
    dirs, valid = camera.directions()
    radiance, res_info, _ = _march_pixels(marcher, dirs, valid, None, profile.wavelengths_nm.size, None)
    sun_irr = marcher.direct_sun_irradiance()
    sun_mask = np.zeros(valid.shape, bool)
    if include_sun:
        from skymodel import sun as sun_module

        sun_mask = add_sun_disc(radiance, dirs, valid, camera.pixel_solid_angles(), marcher.sun, sun_irr,
                                profile.wavelengths_nm, limb_darkening=getattr(sun_module, "limb_darkening", None))
    info = res_info
    info["total_s"] = time.perf_counter() - t0
    info["sun_pixels"] = int(sun_mask.sum())
    info["quality"] = _quality_name(quality)
    return SkyImage(radiance, valid, dirs, profile.wavelengths_nm, camera, marcher.sun, sun_irr, info)


def render_sky_reduced(profile, camera: Camera, sun_elevation_deg: float, reduce, n_channels: int,
                       sun_azimuth_deg: float = 180.0, observer_altitude_m: float = 0.0, quality=None,
                       band_pixels: int = 65536, progress=None, solution=None):
    """Render ``camera`` without ever holding the whole spectral cube: the image is marched
    in bands of about ``band_pixels`` pixels and each band's spectra are reduced at once by
    ``reduce(radiance (n, n_wl), wavelengths_nm) -> (n, n_channels)`` (e.g. to scene-linear
    RGB). Memory then grows with the image as ``n_channels`` values per pixel, not
    ``n_wl``. The sun disc is not added (a renderer that wants it draws a lamp).
    ``solution``: as in :func:`render_sky`.

    Returns ``(image (H, W, n_channels), sun_irradiance (n_wl,), info)``; invalid pixels are 0.
    """
    settings = check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m,
                                      quality)
    sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings = settings
    t0 = time.perf_counter()
    marcher = SkyMarcher(profile, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings,
                         progress=progress, solution=solution)
    dirs, valid = camera.directions()
    out, info, bands = _march_pixels(marcher, dirs, valid, reduce, n_channels, band_pixels)
    info["total_s"] = time.perf_counter() - t0
    info["bands"] = bands
    info["quality"] = _quality_name(quality)
    return out, marcher.direct_sun_irradiance(), info


def _march_pixels(marcher, dirs, valid, reduce, n_channels: int, band_pixels):
    """March the valid pixels of a camera: ``(image (H, W, n_channels), the marcher's info,
    number of bands)``. ``reduce(radiance (n, n_wl), wavelengths_nm) -> (n, n_channels)`` is
    applied to each band of at most ``band_pixels`` pixels (None: keep the spectra; all
    pixels in one band); invalid pixels are 0."""
    h, w = valid.shape
    out = np.zeros((h * w, int(n_channels)))
    flat = dirs.reshape(-1, 3)
    sel = np.nonzero(valid.ravel())[0]
    band = sel.size if band_pixels is None else max(1, int(band_pixels))
    info, bands = {}, 0
    for start in range(0, sel.size, max(band, 1)):
        idx = sel[start:start + band]
        res = marcher.radiance(flat[idx])
        part = res.radiance if reduce is None else reduce(res.radiance, res.wavelengths_nm)
        out[idx] = np.asarray(part, dtype=float).reshape(idx.size, -1)
        info, bands = dict(res.info), bands + 1
    return out.reshape(h, w, int(n_channels)), info, bands
