"""The memory guard: what a spectral render will need, estimated before any work.

A render goes through three phases, each with its own peak; the arrays of one phase are
freed before the next, so the estimate (:func:`estimate_render_memory`) is the base plus
the largest phase, not the sum:

* ``base``: the interpreter with numpy, scipy and skymodel imported (:data:`BASE_BYTES`);
* ``tables``: building the quality's tables, which do not grow with the image: the
  sun-transmittance table (:data:`SUN_TABLE_BYTES_PER_SAMPLE` per ray sample, altitudes x
  x-nodes x steps) and the multiple-scattering solve (:data:`SOLVE_BYTES` plus
  :data:`TRANSPORT_COPIES` float64 transport matrices of (table_altitudes x table_mu)^2 x
  solver wavelengths plus :data:`FIELD_COPIES` float32 fields of solver wavelengths x
  table_mu x table_phi x table_altitudes x table_mus);
* ``bands``: marching one band of directions exactly, ``min(chunk, MARCH_PIECE, directions
  marched exactly) x view_steps x n_wl`` float64 values (the sky-view table's sun cap, or the
  pixels near the sun of a render marched directly), :data:`BAND_COPIES` of them alive at once
  over the marcher's threads (:meth:`skymodel.render.marcher.SkyMarcher._exact`), with the tables
  kept, and :data:`SKYVIEW_TABLE_BYTES` more while the sky-view table is built or
  :data:`DIRECT_MARCH_BYTES` in a render marched directly; the sun cap of a sun clear of the
  horizon marches a quarter of its nodes, the pixels near the sun are counted by the camera,
  when the caller gives the sun and the camera;
* ``image``: the float64 spectral cube ``H x W x n_wl``, :data:`IMAGE_COPIES` of them
  (single, multiple and ground parts, their sum, the image, the writers' conversions), or
  :data:`NEAR_SUN_CUBES` of them while the pixels near the sun are marched in bands, with the tables kept;
  :data:`TABLE_IMAGE_COPIES` when the image is resampled from the sky-view table
  (:mod:`skymodel.render.skyview`, images of ``TABLE_MIN_PIXELS`` pixels or more); a render
  reduced to colour keeps 3 values a pixel (``image_value_bytes`` each: float32 for
  ``skymodel render``) plus the spectra of the band's pixels near the sun it marches, or,
  through the table, its image, :data:`REDUCED_TABLE_PIXEL_BYTES` a pixel (the mask, then
  the writers' own images, :func:`skymodel.render.image_io.save_outputs`: the EXR's float32
  pixels, the float64 luminance, the 8-bit PNG) and :data:`REDUCED_TABLE_BAND_BYTES` a pixel
  of the band it looks up.

The constants were measured, not derived (peak of each phase with ``tracemalloc`` for
the preview and final presets, ``benchmarks/bench_memory_phases.py``, then the whole
render's peak resident memory):
``benchmarks/bench_memory.py`` renders a grid of qualities x image sizes with ``skymodel
render`` in child processes and compares this estimate with each child's peak resident
memory (``ru_maxrss``); docs/reliability.md ("Memory guard") has the table and the
command. The target is the peak within 25 %; the default atmosphere was measured (an
aerosol type with more components has a few more basis functions in the tables).

:func:`check_render_memory` refuses a render whose estimate exceeds the limit, the
``max_memory`` parameter of :mod:`skymodel.scene` (GiB; ``--max-memory`` on the command
line, ``max_memory_gib=`` in :func:`~skymodel.render.sky.render_sky`), with a
:class:`~skymodel.errors.SkymodelInputError` that shows the estimate and its parts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from skymodel import scene
from skymodel.errors import SkymodelInputError

__all__ = ["MemoryEstimate", "estimate_render_memory", "check_render_memory", "limit_bytes"]

GIB = 1024**3
#: Resident memory of a process that has imported skymodel's renderer and its writers [bytes] (measured).
BASE_BYTES = 90 * 1024**2
#: Peak bytes per ray sample while the sun-transmittance table is built (measured with ``tracemalloc``
#: at f78aa99: 23 preview, 15 final; 366 and 345 before #23's speed work).
SUN_TABLE_BYTES_PER_SAMPLE = 25.0
#: The tables' build (the multiple-scattering solve and what ``solve_sky`` builds around it) apart from the
#: transport matrices and the fields [bytes], fitted with :data:`TRANSPORT_COPIES` and :data:`FIELD_COPIES`
#: to ``solve_sky``'s ``tracemalloc`` peak (81 wavelengths, the default sky) at 39cc156: 0.122 GiB preview,
#: 0.958 final with 12 solver azimuths, 1.466 final (24), which the fit reproduces, and 1.866 reference,
#: which it puts at 1.83. Before (f78aa99, no field term): 0.15 GiB and 1.6 transport matrices, which
#: read `final`'s 24 azimuths 0.5 GiB low.
SOLVE_BYTES = 0.086 * GIB
#: float64 transport matrices ((table_altitudes x table_mu)^2 x solver wavelengths) alive at once (fitted:
#: the float32 matrix M and its work arrays).
TRANSPORT_COPIES = 0.73
#: float32 fields (solver wavelengths x table_mu x table_phi x table_altitudes x table_mus) alive at once at
#: the solve's peak (fitted: the orders' source, radiance, the scattering step's modes, the transport's
#: layouts; the spherical correction's and the coarse orders' arrays are smaller).
FIELD_COPIES = 6.8
#: float64 arrays per direction marched exactly (view_steps x n_wl) alive at once, over the marcher's
#: threads, for min(chunk, MARCH_PIECE, directions marched exactly) directions in flight: the sun cap's
#: nodes of the sky-view table, or the pixels near the sun of a render marched directly (the direction
#: grid's own march keeps far less: 0.016 GiB at preview 128x64). Measured with ``tracemalloc`` at
#: f78aa99: 20.7 (preview) and 19.7 (final) for pieces of 1024 directions; 26 before the speed work of
#: #23, 15-16.5 before the marcher split its pieces over threads. 15.2 at 318964e (final 512x256, a piece
#: 0.599 GiB above its entry: ``benchmarks/bench_memory_phases.py final 512x256``), after the per-sun
#: march moved to float32 (e1e79d4).
BAND_COPIES = 15.5
#: The sky-view table's build over the marching bands (its nodes: the grid and the sun's cap) [bytes]
#: (measured: the colour render's preview 1024x512 peak over its 512x256 peak, 0.17-0.22 GiB at 9fe0b71;
#: at final the table's renders peaked at 1.15-1.21 GiB against 1.15 for the marched 512x256: 0.15 splits them).
SKYVIEW_TABLE_BYTES = 0.15 * GIB
#: A direct march of the pixels near the sun (no sky-view table) besides its bands [bytes]: the march's
#: state on entry and the threads' unreturned pages (measured at dba4305 with the pixels counted by the
#: camera: the colour preview 512x256 equirectangular at sun 25 peaked at 0.41-0.49 GiB over 6 runs against
#: 0.33 estimated without it; ``tracemalloc`` traced 0.06 GiB at the march's entry and 0.29 at its peak).
DIRECT_MARCH_BYTES = 0.12 * GIB
#: The peak tables a solution keeps through the march [bytes per cell of their grid, angles x peak depths
#: (``marcher.AUREOLE_TABLE_ANGLES`` x ``AUREOLE_TABLE_DEPTHS``), per wavelength]: the aureole's correction
#: table in float64 and the marcher's float32 copy; with ``MarchSettings.peak_spread`` the first
#: scattering's spread table (float32) for each of :data:`PEAK_SPREAD_REGIMES` aerosol regimes. Counted since
#: ``preview`` took the spread (2026-11-30): its colour 128x64 render peaked at 0.34 GiB against 0.26
#: estimated without them.
AUREOLE_TABLE_BYTES = 8 + 4
SPREAD_TABLE_BYTES = 4
#: Aerosol regimes of a sky (every location's has 2: its boundary-layer type and the stratospheric background).
PEAK_SPREAD_REGIMES = 2
#: float64 spectral cubes (H x W x n_wl) alive at once, render and writers (measured).
IMAGE_COPIES = 6.0
#: ... when the image is resampled from the sky-view table (measured with ``skymodel render --spectral`` at
#: f78aa99: 3.5 from the 2400x1200 preview at 10 nm, 3.18 GiB, and 3.7 from the 1024x512 preview at 5 nm;
#: 3.6-3.9 at 1ea5f38, 4.7-4.8 before #23's speed work; it was 4.5 to keep the 2400x1200 case refused at the
#: default 4 GiB, which it no longer needs: that render fits).
TABLE_IMAGE_COPIES = 3.8
#: ... while the pixels near the sun are marched in bands, besides those bands (measured: the --spectral preview
#: 512x256 peak, 0.59 GiB at 1ea5f38, is its marching bands'; 3 before #23's speed work).
NEAR_SUN_CUBES = 1.0
#: A render reduced to colour through the sky-view table (``image_channels`` fewer than the wavelengths): bytes a pixel
#: besides its image (H x W x image_channels values): the mask, then the writers' images (the EXR's 12 bytes, the
#: luminance's 8, the PNG's 3 and its rows' 3) (measured: 27 bytes a pixel with a float32 image, from the colour
#: render's peaks at preview and final 8192x4096, equirectangular, f78aa99: 1.18-1.26 and 1.36-1.44 GiB over
#: runs; 27 bytes at 9fe0b71, before #23's speed work).
REDUCED_TABLE_PIXEL_BYTES = 18.0
#: ... and bytes per pixel of the band being looked up (``band_pixels``; its directions, the lookup's and the
#: colour finish's temporaries; measured with ``tracemalloc``: 0.24 GiB for a band of 2^20 pixels at f78aa99,
#: 0.35 GiB at 9fe0b71, 0.379-0.410 GiB at e44107b (``benchmarks/bench_memory_phases.py preview`` 2048x1024,
#: 4096x2048, 8192x4096), where 260 put the colour preview 4096x2048's estimate at 0.71-0.75 of its peak).
REDUCED_TABLE_BAND_BYTES = 380.0
#: The tables kept through the march, in float64 transport matrices (the float32 copy, the field, the
#: allocator's unreturned pages; measured: 0.18 GiB traced at the final preset's march, 0.56 of its
#: transport matrices, at f78aa99; 1.0 before #23's speed work).
KEPT_TABLES = 0.6


@dataclass(frozen=True)
class MemoryEstimate:
    """An estimate of a render's peak resident memory [bytes]: the base plus the
    largest of its phases (tables, bands, image; each includes what earlier phases keep)."""

    base: int
    tables: int
    bands: int
    image: int

    @property
    def total(self) -> int:
        return self.base + max(self.tables, self.bands, self.image)

    @property
    def gib(self) -> float:
        return self.total / GIB

    def text(self) -> str:
        """``'1.23 GiB (base 0.06 + the largest phase of: tables 0.40, bands 0.80, image 0.17 GiB)'``."""
        return (f"{self.total / GIB:.2f} GiB (base {self.base / GIB:.2f} + the largest phase of: tables "
                f"{self.tables / GIB:.2f}, bands {self.bands / GIB:.2f}, image {self.image / GIB:.2f} GiB)")


def _n_solver_wavelengths(n_wavelengths: int, wavelengths_nm, settings) -> int:
    """How many wavelengths the multiple-scattering solver uses with the march ``settings``
    (an evenly spaced grid over the tabulated range when ``wavelengths_nm`` is not given)."""
    import numpy as np

    from skymodel.render.marcher import settings_solver_wavelengths
    from skymodel.wavelengths import default_wavelengths

    if wavelengths_nm is None:
        lo, hi = default_wavelengths()[[0, -1]]
        wavelengths_nm = np.linspace(lo, hi, max(int(n_wavelengths), 1))
    return int(settings_solver_wavelengths(np.asarray(wavelengths_nm, dtype=float), settings).size)


def _march_piece() -> int:
    """Directions the marcher has in flight at once (over all its threads)."""
    from skymodel.render import marcher

    return int(getattr(marcher, "MARCH_PIECE", 1 << 30))


def _table_min_pixels() -> int:
    """Images from this many pixels go through the sky-view table (no per-pixel spectra)."""
    try:
        from skymodel.render.skyview import TABLE_MIN_PIXELS
    except ImportError:  # pragma: no cover - a renderer without the table
        return 1 << 62
    return int(TABLE_MIN_PIXELS)


def _cap_nodes(sun_exact_deg: float, sun_elevation_deg=None) -> int:
    """Directions the sky-view table's sun cap marches exactly: a cap clear of the horizon
    (:func:`skymodel.render.skyview.cap_is_clear`, judged against an observer on the ground,
    whose horizon is the lowest) keeps every other node; ``sun_elevation_deg`` None [deg]:
    the full cap (the larger)."""
    from skymodel.render.skyview import cap_is_clear, cap_shape

    clear = sun_elevation_deg is not None and cap_is_clear(math.radians(90.0 - float(sun_elevation_deg)),
                                                            sun_exact_deg, math.pi / 2)
    radial, around = cap_shape(sun_exact_deg, clear)
    return int(radial) * int(around)


def estimate_render_memory(width: int, height: int, n_wavelengths: int, quality=None, *, wavelengths_nm=None,
                           n_pixels: int | None = None, image_channels: int | None = None,
                           band_pixels: int | None = None, sky_view_table: bool | None = None,
                           image_value_bytes: int = 8, sun_elevation_deg: float | None = None,
                           camera=None) -> MemoryEstimate:
    """Estimated peak resident memory of rendering ``width x height`` pixels at
    ``n_wavelengths`` wavelengths with ``quality`` (a preset name, a MarchSettings, or
    None for the default quality); ``wavelengths_nm`` (optional) gives the solver's
    wavelength count exactly; ``n_pixels`` the pixels marched (default all);
    ``image_channels`` the values kept per pixel (default ``n_wavelengths``: the spectral
    cube; 3 for a render reduced to colour band by band, whose pixels marched directly
    hold the spectra of ``band_pixels`` of them at once, default all; images of at least
    ``skymodel.render.skyview.TABLE_MIN_PIXELS`` pixels go through the sky-view table;
    ``sky_view_table=False``: every pixel is marched whatever the size, as a render with
    ``method="direct"`` does; None: by the size); ``image_value_bytes``: bytes of one value
    of the kept image (8: float64; 4: the float32 image of ``render_sky_reduced(dtype=np.float32)``,
    as ``skymodel render`` keeps its colour image); ``sun_elevation_deg`` [deg]: the sun's, which
    decides how many directions the sky-view table's sun cap marches (a cap clear of the horizon
    marches a quarter of them); None counts the full cap, the larger estimate; ``camera``: the
    :class:`~skymodel.render.cameras.Camera`: with the sun, the pixels a direct march evaluates
    near the sun are counted (:meth:`~skymodel.render.cameras.Camera.pixels_near`), otherwise
    the share ``1 - cos(sun_exact_deg)`` of all pixels (a hemisphere's; about twice a panorama's)."""
    from skymodel.render.marcher import AUREOLE_TABLE_ANGLES, AUREOLE_TABLE_DEPTHS
    from skymodel.render.quality import quality_settings

    s = quality_settings(quality)
    w, h, n_wl = int(width), int(height), int(n_wavelengths)
    pixels = w * h if n_pixels is None else int(n_pixels)
    n_ms = _n_solver_wavelengths(n_wl, wavelengths_nm, s)
    transport = (s.table_altitudes * s.table_mu) ** 2 * n_ms * 8.0
    field = n_ms * s.table_mu * s.table_phi * s.table_altitudes * s.table_mus * 4.0
    sun_build = SUN_TABLE_BYTES_PER_SAMPLE * s.sun_table_altitudes * s.sun_table_x * s.sun_table_steps
    tables = max(sun_build, SOLVE_BYTES + TRANSPORT_COPIES * transport + FIELD_COPIES * field)
    grid_dirs = 0 if s.exact else (s.grid_zenith + s.grid_zenith_ground) * s.grid_azimuth
    cells = AUREOLE_TABLE_ANGLES * AUREOLE_TABLE_DEPTHS * n_wl
    peak_tables = (AUREOLE_TABLE_BYTES + (PEAK_SPREAD_REGIMES * SPREAD_TABLE_BYTES if s.peak_spread else 0)) * cells
    kept = KEPT_TABLES * transport + grid_dirs * n_wl * 8 * 3 + (peak_tables if s.peak_aureole else 0)
    per_direction = s.view_steps * n_wl * 8.0  # one float64 band array per marched direction
    table = not s.exact and pixels >= _table_min_pixels() and sky_view_table is not False
    # with a direction grid the pixels near the sun are still marched, in bands, while the
    # three parts of the cube are held (a hemisphere camera: up to 1 - cos(sun_exact) of them)
    if s.exact:
        near = pixels
    elif camera is not None and sun_elevation_deg is not None:
        near = min(pixels, int(camera.pixels_near(90.0 - float(sun_elevation_deg), s.sun_exact_deg)))
    else:
        near = math.ceil(pixels * (1.0 - math.cos(math.radians(s.sun_exact_deg))))
    exact_dirs = _cap_nodes(s.sun_exact_deg, sun_elevation_deg) if table else near  # the directions marched exactly
    marched = max(min(s.chunk, _march_piece(), max(exact_dirs, 1)), 1)
    bands = kept + BAND_COPIES * marched * per_direction
    if table:  # the sky-view table's build: its nodes marched (the grid, the sun's cap) and their totals
        bands += SKYVIEW_TABLE_BYTES
    else:
        bands += DIRECT_MARCH_BYTES
    cube = w * h * (n_wl if image_channels is None else int(image_channels)) * float(image_value_bytes)
    near_bands = BAND_COPIES * min(s.chunk, _march_piece(), near) * per_direction
    if table and image_channels is not None and int(image_channels) < n_wl:
        # reduced (to colour) through the table: the image, then the larger of one band's lookup and
        # the writers' own images (image_io.save_outputs: the EXR's float32 pixels, the float64
        # luminance, the 8-bit PNG and its rows), both per pixel of the image
        looked_up = min(pixels, pixels if band_pixels is None else max(int(band_pixels), 1))
        image = kept + cube + REDUCED_TABLE_PIXEL_BYTES * w * h + REDUCED_TABLE_BAND_BYTES * looked_up
    elif table:  # resampled from the sky-view table: no pixel is marched
        image = kept + TABLE_IMAGE_COPIES * cube
    else:
        image = kept + max(IMAGE_COPIES * cube, NEAR_SUN_CUBES * cube + near_bands)
    if image_channels is not None and not table:
        # reduced to colour, marched directly: the spectra of one band's pixels near the sun (3 parts,
        # then their sum; the rest is interpolated from the grid's total, already reduced)
        band = min(near, pixels if band_pixels is None else int(band_pixels)) * n_wl * 8.0
        image = kept + IMAGE_COPIES * cube + max(4 * band, 3 * band + near_bands)
    return MemoryEstimate(int(BASE_BYTES), int(tables), int(bands), int(image))


def limit_bytes(max_memory_gib=None) -> float:
    """The limit [bytes] of ``max_memory_gib`` (None: the registry's default), checked
    against the ``max_memory`` parameter of :mod:`skymodel.scene`."""
    gib = scene.check("max_memory", scene.default("max_memory") if max_memory_gib is None else max_memory_gib)
    return float(gib) * GIB


def check_render_memory(width: int, height: int, n_wavelengths: int, quality=None, max_memory_gib=None, *,
                        wavelengths_nm=None, image_channels: int | None = None,
                        band_pixels: int | None = None, sky_view_table: bool | None = None,
                        image_value_bytes: int = 8, sun_elevation_deg: float | None = None,
                        camera=None) -> MemoryEstimate:
    """The estimate (:func:`estimate_render_memory`), or :class:`SkymodelInputError`
    naming ``max_memory`` when it exceeds ``max_memory_gib`` [GiB] (None: the default);
    ``sun_elevation_deg`` [deg] and ``camera`` as there (None: the larger estimates)."""
    limit = limit_bytes(max_memory_gib)
    est = estimate_render_memory(width, height, n_wavelengths, quality, wavelengths_nm=wavelengths_nm,
                                 image_channels=image_channels, band_pixels=band_pixels,
                                 sky_view_table=sky_view_table, image_value_bytes=image_value_bytes,
                                 sun_elevation_deg=sun_elevation_deg, camera=camera)
    if est.total > limit:
        gib = limit / GIB
        raise SkymodelInputError(
            "max_memory", float(f"{gib:.6g}"),
            f"at least {est.gib:.2f} GiB for {int(width)}x{int(height)} px x {int(n_wavelengths)} wavelengths "
            f"at this quality: the estimate is {est.text()}; give a smaller image, a coarser wavelength step or "
            f"a lower quality, or raise the limit ({scene.parameter('max_memory').flag})")
    return est
