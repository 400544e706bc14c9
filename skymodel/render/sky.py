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
from dataclasses import dataclass, field

import numpy as np

from skymodel import scene
from skymodel.render.cameras import Camera
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES, QUALITY, quality_settings
from skymodel.render.sun_transmittance import SUN_ANGULAR_RADIUS_RAD
from skymodel.render.threads import SOLVER_THREADS, in_threads

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
    (:mod:`skymodel.scene`: ``sun_elevation`` -18..90 deg, ``sun_azimuth``, finite) and the
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
               progress=None, solution=None, method: str = "auto", max_memory_gib=None,
               solutions=None) -> SkyImage:
    """Render ``camera``'s pixels for the atmosphere ``profile`` (smooth or layered).

    ``sun_elevation_deg`` [deg] in the registry's -18..90 (below is night: refused, not clamped;
    :mod:`skymodel.render.night` skips the sunlit sky there),
    ``sun_azimuth_deg`` [deg], ``observer_altitude_m`` [m]; ``quality``: a preset name, a
    MarchSettings, or None for the default quality (:mod:`skymodel.scene`, ``quality``).
    Every argument is checked before the march (:func:`check_render_arguments`), and the
    render's estimated peak memory against ``max_memory_gib`` [GiB] (None: the registry's
    ``max_memory``; :func:`skymodel.render.memory.check_render_memory`).
    ``solution``: a :class:`~skymodel.render.marcher.SkySolution` of this profile to reuse
    instead of solving multiple scattering again (:mod:`skymodel.render.sequence`).
    ``method``: ``"direct"`` marches every pixel, ``"table"`` resamples the sky-view table
    (:mod:`skymodel.render.skyview`), ``"auto"`` the table for images of at least
    ``TABLE_MIN_PIXELS`` valid pixels unless the settings ask for ``exact``.
    ``solutions``: where the solve comes from when ``solution`` is None: a
    :class:`~skymodel.render.sequence.SolutionCache`, None for the process's own
    (:func:`shared_solutions`: a render of the same atmosphere with another sun reuses the
    solve), False to solve afresh."""
    from skymodel.render.memory import check_render_memory

    settings = check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m,
                                      quality)
    sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings = settings
    method = _check_method(method)
    check_render_memory(camera.width, camera.height, profile.wavelengths_nm.size, settings, max_memory_gib,
                        wavelengths_nm=profile.wavelengths_nm, sky_view_table=None if method != "direct" else False,
                        sun_elevation_deg=sun_elevation_deg, camera=camera)
    t0 = time.perf_counter()
    solution = _solution(profile, settings, solution, solutions, progress)
    marcher = SkyMarcher(profile, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings,
                         progress=progress, solution=solution)
    dirs, valid = camera.directions()
    radiance, res_info, _ = _pixels(marcher, dirs, valid, None, profile.wavelengths_nm.size, None, method)
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
                       band_pixels: int = 65536, progress=None, solution=None, method: str = "auto",
                       include_sun: bool = False, solutions=None, max_memory_gib=None, dtype=np.float64):
    """Render ``camera`` without ever holding the whole spectral cube: each band of about
    ``band_pixels`` pixels is reduced to ``n_channels`` values at once, so memory grows with
    the image as ``n_channels`` values per pixel, not ``n_wl``.

    ``reduce``: a :class:`~skymodel.render.skyview.Reduction` (a linear map of the spectrum,
    then an optional per-pixel finish; e.g. :func:`~skymodel.render.skyview.xyz_reduction`),
    or any ``reduce(radiance (n, n_wl), wavelengths_nm) -> (n, n_channels)`` (then every
    pixel is marched: ``method`` is taken as ``"direct"``). ``method`` as in
    :func:`render_sky`: with a Reduction and ``"auto"``/``"table"`` the sky-view table is
    built in the reduced channels and resampled, so a 4096x2048 panorama holds 3 values a
    pixel. ``include_sun``: add the solar disc (:func:`sun_disc_spectra`) before the
    finish (the add-on leaves it out and draws a lamp). ``solution``, ``solutions``: as in
    :func:`render_sky`. ``max_memory_gib`` [GiB]: as in :func:`render_sky`, the limit of the
    same estimate (:func:`skymodel.render.memory.check_render_memory`, ``n_channels`` values
    a pixel, the spectra of ``band_pixels`` marched pixels), checked before any work.
    ``dtype``: the returned image's (each band is computed in float64 and stored in it;
    ``np.float32`` halves the image, e.g. for the CLI's colour output, whose EXR is float32).

    Returns ``(image (H, W, n_channels), sun_irradiance (n_wl,), info)``; invalid pixels are 0.
    """
    from skymodel.render.skyview import Reduction

    settings = check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m,
                                      quality)
    sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings = settings
    method = _check_method(method)
    if np.dtype(dtype) not in (np.dtype(np.float32), np.dtype(np.float64)):
        from skymodel.errors import SkymodelInputError

        raise SkymodelInputError("dtype", dtype, "numpy.float32 or numpy.float64")
    from skymodel.render.memory import check_render_memory

    check_render_memory(camera.width, camera.height, profile.wavelengths_nm.size, settings, max_memory_gib,
                        wavelengths_nm=profile.wavelengths_nm, image_channels=n_channels, band_pixels=band_pixels,
                        sky_view_table=None if isinstance(reduce, Reduction) and method != "direct" else False,
                        image_value_bytes=np.dtype(dtype).itemsize, sun_elevation_deg=sun_elevation_deg,
                        camera=camera)
    t0 = time.perf_counter()
    solution = _solution(profile, settings, solution, solutions, progress)
    marcher = SkyMarcher(profile, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, settings,
                         progress=progress, solution=solution)
    sun_irr = marcher.direct_sun_irradiance()
    disc = None
    if include_sun:
        disc = _sun_disc_of_camera(camera, marcher.sun, sun_irr, profile.wavelengths_nm)
    if isinstance(reduce, Reduction):
        # directions by bands of rows (the camera's): a panorama's are never all held at once
        out, info, bands = _pixels(marcher, camera, camera.valid_mask(), reduce, n_channels, band_pixels, method,
                                   disc, dtype=dtype)
    else:
        dirs, valid = camera.directions()
        if disc is not None:
            raise ValueError("include_sun needs a Reduction (the disc is added before the finish)")
        out, info, bands = _march_pixels(marcher, dirs, valid, reduce, n_channels, band_pixels, dtype=dtype)
        info["method"] = "direct"
    info["total_s"] = time.perf_counter() - t0
    info["bands"] = bands
    info["quality"] = _quality_name(quality)
    info["sun_pixels"] = 0 if disc is None else int(disc[0].sum())
    return out, sun_irr, info


#: Multiple-scattering solutions the process keeps in memory for :func:`shared_solutions`.
SHARED_SOLUTIONS = 2
_SHARED = []


def shared_solutions():
    """The process's :class:`~skymodel.render.sequence.SolutionCache` (memory only, the
    :data:`SHARED_SOLUTIONS` most recent): what :func:`render_sky` and
    :func:`render_sky_reduced` use when given neither ``solution`` nor ``solutions``."""
    if not _SHARED:
        from skymodel.render.sequence import SolutionCache

        _SHARED.append(SolutionCache(keep=SHARED_SOLUTIONS))
    return _SHARED[0]


def _solution(profile, settings, solution, solutions, progress):
    """The solution to march with: ``solution``, else from ``solutions`` (None: the shared
    cache; False: none, the marcher solves)."""
    if solution is not None or solutions is False:
        return solution
    cache = shared_solutions() if solutions is None else solutions
    return cache.get(profile, settings, progress=progress)


def sun_disc_spectra(directions, valid, solid_angles, sun_dir, irradiance, wavelengths_nm,
                     angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD, reach_rad=None):
    """The solar disc as :func:`add_sun_disc` draws it (limb darkened, irradiance
    conserved), without a spectral image: ``(mask (H, W), radiance (mask.sum(), n_wl))``.
    ``reach_rad``: how far from the sun pixels are considered (None: add_sun_disc's
    fallback reach from these pixels' largest solid angle)."""
    from skymodel import sun as sun_module

    n_wl = len(wavelengths_nm)
    mask = np.zeros(valid.shape, bool)
    if not np.any(np.asarray(irradiance) > 0):
        return mask, np.zeros((0, n_wl))
    reach = (4 * angular_radius_rad + 2.0 * float(np.sqrt(np.max(solid_angles))) if reach_rad is None
             else float(reach_rad))  # add_sun_disc's fallback reach
    near = valid & (directions @ np.asarray(sun_dir, float) > np.cos(min(reach, np.pi)))
    rows = np.nonzero(near.any(axis=1))[0]
    cols = np.nonzero(near.any(axis=0))[0]
    if rows.size == 0:  # add_sun_disc's own fallback: the nearest valid pixel anywhere
        rows, cols = np.arange(valid.shape[0]), np.arange(valid.shape[1])
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    sub = np.zeros((r1 - r0, c1 - c0, n_wl))
    inside = add_sun_disc(sub, directions[r0:r1, c0:c1], valid[r0:r1, c0:c1], solid_angles[r0:r1, c0:c1], sun_dir,
                          irradiance, wavelengths_nm, angular_radius_rad,
                          limb_darkening=getattr(sun_module, "limb_darkening", None))
    mask[r0:r1, c0:c1] = inside
    return mask, sub[inside]


def _sun_disc_of_camera(camera, sun_dir, irradiance, wavelengths_nm, rows: int = 256):
    """:func:`sun_disc_spectra` of ``camera``'s pixels, finding the pixels near the sun by
    bands of ``rows`` rows (``Camera.directions_rows``), so that every pixel's direction is
    never held at once; the same result."""
    n_wl = len(wavelengths_nm)
    valid = camera.valid_mask()
    if not np.any(np.asarray(irradiance) > 0):
        return np.zeros(valid.shape, bool), np.zeros((0, n_wl))
    solid = camera.pixel_solid_angles()
    reach = 4 * SUN_ANGULAR_RADIUS_RAD + 2.0 * float(np.sqrt(np.max(solid)))  # sun_disc_spectra's
    cos_reach = np.cos(min(reach, np.pi))
    near_rows, near_cols = [], np.zeros(valid.shape[1], bool)
    for r0 in range(0, valid.shape[0], rows):
        d = camera.directions_rows(r0, r0 + rows)[0]
        near = valid[r0:r0 + rows] & (d @ np.asarray(sun_dir, float) > cos_reach)
        near_rows.extend(r0 + np.nonzero(near.any(axis=1))[0])
        near_cols |= near.any(axis=0)
    if not near_rows:  # sun_disc_spectra's fallback searches the whole image
        d, _ = camera.directions()
        return sun_disc_spectra(d, valid, solid, sun_dir, irradiance, wavelengths_nm)
    r0, r1 = near_rows[0], near_rows[-1] + 1
    cols = np.nonzero(near_cols)[0]
    c0, c1 = cols[0], cols[-1] + 1
    d = camera.directions_rows(r0, r1)[0][:, c0:c1]
    # the same rectangle sun_disc_spectra would cut, with the whole image's reach (its solid angles' maximum)
    sub_mask, spectra = sun_disc_spectra(d, valid[r0:r1, c0:c1], solid[r0:r1, c0:c1], sun_dir, irradiance,
                                         wavelengths_nm, reach_rad=reach)
    mask = np.zeros(valid.shape, bool)
    mask[r0:r1, c0:c1] = sub_mask
    return mask, spectra


def _check_method(method) -> str:
    from skymodel.errors import SkymodelInputError

    m = str(method).lower() if isinstance(method, str) else method
    if m not in ("auto", "table", "direct"):
        raise SkymodelInputError("method", method, "one of: auto, table, direct")
    return m


def _use_table(marcher, valid, method: str) -> bool:
    from skymodel.render.skyview import TABLE_MIN_PIXELS

    if method == "direct" or marcher._grid is None:
        return False
    return method == "table" or int(valid.sum()) >= TABLE_MIN_PIXELS


def _pixels(marcher, dirs, valid, reduction, n_channels: int, band_pixels, method: str, disc=None,
            dtype=np.float64):
    """The valid pixels of a camera through the sky-view table (:mod:`skymodel.render.skyview`)
    or marched directly (:meth:`~skymodel.render.marcher.SkyMarcher.total_radiance`), as
    ``method`` says (:func:`_use_table`). ``dirs``: the pixels' directions (H, W, 3), or the
    :class:`~skymodel.render.cameras.Camera`, which then gives each band's rows only
    (``directions_rows``), so every pixel's direction is never held at once. A band is
    ``band_pixels`` valid pixels in row-major order (None: all). ``reduction``: a
    :class:`~skymodel.render.skyview.Reduction` or None (spectra); ``disc``: ``(mask,
    spectra)`` of the solar disc, added before the reduction's finish. ``dtype``: the
    image's (each band is computed in float64).
    Returns ``(image (H, W, n_channels), info, number of bands)``."""
    from skymodel.render.skyview import Reduction, SkyViewTable

    red = reduction if reduction is not None else Reduction(None, int(n_channels))
    h, w = valid.shape
    out = np.zeros((h * w, int(n_channels)), dtype=dtype)
    per_row = valid.sum(axis=1)
    before = np.concatenate([[0], np.cumsum(per_row)])  # valid pixels before each row
    total = int(before[-1])
    band = total if band_pixels is None else max(1, int(band_pixels))
    disc_at = {}
    if disc is not None and disc[1].shape[0]:
        disc_at = dict(zip(np.nonzero(disc[0].ravel())[0].tolist(), red.linear(disc[1])))
    t_start = time.perf_counter()
    table = SkyViewTable(marcher, red) if _use_table(marcher, valid, method) else None

    def one_band(start):  # writes its own pixels of ``out``
        stop = min(total, start + band)
        r0 = int(np.searchsorted(before, start, side="right")) - 1  # the rows holding valid pixels start..stop-1
        r1 = int(np.searchsorted(before, stop, side="left"))
        d_rows = dirs[r0:r1] if isinstance(dirs, np.ndarray) else dirs.directions_rows(r0, r1)[0]
        local = np.nonzero(valid[r0:r1].ravel())[0][start - before[r0]:stop - before[r0]]
        idx = r0 * w + local
        d = d_rows.reshape(-1, 3)[local]
        del d_rows
        if table is not None:
            part = table.lookup(d)
        else:  # the grid's total, reduced once, or marched (= red.linear(marcher.radiance(..).radiance))
            part = marcher.total_radiance(d, red.matrix)
        if disc_at:
            hit = np.nonzero(np.isin(idx, list(disc_at)))[0]
            for k in hit:
                part[k] = part[k] + disc_at[int(idx[k])]
        out[idx] = red.final(part).reshape(idx.size, -1)

    starts = range(0, total, max(band, 1))
    if table is not None:  # the table's look-ups on the solver's threads (numpy releases the GIL)
        in_threads(one_band, starts, SOLVER_THREADS)
    else:  # marching runs its own threads
        for start in starts:
            one_band(start)
    bands = len(starts)
    info = {"orders": marcher.field.orders, "order_contributions": list(marcher.field.order_contributions),
            "timings": dict(marcher.timings, directions_s=time.perf_counter() - t_start),
            "settings": marcher.settings, "method": "table" if table is not None else "direct"}
    if table is not None:
        info["timings"].update(table.timings)
        info["table_nodes"] = table.n_nodes
        info["table_exact_pixels"] = table.exact_pixels
    return out.reshape(h, w, int(n_channels)), info, bands


def _march_pixels(marcher, dirs, valid, reduce, n_channels: int, band_pixels, dtype=np.float64):
    """March the valid pixels of a camera: ``(image (H, W, n_channels), the marcher's info,
    number of bands)``. ``reduce(radiance (n, n_wl), wavelengths_nm) -> (n, n_channels)`` is
    applied to each band of at most ``band_pixels`` pixels (None: keep the spectra; all
    pixels in one band); invalid pixels are 0; the image in ``dtype``."""
    h, w = valid.shape
    out = np.zeros((h * w, int(n_channels)), dtype=dtype)
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
