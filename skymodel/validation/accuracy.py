"""What accuracy costs in time: error of the sky renderer against a converged reference,
knob by knob, and of the quality presets (``skymodel bench accuracy``).

Scenes (:data:`SCENES`): the default atmosphere (location ``rural``, month 6 = June,
its default aerosol, ozone and grass albedo), sun azimuth 180 degrees, sun elevation 60
degrees ("noon"), 5 degrees ("sunset5") and -4 degrees ("twilight"); observer on the
ground. Camera: equirectangular, full sphere, sun in the middle of the image.

Reference: the ``reference`` quality preset at 81 wavelengths (380-780 nm every 5 nm) on
the smooth profile, rendered once per scene and cached under :func:`cache_dir`.

Each knob is varied on its own, the other knobs staying at the ``final`` preset:

* ``wavelengths``: 81, 41, 21, 11 evenly spaced samples (5, 10, 20, 40 nm) and ``rgb3``,
  a 3-wavelength RGB shortcut (440, 550, 680 nm, as in precomputed-atmosphere renderers):
  each channel's radiance divided by the top-of-atmosphere solar irradiance at its
  wavelength is taken as the sky's "reflectance" of the sun in that channel and
  multiplied by the Rec.709 value of the full solar spectrum in the same channel,
  ``RGB_c = L(lambda_c) / E0(lambda_c) * RGB(E0)_c``;
* ``orders``: highest scattering order 1..8, or ``tolerance`` (until an order adds less
  than the preset's ``order_tolerance``);
* ``layers``: the medium as the N volume shells the add-on's Volumetric mode builds
  (:func:`skymodel.optics.shells.volume_shells`: edges at equal shares of the column of
  extinction^0.3; measured with equal optical-depth shells until 2026-11-29) or ``smooth``;
* ``angular_grid``: every angular resolution of the marcher (the direction grid
  ``grid_zenith``/``grid_zenith_ground``/``grid_azimuth`` and the multiple-scattering
  tables ``table_mu``/``table_phi``/``table_mus``) scaled together by the value;
* ``phase``: the aerosol phase tables as computed by Mie theory (``mie``), or replaced by
  their Henyey-Greenstein (``hg``) or double Henyey-Greenstein (``dhg``) fits
  (:func:`with_fitted_phase`);
* ``mc_samples``: the Monte Carlo tracer with N paths per direction and wavelength on a
  handful of directions (:data:`MC_DIRECTIONS`) against the reference marcher there.

Errors, over the sky pixels (above the horizon) with the pixels the solar disc touches
left out, each pixel weighted by its solid angle:

* spectral radiance: the relative error ``|L - L_ref| / L_ref`` at every wavelength the
  variant has in common with the reference; mean, RMS and maximum over pixels and those
  wavelengths;
* colour: both images to scene-linear Rec.709 (CIE 1931 2-degree observer), tone-mapped
  with :func:`skymodel.render.image_io.tonemap` at the *reference's* exposure, sRGB to
  CIELAB (D65), CIEDE2000 per pixel (``colour.delta_E(..., method="CIE 2000")``); mean
  and 95th percentile; the same per view-elevation band (``bands``);
* lighting (``lighting``, every knob row but ``mc_samples``, and the presets): the
  irradiance on a horizontal surface under the whole upper hemisphere and the sun, its
  relative illuminance error and the CIEDE2000 of its colour against the reference's
  (:mod:`skymodel.validation.lighting`, as the planner's effect table measures it).

Times are wall-clock seconds of building the marcher and evaluating every pixel (median
of repeats when a render takes under :data:`REPEAT_BELOW_S`), with the 1-minute load
average of the (shared) machine recorded next to each. The baseline configuration
(81 wavelengths, orders to tolerance, smooth medium, angular scale 1, Mie phase) appears
under every knob; it is rendered once per scene and its measurement repeated in each row. Presets are rendered at 512x256
in a fresh subprocess, which also reports its peak resident memory (:func:`peak_memory_mb`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace

import numpy as np

from skymodel.errors import SkymodelInputError, check_choice
from skymodel.optics.shells import volume_shells
from skymodel.validation.lighting import horizontal_irradiance, lighting_errors

#: Scenes: name -> sun elevation in degrees (sun azimuth 180, observer on the ground).
SCENES = {"noon": 60.0, "sunset5": 5.0, "twilight": -4.0}
LOCATION = "rural"
MONTH = 6
SUN_AZIMUTH_DEG = 180.0
#: Knob names, as in skymodel/data/presets/accuracy/measured.json.
KNOBS = ("wavelengths", "orders", "layers", "angular_grid", "phase", "geometry", "mc_samples", "preset")
#: The RGB shortcut's wavelengths (nm): red, green, blue.
RGB3_WAVELENGTHS_NM = (680.0, 550.0, 440.0)
#: Monte Carlo check directions: (view zenith, azimuth from the sun), degrees.
MC_DIRECTIONS = ((0.0, 0.0), (30.0, 180.0), (60.0, 90.0), (75.0, 0.0), (85.0, 90.0), (85.0, 180.0))
#: Renders faster than this are repeated and the median taken.
REPEAT_BELOW_S = 3.0
REPEATS = 3


def _settings_dict(s) -> dict:
    return dataclasses.asdict(s)


def _settings_from_dict(d):
    from skymodel.render.marcher import MarchSettings

    return MarchSettings(**d)


def scale_angular(settings, factor: float):
    """``settings`` with every angular resolution (direction grid and multiple-scattering
    tables) scaled by ``factor`` (the azimuth grid keeps an odd node count; the zenith nodes
    crowded at the horizon, ``table_mu_horizon_nodes``, scale with their hemisphere's count and
    stay fewer than it; the solver's azimuths stay even where some orders run on every other
    one)."""
    f = float(factor)
    if not f > 0:
        raise SkymodelInputError("angular_grid", factor, "a positive scale factor")

    def n(v, lo):
        return max(lo, int(round(v * f)))

    half = n(settings.table_mu / 2, 3)
    # the zenith nodes within table_mu_horizon_deg of the horizon keep their share of each half
    horizon = settings.table_mu_horizon_nodes and min(half - 1, n(settings.table_mu_horizon_nodes, 1))
    phi = n(settings.table_phi, 3)
    if settings.halves_azimuths and phi % 2:
        phi += 1
    return replace(settings, grid_zenith=n(settings.grid_zenith, 8), grid_zenith_ground=n(settings.grid_zenith_ground, 4),
                   grid_azimuth=2 * n((settings.grid_azimuth - 1) / 2, 3) + 1, table_mu=2 * half,
                   table_mu_horizon_nodes=horizon, table_phi=phi, table_mus=n(settings.table_mus, 6))


@dataclass(frozen=True)
class BenchConfig:
    """Sizes and knob values of one benchmark run (:data:`FULL` or :data:`QUICK`)."""

    name: str
    width: int  # knob sweeps: equirectangular width x height
    height: int
    preset_width: int  # presets: 512 x 256 in the full run
    preset_height: int
    scenes: tuple
    reference: object  # MarchSettings of the reference
    baseline: object  # MarchSettings the knobs vary from
    presets: dict  # name -> MarchSettings
    wavelengths: tuple = (81, 41, 21, 11, "rgb3")
    orders: tuple = (1, 2, 3, 4, 5, 6, 7, 8, "tolerance")
    layers: tuple = (4, 8, 16, 32, 64, "smooth")
    angular_grid: tuple = (0.25, 0.5, 1.0, 1.5)
    phase: tuple = ("mie", "hg", "dhg")
    #: how much of the sphere's geometry and of the forward peak the multiple scattering
    #: keeps: "columnsN" = transports of orders 1..N with each point's own sun angle
    #: (0: independent columns throughout; 20, the baseline's max_orders: every order, as
    #: the Monte Carlo comparison's marcher with the sun below the horizon), "no-aureole"
    #: = the baseline without the peak aureole (skymodel.render.aureole)
    geometry: tuple = ("columns0", "columns1", "columns2", "columns3", "columns20", "no-aureole")
    mc_samples: tuple = (64, 256, 1024, 4096)
    mc_wavelength_step_nm: float = 20.0
    repeat: bool = True

    def knob_values(self, knob):
        return getattr(self, knob)


def full_config() -> BenchConfig:
    from skymodel.render.quality import QUALITY

    return BenchConfig("full", 128, 64, 512, 256, tuple(SCENES), QUALITY["reference"], QUALITY["final"], dict(QUALITY))


def quick_config() -> BenchConfig:
    """A small run for tests: one scene, a 32x16 camera, cheap marcher settings."""
    from skymodel.render.marcher import MarchSettings

    ref = MarchSettings(view_steps=48, order_tolerance=1e-3, ms_wavelength_step_nm=40.0, table_altitudes=12,
                        table_mu=12, table_phi=6, table_mus=12, table_steps=24, sun_table_altitudes=48,
                        sun_table_x=96, sun_table_steps=64, grid_zenith=24, grid_zenith_ground=8, grid_azimuth=17)
    base = scale_angular(replace(ref, view_steps=32, table_steps=16), 0.75)
    presets = {"preview": scale_angular(base, 0.75), "final": base, "reference": ref}
    return BenchConfig("quick", 32, 16, 48, 24, ("noon",), ref, base, presets, wavelengths=(81, 41, 11, "rgb3"),
                       orders=(1, 2, 4, "tolerance"), layers=(4, "smooth"), angular_grid=(0.5, 1.0),
                       phase=("mie", "hg", "dhg"), geometry=("columns0", "no-aureole"), mc_samples=(8, 32), mc_wavelength_step_nm=80.0, repeat=False)


# ----------------------------------------------------------------------------- inputs


def atmosphere():
    from skymodel.optics.atmosphere import Atmosphere

    return Atmosphere(location=LOCATION, month=MONTH)


def base_profile(wavelengths_nm=None):
    return atmosphere().optical_profile(wavelengths_nm)


def phase_fits(profile) -> list:
    """The HG / double-HG fit (:func:`skymodel.optics.phase_fit.fit_phase`) of every aerosol
    regime's phase table (None for a regime whose table is all zero)."""
    from skymodel.optics.phase_fit import fit_phase

    ang = profile.aerosol_phase_angles_deg
    return [fit_phase(ang, tab) if np.any(tab > 0) else None for tab in profile.aerosol_phase]


def with_fitted_phase(profile, kind: str, fits=None):
    """``profile`` with every aerosol regime's phase table replaced by its
    Henyey-Greenstein (``"hg"``) or double Henyey-Greenstein (``"dhg"``) fit, evaluated
    on the same angle grid; ``"mie"`` returns the profile unchanged. ``fits``: the
    result of :func:`phase_fits` for ``profile`` if already computed."""
    kind = check_choice("phase", kind, ("mie", "hg", "dhg"))
    if kind == "mie":
        return profile
    ang = profile.aerosol_phase_angles_deg
    fits = phase_fits(profile) if fits is None else fits
    tables = [tab if fit is None else (fit.hg_table(ang) if kind == "hg" else fit.dhg_table(ang))
              for tab, fit in zip(profile.aerosol_phase, fits)]
    return replace(profile, aerosol_phase=np.stack(tables))


def camera(width, height):
    from skymodel.render.cameras import make_camera

    return make_camera("equirectangular", width, height)


def sky_mask(cam, sun_elevation_deg):
    """Pixels above the horizon, minus those within the solar disc plus half a pixel
    diagonal of the sun's centre."""
    from skymodel.render.rays import sun_direction
    from skymodel.render.sun_transmittance import SUN_ANGULAR_RADIUS_RAD

    dirs, valid = cam.directions()
    sun = sun_direction(sun_elevation_deg, SUN_AZIMUTH_DEG)
    pix = np.sqrt(2.0) * 0.5 * np.sqrt(np.max(cam.pixel_solid_angles()))
    ang = np.arccos(np.clip(dirs @ sun, -1.0, 1.0))
    return valid & (dirs[..., 2] > 0.0) & (ang > SUN_ANGULAR_RADIUS_RAD + pix)


def mc_directions(sun_elevation_deg=None):
    """Unit vectors (N, 3) of :data:`MC_DIRECTIONS` (azimuths relative to the sun's)."""
    from skymodel.render.rays import direction_from_angles

    zen = np.array([z for z, _ in MC_DIRECTIONS])
    rel = np.array([a for _, a in MC_DIRECTIONS])
    return direction_from_angles(zen, (SUN_AZIMUTH_DEG + rel) % 360.0)


# ----------------------------------------------------------------------------- colour and errors


def rgb_of(radiance, wavelengths_nm):
    """Scene-linear Rec.709 of spectra on the last axis; a 3-sample spectrum on
    :data:`RGB3_WAVELENGTHS_NM` goes through the RGB shortcut (see the module doc)."""
    from skymodel.colorimetry import spectral_to_rgb

    wl = np.asarray(wavelengths_nm, float)
    if wl.size == 3 and np.allclose(np.sort(wl), np.sort(RGB3_WAVELENGTHS_NM)):
        return rgb3_to_rgb(radiance, wl)
    return spectral_to_rgb(radiance, wl)


def rgb3_to_rgb(radiance, wavelengths_nm):
    """The RGB shortcut: R, G, B = L(lambda_c) / E0(lambda_c) * RGB(E0)_c with E0 the
    top-of-atmosphere solar spectrum (on the 5 nm grid for RGB(E0))."""
    from skymodel.colorimetry import spectral_to_rgb
    from skymodel.wavelengths import default_wavelengths

    full = base_profile(default_wavelengths())
    rgb_sun = spectral_to_rgb(full.solar_irradiance, full.wavelengths_nm)
    wl = np.asarray(wavelengths_nm, float)
    e0 = base_profile(wl).solar_irradiance
    out = np.empty(np.shape(radiance)[:-1] + (3,))
    for c, lam in enumerate(RGB3_WAVELENGTHS_NM):
        j = int(np.argmin(np.abs(wl - lam)))
        out[..., c] = np.asarray(radiance)[..., j] / e0[j] * rgb_sun[c]
    return out


def xyz_of(radiance, wavelengths_nm):
    """CIE XYZ of spectra on the last axis, through :func:`rgb_of` (so a 3-sample spectrum
    goes through the RGB shortcut as its colours do; for a spectral grid the same as
    :func:`skymodel.colorimetry.spectral_to_xyz`)."""
    from skymodel.colorimetry import xyz_to_rgb_matrix

    return rgb_of(radiance, wavelengths_nm) @ np.linalg.inv(xyz_to_rgb_matrix()).T


def lighting_xyz(radiance, wavelengths_nm, directions, omega, sun_irradiance, sun_elevation_deg):
    """XYZ (3,) of the irradiance on a horizontal surface under the sky ``radiance``
    (..., n_wl) over ``directions`` (..., 3) with solid angles ``omega`` (...) and the sun
    (:func:`skymodel.validation.lighting.horizontal_irradiance`)."""
    return xyz_of(horizontal_irradiance(radiance, directions, omega, sun_irradiance, sun_elevation_deg),
                  wavelengths_nm)


def _weighted_quantile(values, weights, q):
    order = np.argsort(values)
    v = values[order]
    cw = np.cumsum(weights[order])
    return float(np.interp(q * cw[-1], cw, v)) if v.size else float("nan")


def band_matrix(wl_variant, wl_reference) -> np.ndarray:
    """Matrix M (n_variant, n_reference) that turns a reference spectrum into what each
    sample of a coarser grid stands for. A sample on a grid is the mean over a band
    centred on it as wide as the local grid spacing (this is how the solar spectrum is
    put on a grid, :func:`skymodel.sun.default_bandwidths`), so each variant sample is
    compared with the reference's samples averaged with weights equal to the overlap of
    their bands with its band (the trapezoid rule for a coarser even grid; the identity
    for the same grid). Bands are clipped to the reference's range."""
    from skymodel.sun import default_bandwidths

    wv = np.asarray(wl_variant, float)
    wr = np.asarray(wl_reference, float)
    bv = default_bandwidths(wv) if wv.size > 1 else np.array([float(np.median(np.diff(wr)))])
    br = default_bandwidths(wr)
    lo_r, hi_r = wr - br / 2, wr + br / 2
    lo_v = np.maximum(wv - bv / 2, lo_r.min())
    hi_v = np.minimum(wv + bv / 2, hi_r.max())
    ov = np.clip(np.minimum(hi_v[:, None], hi_r[None, :]) - np.maximum(lo_v[:, None], lo_r[None, :]), 0.0, None)
    tot = ov.sum(axis=1, keepdims=True)
    if np.any(tot <= 0):
        raise SkymodelInputError("wavelengths", wv.tolist(), "wavelengths inside the reference's range")
    return ov / tot


def _lab(rgb_linear, valid, average_luminance):
    import colour

    from skymodel.render.image_io import tonemap

    enc = tonemap(rgb_linear, valid=valid, average_luminance=average_luminance, return_float=True)
    return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(enc))


def errors(radiance, wavelengths_nm, ref_radiance, ref_wavelengths_nm, weights, ref_average_luminance=None,
           elevation_deg=None) -> dict:
    """Error metrics of ``radiance`` (..., n_wl) against ``ref_radiance`` (..., n_ref)
    over the points where ``weights`` (...,) > 0 (weights: solid angles).

    Returns radiance_rel_mean / _rms / _max (fractions, over every wavelength of the
    variant, the reference averaged over each variant sample's band by
    :func:`band_matrix`) and
    de2000_mean / _p95 (CIEDE2000 of the tone-mapped colours at the reference's exposure).
    Given the points' view elevations (degrees, shaped like ``weights``), also ``bands``:
    ``{band: {de2000_mean, radiance_rel_mean, radiance_rel_rms}}`` over the points of each view-elevation
    band of :data:`skymodel.geometry.VIEW_BANDS_DEG` that holds any (the same tone
    mapping and exposure as the whole sky's)."""
    import colour

    from skymodel.render.image_io import auto_exposure_luminance

    w = np.asarray(weights, float)
    sel = w > 0
    if not np.any(sel):
        raise SkymodelInputError("weights", "no positive weight", "at least one point to compare")
    L = np.asarray(radiance, float)
    R = np.asarray(ref_radiance, float)
    band = band_matrix(wavelengths_nm, ref_wavelengths_nm)
    out = {}
    a = L[sel]
    b = R[sel] @ band.T
    floor = 1e-12 * max(float(np.max(np.abs(b))), 1e-300)
    rel = np.abs(a - b) / np.maximum(np.abs(b), floor)
    ws = w[sel]
    out["radiance_rel_mean"] = float((ws * rel.mean(axis=1)).sum() / ws.sum())
    out["radiance_rel_rms"] = float(np.sqrt((ws * (rel**2).mean(axis=1)).sum() / ws.sum()))
    out["radiance_rel_max"] = float(rel.max())
    out["n_wavelengths_compared"] = int(a.shape[1])
    rgb_ref = rgb_of(R, ref_wavelengths_nm)
    rgb = rgb_of(L, wavelengths_nm)
    if ref_average_luminance is None:
        ref_average_luminance = auto_exposure_luminance(rgb_ref, sel)
    de = np.asarray(colour.delta_E(_lab(rgb, sel, ref_average_luminance), _lab(rgb_ref, sel, ref_average_luminance),
                                   method="CIE 2000"))[sel]
    out["de2000_mean"] = float((de * w[sel]).sum() / w[sel].sum())
    out["de2000_p95"] = _weighted_quantile(de, w[sel], 0.95)
    if elevation_deg is not None:
        from skymodel.geometry import view_band_masks

        rel_mean, rel_ms = rel.mean(axis=1), (rel**2).mean(axis=1)
        out["bands"] = {}
        for name, m in view_band_masks(np.broadcast_to(elevation_deg, w.shape)[sel]).items():
            if np.any(m):
                wm = ws[m] / ws[m].sum()
                out["bands"][name] = {"de2000_mean": float((de[m] * wm).sum()),
                                      "radiance_rel_mean": float((rel_mean[m] * wm).sum()),
                                      "radiance_rel_rms": float(np.sqrt((rel_ms[m] * wm).sum()))}
    return out


# ----------------------------------------------------------------------------- rendering


def _wavelengths_for(value):
    from skymodel.wavelengths import default_wavelengths

    if value == "rgb3":
        return np.array(sorted(RGB3_WAVELENGTHS_NM))
    n = int(value)
    return default_wavelengths(400.0 / (n - 1))


def render_directions(profile, settings, sun_elevation_deg, directions):
    """(radiance (N, n_wl) without the solar disc, seconds, marcher info): build the
    marcher and evaluate ``directions``; the time covers both. The info holds
    ``orders_used``, ``cpu_s`` and ``sun_irradiance`` (n_wl,; the direct beam at the
    observer, W m^-2 nm^-1)."""
    from skymodel.render.marcher import SkyMarcher

    t0, c0 = time.perf_counter(), time.process_time()
    m = SkyMarcher(profile, sun_elevation_deg, SUN_AZIMUTH_DEG, 0.0, settings)
    res = m.radiance(directions)
    dt = time.perf_counter() - t0
    return res.radiance, dt, {"orders_used": int(m.field.orders), "cpu_s": time.process_time() - c0,
                              "sun_irradiance": np.asarray(res.sun_irradiance, float)}


def _timed(fn, repeat: bool):
    """Run ``fn`` (returning (result, seconds, info with cpu_s)) once, or
    :data:`REPEATS` times when it is fast; (first output, median seconds, count), the
    first output's ``cpu_s`` replaced by the median CPU time."""
    out = fn()
    times, cpus = [out[1]], [out[2]["cpu_s"]]
    if repeat and times[0] < REPEAT_BELOW_S:
        for _ in range(REPEATS - 1):
            o = fn()
            times.append(o[1])
            cpus.append(o[2]["cpu_s"])
    out[2]["cpu_s"] = statistics.median(cpus)
    return out, statistics.median(times), len(times)


# ----------------------------------------------------------------------------- cache and subprocess jobs


def cache_dir() -> str:
    """Where references are cached: ``$SKYMODEL_CACHE/accuracy`` or ``.cache/accuracy``
    under the current directory (git-ignored)."""
    root = os.environ.get("SKYMODEL_CACHE") or os.path.join(os.getcwd(), ".cache")
    return os.path.join(root, "accuracy")


def _key(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def code_digest() -> str:
    """Hash of the package's Python sources (every module of ``skymodel``, the renderer's
    included): part of every cache key, so that a change to the renderer renders the
    references and presets again instead of reusing stale ones (it hashed
    ``skymodel/validation`` alone before, so a renderer change kept the cached renders)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    h = hashlib.sha256()
    for folder, dirs, files in sorted(os.walk(root)):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                h.update(os.path.relpath(os.path.join(folder, name), root).encode())
                with open(os.path.join(folder, name), "rb") as f:
                    h.update(f.read())
    return h.hexdigest()[:16]


def peak_memory_mb() -> float:
    """Peak resident memory of this process in MiB: ``VmHWM`` of /proc/self/status
    (Linux; it belongs to the current program image only, whereas ``ru_maxrss`` keeps
    the high-water mark of the parent that forked this process), else ``ru_maxrss``."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def render_job(job: dict) -> dict:
    """Render one scene with one preset in *this* process (run it in a fresh subprocess
    for a clean peak-memory figure): time the marcher build, the pixels of the first
    camera and the solar disc (what :func:`skymodel.render.sky.render_sky` does); then,
    untimed, radiance for the other cameras and the Monte Carlo directions. Sky radiance
    without the disc and the direct sun's irradiance (``sun_irradiance``) are saved to
    ``job["out"]`` (npz)."""
    from skymodel import sun as sun_module
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.sky import add_sun_disc
    from skymodel.wavelengths import default_wavelengths

    settings = _settings_from_dict(job["settings"])
    elev = float(job["sun_elevation_deg"])
    profile = base_profile(default_wavelengths())
    cams = [camera(w, h) for w, h in job["cameras"]]
    dirs0, valid0 = cams[0].directions()
    t0, c0 = time.perf_counter(), time.process_time()
    m = SkyMarcher(profile, elev, SUN_AZIMUTH_DEG, 0.0, settings)
    res = m.radiance(dirs0.reshape(-1, 3))
    rad = res.radiance.reshape(dirs0.shape[:-1] + (-1,))
    img = rad.copy()
    add_sun_disc(img, dirs0, valid0, cams[0].pixel_solid_angles(), m.sun, res.sun_irradiance, profile.wavelengths_nm,
                 limb_darkening=sun_module.limb_darkening)
    elapsed = time.perf_counter() - t0
    cpu = time.process_time() - c0
    arrays = {"cam0": rad}
    for k, cam in enumerate(cams[1:], start=1):
        d, _ = cam.directions()
        arrays[f"cam{k}"] = m.radiance(d.reshape(-1, 3)).radiance.reshape(d.shape[:-1] + (-1,))
    if job.get("mc"):
        arrays["mc"] = m.radiance(mc_directions()).radiance
    arrays["wavelengths_nm"] = profile.wavelengths_nm
    arrays["sun_irradiance"] = np.asarray(res.sun_irradiance, float)
    np.savez(job["out"], **arrays)
    rss_mb = peak_memory_mb()
    return {"time_s": elapsed, "cpu_s": cpu, "peak_memory_mb": rss_mb, "orders_used": int(m.field.orders),
            "load_avg_1m": os.getloadavg()[0]}


def run_job_subprocess(job: dict) -> dict:
    cmd = [sys.executable, "-m", "skymodel.validation.accuracy", json.dumps(job)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"render job failed: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _wait_for_other(npz, meta_path, log, poll_s: float = 5.0) -> bool:
    """Take the lock ``npz + ".lock"`` (False: this process renders), or, when another
    run holds it (benchmark runs of different scenes in parallel), wait for that run's
    result and return True (a stale lock older than 2 hours is taken over)."""
    lock = npz + ".lock"
    try:
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return False
    except FileExistsError:
        pass
    log(f"  waiting for another run to finish {os.path.basename(npz)} ...")
    while not (os.path.exists(npz) and os.path.exists(meta_path)):
        if not os.path.exists(lock) or time.time() - os.path.getmtime(lock) > 7200:
            with open(lock, "w"):
                pass
            return False
        time.sleep(poll_s)
    return True


def preset_run(cfg: BenchConfig, scene: str, preset: str, with_sweep_camera: bool, log=print):
    """(metadata, arrays) of ``preset`` on ``scene`` at the preset camera size; the
    reference (``with_sweep_camera``) also gets the sweep camera and the MC directions.
    Cached on disk by settings, scene and sizes."""
    settings = cfg.presets[preset] if preset != "__reference__" else cfg.reference
    cams = [(cfg.preset_width, cfg.preset_height)] + ([(cfg.width, cfg.height)] if with_sweep_camera else [])
    spec = {"settings": _settings_dict(settings), "sun_elevation_deg": SCENES[scene], "cameras": cams,
            "mc": bool(with_sweep_camera), "location": LOCATION, "month": MONTH,
            "version": 3 if preset == "__reference__" else 4, "code": code_digest()}
    key = _key(spec)
    d = cache_dir()
    os.makedirs(d, exist_ok=True)
    npz = os.path.join(d, f"{scene}-{key}.npz")
    meta_path = os.path.join(d, f"{scene}-{key}.json")
    if os.path.exists(npz) and os.path.exists(meta_path):
        with open(meta_path) as f:
            meta = json.load(f)
        meta["cached"] = True
    elif _wait_for_other(npz, meta_path, log):
        with open(meta_path) as f:
            meta = json.load(f)
        meta["cached"] = True
    else:
        log(f"  rendering {preset} for {scene} at {cams[0][0]}x{cams[0][1]} in a subprocess ...")
        fd, tmp = tempfile.mkstemp(suffix=".npz", dir=d)
        os.close(fd)
        try:
            meta = run_job_subprocess(dict(spec, out=tmp))
            os.replace(tmp, npz)
            with open(meta_path, "w") as f:
                json.dump(meta, f)
        finally:
            for path in (tmp, npz + ".lock"):
                if os.path.exists(path):
                    os.remove(path)
        meta["cached"] = False
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    return meta, arrays


# ----------------------------------------------------------------------------- the benchmark


def _variant(cfg: BenchConfig, knob, value):
    """(profile, settings, medium key) of one knob value; the key names the medium so
    that identical configurations (the baseline appears under every knob) are rendered
    once per scene."""
    from skymodel.wavelengths import default_wavelengths

    s = cfg.baseline
    wl81 = default_wavelengths()
    if knob == "wavelengths":
        wl = _wavelengths_for(value)
        return base_profile(wl), s, f"wl{wl.size}" + ("rgb3" if value == "rgb3" else "")
    if knob == "orders":
        return base_profile(wl81), (replace(s, orders=None) if value == "tolerance" else replace(s, orders=int(value))), "wl81"
    if knob == "layers":
        p = base_profile(wl81)
        return (p, s, "wl81") if value == "smooth" else (volume_shells(p, int(value)), s, f"wl81-shells{int(value)}")
    if knob == "angular_grid":
        return base_profile(wl81), scale_angular(s, float(value)), "wl81"
    if knob == "phase":
        return _fitted(str(value)), s, "wl81" + ("" if value == "mie" else f"-{value}")
    if knob == "geometry":
        value = check_choice("geometry", value, cfg.geometry)
        if value == "no-aureole":
            return base_profile(wl81), replace(s, peak_aureole=False), "wl81"
        return base_profile(wl81), replace(s, spherical_orders=int(value[len("columns"):])), "wl81"
    raise SkymodelInputError("knob", knob, "one of: " + ", ".join(KNOBS))


_FITS = {}


def _fitted(kind):
    """The default profile (81 wavelengths) with its phase tables as ``kind``; the fits
    are computed once per process."""
    from skymodel.wavelengths import default_wavelengths

    prof = base_profile(default_wavelengths())
    if "fits" not in _FITS:
        _FITS["fits"] = phase_fits(prof)
    return with_fitted_phase(prof, kind, _FITS["fits"])


def _row(scene, knob, value, settings_dict, time_s, err, **extra):
    row = {"scene": scene, "knob": knob, "value": value, "settings": settings_dict, "time_s": float(time_s),
           "radiance_rel_rms": err["radiance_rel_rms"], "radiance_rel_max": err["radiance_rel_max"],
           "de2000_mean": err["de2000_mean"], "de2000_p95": err["de2000_p95"],
           "radiance_rel_mean": err["radiance_rel_mean"]}
    for k in ("bands", "lighting"):
        if k in err:
            row[k] = err[k]
    row.update(extra)
    return row


def run_benchmark(cfg: BenchConfig, knobs=None, scenes=None, log=print) -> dict:
    """Measure every knob and preset on every scene; returns the measured.json dict."""
    from skymodel.validation.montecarlo import trace_radiance
    from skymodel.wavelengths import default_wavelengths

    knobs = tuple(knobs or KNOBS)
    for k in knobs:
        check_choice("knob", k, KNOBS)
    scenes = tuple(scenes or cfg.scenes)
    for s in scenes:
        check_choice("scene", s, SCENES)
    t_all = time.perf_counter()
    cam = camera(cfg.width, cfg.height)
    cam_p = camera(cfg.preset_width, cfg.preset_height)
    dirs, _ = cam.directions()
    flat = dirs.reshape(-1, 3)
    rows = []
    presets = {p: {} for p in cfg.presets}
    wl81 = default_wavelengths()
    for scene in scenes:
        elev = SCENES[scene]
        log(f"scene {scene} (sun {elev:g} deg)")
        ref_meta, ref = preset_run(cfg, scene, "__reference__", True, log)
        ref_wl = ref["wavelengths_nm"]
        mask = sky_mask(cam, elev)
        omega = cam.pixel_solid_angles()
        weights = np.where(mask, omega, 0.0)
        elevation_deg = np.degrees(np.arcsin(np.clip(dirs[..., 2], -1.0, 1.0)))
        from skymodel.render.image_io import auto_exposure_luminance

        ref_img = ref["cam1"]
        ref_avg = auto_exposure_luminance(rgb_of(ref_img, ref_wl), mask)
        light_ref = lighting_xyz(ref_img, ref_wl, dirs, omega, ref["sun_irradiance"], elev)
        done = {}  # (medium, settings) -> measurement: the baseline is rendered once per scene
        for knob in knobs:
            if knob in ("preset", "mc_samples"):
                continue
            for value in cfg.knob_values(knob):
                prof, settings, medium_key = _variant(cfg, knob, value)
                key = (medium_key, settings)
                if key not in done:
                    (rad, _, info), t_med, n_rep = _timed(
                        lambda: render_directions(prof, settings, elev, flat), cfg.repeat)
                    rad = rad.reshape(dirs.shape[:-1] + (-1,))
                    sun = info.pop("sun_irradiance")
                    err = errors(rad, prof.wavelengths_nm, ref_img, ref_wl, weights, ref_avg, elevation_deg)
                    err["lighting"] = lighting_errors(
                        lighting_xyz(rad, prof.wavelengths_nm, dirs, omega, sun, elev), light_ref)
                    done[key] = (t_med, n_rep, info, err)
                t_med, n_rep, info, err = done[key]
                sd = dict(_settings_dict(settings), n_wavelengths=int(prof.n_wavelengths),
                          medium="smooth" if not hasattr(prof, "edges_m") else f"layered-{prof.n_layers}",
                          phase=value if knob == "phase" else "mie")
                rows.append(_row(scene, knob, value, sd, t_med, err, repeats=n_rep, width=cfg.width,
                                 height=cfg.height, load_avg_1m=os.getloadavg()[0], **info))
                log(f"  {knob:>12} = {str(value):>9}: {t_med:7.2f} s  rel mean {err['radiance_rel_mean']:.2e}  "
                    f"max {err['radiance_rel_max']:.2e}  dE00 {err['de2000_mean']:.3f} (p95 {err['de2000_p95']:.3f})")
        if "mc_samples" in knobs:
            wl_mc = default_wavelengths(cfg.mc_wavelength_step_nm)
            prof_mc = base_profile(wl_mc)
            mdirs = mc_directions()
            ref_mc = ref["mc"]
            band = band_matrix(wl_mc, ref_wl)
            ref_mc_band = ref_mc @ band.T  # the reference on the MC grid (band means)
            # exposure of the reference image, on the MC wavelength grid's colours
            avg_mc = auto_exposure_luminance(rgb_of(ref_img @ band.T, wl_mc), mask)
            for n in cfg.mc_samples:
                t0, c0 = time.perf_counter(), time.process_time()
                mc = trace_radiance(prof_mc, mdirs, elev, SUN_AZIMUTH_DEG, 0.0, n_paths=int(n), seed=1)
                dt = time.perf_counter() - t0
                cpu = time.process_time() - c0
                err = errors(mc.radiance, wl_mc, ref_mc_band, wl_mc, np.ones(len(mdirs)), avg_mc)
                stderr_rel = float(np.mean(mc.stderr / np.maximum(mc.radiance, 1e-300)))
                rows.append(_row(scene, "mc_samples", int(n), {"n_paths": int(n), "n_wavelengths": int(wl_mc.size),
                                                                "directions_deg": [list(d) for d in MC_DIRECTIONS],
                                                                "max_bounces": 64},
                                 dt, err, repeats=1, mc_stderr_rel_mean=stderr_rel, load_avg_1m=os.getloadavg()[0],
                                 cpu_s=cpu))
                log(f"  {'mc_samples':>12} = {n:>9}: {dt:7.2f} s  rel mean {err['radiance_rel_mean']:.2e}  "
                    f"(MC stderr {stderr_rel:.2e})  dE00 {err['de2000_mean']:.3f}")
        if "preset" in knobs:
            mask_p = sky_mask(cam_p, elev)
            dirs_p, omega_p = cam_p.directions()[0], cam_p.pixel_solid_angles()
            w_p = np.where(mask_p, omega_p, 0.0)
            ref_p = ref["cam0"]
            avg_p = auto_exposure_luminance(rgb_of(ref_p, ref_wl), mask_p)
            light_ref_p = lighting_xyz(ref_p, ref_wl, dirs_p, omega_p, ref["sun_irradiance"], elev)
            for name, settings in cfg.presets.items():
                if settings == cfg.reference:
                    meta, arr = ref_meta, {"cam0": ref_p, "wavelengths_nm": ref_wl, "sun_irradiance": ref["sun_irradiance"]}
                else:
                    meta, arr = preset_run(cfg, scene, name, False, log)
                err = errors(arr["cam0"], arr["wavelengths_nm"], ref_p, ref_wl, w_p, avg_p)
                err["lighting"] = lighting_errors(
                    lighting_xyz(arr["cam0"], arr["wavelengths_nm"], dirs_p, omega_p, arr["sun_irradiance"], elev),
                    light_ref_p)
                entry = {"time_s": meta["time_s"], "radiance_rel_mean": err["radiance_rel_mean"],
                         "radiance_rel_rms": err["radiance_rel_rms"], "radiance_rel_max": err["radiance_rel_max"],
                         "de2000_mean": err["de2000_mean"], "de2000_p95": err["de2000_p95"],
                         "lighting": err["lighting"], "peak_memory_mb": meta["peak_memory_mb"], "width": cfg.preset_width,
                         "height": cfg.preset_height, "orders_used": meta["orders_used"], "cpu_s": meta.get("cpu_s"),
                         "load_avg_1m": meta["load_avg_1m"]}
                presets[name][scene] = entry
                rows.append(_row(scene, "preset", name, dict(_settings_dict(settings), n_wavelengths=81), meta["time_s"],
                                 err, repeats=1, width=cfg.preset_width, height=cfg.preset_height,
                                 peak_memory_mb=meta["peak_memory_mb"], load_avg_1m=meta["load_avg_1m"],
                                 cpu_s=meta.get("cpu_s"), orders_used=meta["orders_used"]))
                log(f"  {'preset':>12} = {name:>9}: {meta['time_s']:7.2f} s  rel mean {err['radiance_rel_mean']:.2e}  "
                    f"dE00 {err['de2000_mean']:.3f}  peak {meta['peak_memory_mb']:.0f} MB")
    from datetime import datetime, timezone

    date = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    for r in rows:  # each row and preset says when it was measured (a merged table mixes runs)
        r["date"] = date
    for per in presets.values():
        for entry in per.values():
            entry["date"] = date
    return {
        "source": "measured on this project's renderer by `skymodel bench accuracy` (skymodel/validation/accuracy.py); "
                  "method and discussion in docs/accuracy.md",
        "machine": _machine(), "command": "", "date": date,
        "config": cfg.name, "total_s": time.perf_counter() - t_all, "load_avg_end": list(os.getloadavg()),
        "camera": {"kind": "equirectangular", "width": cfg.width, "height": cfg.height},
        "preset_camera": {"kind": "equirectangular", "width": cfg.preset_width, "height": cfg.preset_height},
        "atmosphere": dict(base_profile(wl81).metadata),
        "reference_settings": dict(_settings_dict(cfg.reference), n_wavelengths=81),
        "baseline_settings": _settings_dict(cfg.baseline),
        "scenes": {s: {"sun_elevation_deg": SCENES[s], "sun_azimuth_deg": SUN_AZIMUTH_DEG, "location": LOCATION,
                       "month": MONTH} for s in scenes},
        "rows": rows,
        "presets": {p: v for p, v in presets.items()} if "preset" in knobs else {},
        "units": {"time_s": "seconds wall clock", "radiance_rel_*": "fraction (0.01 = 1%)",
                  "de2000_*": "CIEDE2000", "peak_memory_mb": "MiB (VmHWM of the render subprocess)"},
    }


def _machine() -> str:
    import platform

    try:
        cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    except OSError:
        cpu = platform.processor() or "?"
    return f"{cpu}, {os.cpu_count()} cores; {platform.system()} {platform.release()}; Python {platform.python_version()}, numpy {np.__version__}"


def bench(quick: bool = False, out: str | None = None, json_path: str | None = None, knobs=None, scenes=None,
          command: str = "", log=print) -> dict:
    """Run the benchmark (:data:`FULL` sizes, or the small ``quick`` run) and write the
    measured table (``json_path``) and the markdown with its plots (``out``; the PNGs
    go to ``img/`` beside it). Returns the result dict."""
    from skymodel.validation import accuracy_report

    cfg = quick_config() if quick else full_config()
    result = run_benchmark(cfg, knobs=knobs, scenes=scenes, log=log)
    result["command"] = command or ("skymodel bench accuracy" + (" --quick" if quick else ""))
    if (knobs or scenes) and json_path and os.path.exists(json_path):
        result = merge_results(_load_json(json_path), result)
    if json_path:
        accuracy_report.write_json(result, json_path)
        log(f"wrote {json_path}")
    if out:
        accuracy_report.write_markdown(result, out)
        log(f"wrote {out}")
    return result


def _load_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def merge_results(old: dict, new: dict) -> dict:
    """``old`` with the rows and presets that ``new`` measured (a run restricted with
    --knobs/--scenes) replaced; other rows kept. Runs of different configurations
    (full/quick) are not merged: ``new`` is returned."""
    if old.get("config") != new.get("config") or old.get("camera") != new.get("camera"):
        return new
    measured = {(r["scene"], r["knob"]) for r in new["rows"]}
    out = dict(old)
    kept = [dict(r, date=r.get("date") or row_date(old, r["scene"], r["knob"])) for r in old["rows"]
            if (r["scene"], r["knob"]) not in measured]
    out["rows"] = kept + new["rows"]
    order = {k: i for i, k in enumerate(KNOBS)}
    scenes = list(SCENES)
    out["rows"].sort(key=lambda r: (scenes.index(r["scene"]), order[r["knob"]]))
    out["scenes"] = {s: v for s, v in sorted({**old["scenes"], **new["scenes"]}.items(), key=lambda kv: scenes.index(kv[0]))}
    presets = {name: {sc: dict(v, date=v.get("date") or row_date(old, sc, "preset")) for sc, v in per.items()}
               for name, per in old.get("presets", {}).items()}
    for name, per in new.get("presets", {}).items():
        presets.setdefault(name, {}).update(per)
    out["presets"] = presets
    for key in ("machine", "date", "load_avg_end", "reference_settings"):
        out[key] = new[key]
    # the rows kept were measured in the old table's atmosphere: it stays the table's, and a
    # part measured in another one says so in its partial_runs entry
    out["atmosphere"] = old.get("atmosphere", new["atmosphere"])
    if any(r["knob"] not in ("preset", "mc_samples") for r in new["rows"]):
        out["baseline_settings"] = new["baseline_settings"]
    out["total_s"] = old.get("total_s", 0.0) + new["total_s"]
    run = {"command": new["command"], "date": new["date"], "total_s": new["total_s"]}
    if new.get("atmosphere") != out["atmosphere"]:
        run["atmosphere"] = new["atmosphere"]
    out["partial_runs"] = list(old.get("partial_runs", [])) + [run]
    out["command"] = old["command"]
    return _prune_runs(out)


def _prune_runs(table: dict) -> dict:
    """``table`` with only the ``partial_runs`` whose rows or presets it still holds (a run
    whose every row a later one replaced is dropped, with its time) and, when every row and
    preset left was measured in one atmosphere other than the table's, that atmosphere as the
    table's (a table first measured in another model and since re-measured row by row)."""
    dates = [r.get("date") for r in table.get("rows", [])]
    dates += [v.get("date") for per in table.get("presets", {}).values() for v in per.values()]
    held = set(dates)
    runs = [run for run in table.get("partial_runs", []) if run.get("date") in held]
    if not runs:
        return table
    by_date = {run["date"]: run for run in runs}
    atmospheres = [by_date.get(d, {}).get("atmosphere") for d in dates]
    out = dict(table, total_s=sum(float(run.get("total_s", 0.0)) for run in runs))
    if atmospheres and atmospheres[0] is not None and all(a == atmospheres[0] for a in atmospheres):
        out["atmosphere"] = atmospheres[0]
        runs = [{k: v for k, v in run.items() if k != "atmosphere"} for run in runs]
    out["partial_runs"] = runs
    return out


def _run_covers(command: str, scene: str, knob: str) -> bool:
    """Whether a ``skymodel bench accuracy`` command line measured ``knob`` on ``scene``
    (no --knobs / --scenes: every one)."""
    words = command.split()

    def listed(flag, value):
        if flag not in words or words.index(flag) + 1 >= len(words):
            return True
        return value in words[words.index(flag) + 1].split(",")

    return listed("--knobs", knob) and listed("--scenes", scene)


def row_date(table: dict, scene: str, knob: str) -> str:
    """When ``table`` measured ``knob`` on ``scene``: the row's own ``date`` when it has
    one, else that of the last of its ``partial_runs`` whose command covered it, else the
    table's ``date`` (tables written before rows carried their date)."""
    for r in table.get("rows", []):
        if r.get("scene") == scene and r.get("knob") == knob and r.get("date"):
            return r["date"]
    for run in reversed(table.get("partial_runs", [])):
        if _run_covers(run.get("command", ""), scene, knob):
            return run.get("date", table.get("date", ""))
    return table.get("date", "")


def merge_parts(parts: list[dict]) -> dict:
    """One measured table from runs restricted with --scenes/--knobs (for example one
    process per scene, run in parallel): the first part is the base, each later one
    replaces the rows and presets it measured (:func:`merge_results`). Every part is
    listed under ``partial_runs`` with its command and time (a first part that was merged
    before keeps its list); the table's command is the plain ``skymodel bench accuracy``."""
    if not parts:
        raise ValueError("merge: give at least one part (a measured-table JSON)")
    first = parts[0]
    # a first part that is itself a merged table keeps its list of parts (merging it alone changes nothing)
    runs = first.get("partial_runs") or [{"command": first["command"], "date": first["date"], "total_s": first["total_s"]}]
    out = dict(first, command="skymodel bench accuracy", total_s=first["total_s"], partial_runs=list(runs))
    for part in parts[1:]:
        if part.get("config") != first.get("config") or part.get("camera") != first.get("camera"):
            raise ValueError(f"merge: part {part.get('command')!r} was measured with another configuration "
                             "than the first part (full and --quick runs do not mix)")
        out = merge_results(out, part)
    return out


def main(argv=None) -> int:  # the subprocess entry point of render_job
    argv = sys.argv[1:] if argv is None else argv
    out = render_job(json.loads(argv[0]))
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
