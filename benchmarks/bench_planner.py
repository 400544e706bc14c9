"""Benchmark: what each effect of the sky contributes, measured with the marcher, for the
effect planner (``skymodel/planner/``); and the proof that the planner's plans pay.

Two modes:

``python benchmarks/bench_planner.py [--write]``
    For a grid of sun elevations, render the sky with every effect on (the reference)
    and again with one effect switched off or simplified at a time, and record the
    colour difference (CIEDE2000 of the tone-mapped sky) and the luminance error, for the
    sky seen directly (by elevation band) and for the sky as lighting (illuminance on a
    horizontal surface and its colour), plus aerial perspective vs distance. ``--write``
    stores the table in ``skymodel/data/presets/planner/effects.json``.

``python benchmarks/bench_planner.py --proof [--write]`` (``--doc-only``: rewrite the doc from the JSON)
    For the three example scenes of issue 5 and a daylight study, plan with :func:`skymodel.planner.plan`,
    render the planned build and the everything-on build with the marcher, and report
    both times and the planned build's error against everything-on; ``--write`` stores
    the result in ``skymodel/data/presets/planner/proof.json`` and the tables in ``docs/planner.md``.

Conventions (the same in both modes)
------------------------------------
* Sky seen directly: an equirectangular camera (full sphere, sun disc excluded), errors
  weighted by pixel solid angle; bands by view elevation: ``ground`` (< 0 deg),
  ``horizon`` (0..10), ``low`` (10..30), ``high`` (30..90).
* Tone mapping: XYZ is divided by the luminance of a white horizontal Lambertian surface
  under the *reference* sky + sun (``E_h,Y / pi``, the add-on's exposure rule), then
  compressed with Reinhard's global operator on luminance (every channel scaled by
  ``1 / (1 + Y)``), then CIE Lab (D65 white) and CIEDE2000 (colour-science). Both images
  use the reference's exposure, so a change of brightness counts as an error.
* ``radiance_rel``: ``|Y - Y_ref| / Y_ref`` of the per-pixel luminance.
* Lighting: the spectral irradiance on a horizontal surface, ``sum(L cos(zenith) dOmega)``
  over the upper hemisphere plus the direct sun; ``illuminance_rel`` is the relative error
  of its luminance, ``de2000`` the colour difference of XYZ / Y_ref (white = reference).
* Aerial perspective: a grey Lambertian object (albedo 0.2) lit by the reference
  irradiance, seen along a horizontal path of length D from the ground:
  ``L = L_obj T(D) + L_path(D)`` with ``T`` from the profile's extinction along the
  curved path and ``L_path(D) = L_hor (1 - T(D)) / (1 - T_inf)`` (``L_hor`` the marched
  radiance 0.5 degrees above the horizon, exact when the source function is constant along the path, i.e. for
  paths short against the 8 km scale height's curvature length); the error is that of
  showing ``L_obj`` alone (no atmosphere in between), averaged over azimuths 0, 90 and
  180 degrees from the sun (``mean``) and the worst of them (``max``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys
import time
from dataclasses import replace

import numpy as np

from skymodel.geometry import VIEW_BANDS_DEG, view_band_masks
from skymodel.optics.shells import volume_shells
from skymodel.validation.lighting import horizontal_irradiance, lighting_errors, reinhard_de2000

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from common import command_line, git_revision, machine  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# the package's tables (skymodel/data/presets/planner since 52f0e5b; the planner reads them there)
EFFECTS_JSON = os.path.join(ROOT, "skymodel", "data", "presets", "planner", "effects.json")
PROOF_JSON = os.path.join(ROOT, "skymodel", "data", "presets", "planner", "proof.json")
DOC = os.path.join(ROOT, "docs", "planner.md")

ELEVATIONS_DEG = (-6, -4, -2, 0, 2, 5, 10, 20, 30, 45, 60, 90)
DISTANCES_M = (200, 500, 1_000, 2_000, 5_000, 10_000, 20_000, 30_000, 50_000, 100_000)
OBJECT_ALBEDO = 0.2
HORIZON_VIEW_DEG = 0.5
#: Timed runs of each build in the proof (the fastest is reported).
REPEATS = 3
LOCATION = "rural"
MONTH = 6


# --------------------------------------------------------------------------- metrics


def _weighted_stats(values, weights):
    v = np.asarray(values, float).ravel()
    w = np.asarray(weights, float).ravel()
    if v.size == 0 or w.sum() <= 0:
        return 0.0, 0.0
    mean = float((v * w).sum() / w.sum())
    order = np.argsort(v)
    cw = np.cumsum(w[order]) / w.sum()
    p95 = float(v[order][min(np.searchsorted(cw, 0.95), v.size - 1)])
    return mean, p95


class Reference:
    """What every comparison needs from the reference render."""

    def __init__(self, radiance, directions, omega, sun_irradiance, sun_elevation_deg, wavelengths_nm):
        from skymodel.colorimetry import cmf_weights

        self.w = cmf_weights(wavelengths_nm)
        self.dirs = directions
        self.omega = omega
        self.elev = np.degrees(np.arcsin(np.clip(directions[:, 2], -1, 1)))
        self.xyz = radiance @ self.w
        self.e_h = horizontal_irradiance(radiance, directions, omega, sun_irradiance, sun_elevation_deg)
        self.e_h_xyz = self.e_h @ self.w
        self.white_y = max(float(self.e_h_xyz[1]) / np.pi, 1e-30)

    def compare(self, radiance, sun_irradiance, sun_elevation_deg, wavelengths_nm=None) -> dict:
        """Errors of a render (its own wavelength grid allowed) against the reference."""
        from skymodel.colorimetry import cmf_weights

        w = self.w if wavelengths_nm is None else cmf_weights(wavelengths_nm)
        xyz = radiance @ w
        de = reinhard_de2000(xyz, self.xyz, self.white_y)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(xyz[:, 1] - self.xyz[:, 1]) / np.maximum(self.xyz[:, 1], 1e-30)
        out = {"sky": {}}
        for band, m in view_band_masks(self.elev).items():
            de_mean, de_p95 = _weighted_stats(de[m], self.omega[m])
            rel_mean, rel_p95 = _weighted_stats(rel[m], self.omega[m])
            out["sky"][band] = {"de2000_mean": round(de_mean, 4), "de2000_p95": round(de_p95, 4),
                                "radiance_rel_mean": round(rel_mean, 5), "radiance_rel_p95": round(rel_p95, 5)}
        e_h = horizontal_irradiance(radiance, self.dirs, self.omega, sun_irradiance, sun_elevation_deg)
        light = lighting_errors(e_h @ w, self.e_h_xyz)
        out["lighting"] = {"illuminance_rel": round(light["illuminance_rel"], 5), "de2000": round(light["de2000"], 4)}
        return out


# --------------------------------------------------------------------------- renders


def base_settings():
    """Preview tables and direction grid, scattering orders until they add < 1e-4."""
    from skymodel.render.sky import QUALITY

    return replace(QUALITY["preview"], order_tolerance=1e-4)


def sky_directions(width):
    from skymodel.render.cameras import make_camera

    cam = make_camera("equirectangular", width)
    d, _ = cam.directions()
    return d.reshape(-1, 3), cam.pixel_solid_angles().ravel()


def march(profile, sun_elevation_deg, settings, dirs):
    from skymodel.render.marcher import SkyMarcher

    t = time.perf_counter()
    m = SkyMarcher(profile, sun_elevation_deg, 180.0, 0.0, settings)
    r = m.radiance(dirs)
    return r.radiance, r.sun_irradiance, time.perf_counter() - t, int(m.field.orders)


def variants(profile, settings):
    """(name, profile, settings) of every simplification measured."""
    z = np.zeros_like
    out = [
        ("ozone_off", profile.with_(ozone_absorption=z(profile.ozone_absorption)), settings),
        ("aerosols_off", profile.with_(aerosol_scattering_by_regime=z(profile.aerosol_scattering_by_regime),
                                       aerosol_absorption=z(profile.aerosol_absorption)), settings),
        ("ground_albedo_0", profile.with_(ground_albedo=z(profile.ground_albedo)), settings),
        ("earth_shadow_off", profile, replace(settings, earth_shadow=False)),
    ]
    out += [(f"orders_{n}", profile, replace(settings, orders=n)) for n in (1, 2, 3, 4)]
    # the shells the add-on builds (their edges: skymodel.optics.shells)
    out += [(f"layers_{n}", volume_shells(profile, n), settings) for n in (4, 8, 16, 24)]
    return out


def aerial_perspective(profile, ref_radiance_fn, e_h, w, sun_elevation_deg):
    """Error of leaving out the air between the camera and an object, vs distance."""
    from skymodel.geometry import EARTH_RADIUS_M

    R = EARTH_RADIUS_M
    rel_az = np.radians([0.0, 90.0, 180.0])
    az = np.radians(180.0) + rel_az
    # the sky just above the horizon (0.5 degrees: a horizontal ray from the ground is the
    # sky/ground edge of the marcher's direction grid)
    e = np.radians(HORIZON_VIEW_DEG)
    dirs = np.stack([np.cos(e) * np.sin(az), np.cos(e) * np.cos(az), np.full_like(az, np.sin(e))], axis=1)
    l_hor = ref_radiance_fn(dirs)  # (3, n_wl)
    s = np.linspace(0.0, 400_000.0, 4001)
    h = np.sqrt(R * R + s * s) - R
    ext = profile.sample(h).extinction  # (n_s, n_wl)
    tau = np.concatenate([np.zeros((1, ext.shape[1])), np.cumsum(0.5 * (ext[1:] + ext[:-1]) * np.diff(s)[:, None], axis=0)])
    t_inf = np.exp(-tau[-1])
    l_obj = OBJECT_ALBEDO * e_h / np.pi
    white_y = max(float(e_h @ w[:, 1]) / np.pi, 1e-30)
    rows = []
    for dist in DISTANCES_M:
        t_d = np.exp(-np.array([np.interp(dist, s, tau[:, k]) for k in range(tau.shape[1])]))
        l_path = l_hor * ((1.0 - t_d) / np.maximum(1.0 - t_inf, 1e-12))[None, :]
        seen = l_obj[None, :] * t_d[None, :] + l_path
        de = reinhard_de2000(np.broadcast_to(l_obj @ w, (3, 3)), seen @ w, white_y)
        y_seen = seen @ w[:, 1]
        rel = np.abs(float(l_obj @ w[:, 1]) - y_seen) / np.maximum(y_seen, 1e-30)
        rows.append({"distance_m": dist, "de2000_mean": round(float(de.mean()), 4),
                     "de2000_max": round(float(de.max()), 4), "radiance_rel_mean": round(float(rel.mean()), 5),
                     "radiance_rel_max": round(float(rel.max()), 5),
                     "transmittance_550": round(float(np.interp(550.0, profile.wavelengths_nm, t_d)), 5)})
    return rows


def measure_effects(elevations, width, step_nm):
    from skymodel import Atmosphere
    from skymodel.render.marcher import SkyMarcher
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(step_nm)
    prof = Atmosphere(location=LOCATION, month=MONTH).optical_profile(wl)
    dirs, omega = sky_directions(width)
    settings = base_settings()
    table = []
    for el in elevations:
        t0 = time.perf_counter()
        marcher = SkyMarcher(prof, el, 180.0, 0.0, settings)
        res = marcher.radiance(dirs)
        t_ref = time.perf_counter() - t0
        ref = Reference(res.radiance, dirs, omega, res.sun_irradiance, el, wl)
        entry = {"sun_elevation_deg": el, "reference": {"time_s": round(t_ref, 3), "orders": int(marcher.field.orders)},
                 "effects": {}}
        for name, p, s in variants(prof, settings):
            rad, sun_irr, t, n = march(p, el, s, dirs)
            entry["effects"][name] = dict(ref.compare(rad, sun_irr, el), time_s=round(t, 3), orders=n)
        # coarser spectral grids: render on the coarse grid, interpolate back (what a
        # coarse render's colours are computed from)
        for coarse in (2 * step_nm, 4 * step_nm):
            wlc = default_wavelengths(coarse)
            pc = Atmosphere(location=LOCATION, month=MONTH).optical_profile(wlc)
            rad, sun_irr, t, n = march(pc, el, settings, dirs)
            rad_f = np.stack([np.interp(wl, wlc, r) for r in rad])
            sun_f = np.interp(wl, wlc, sun_irr)
            entry["effects"][f"wavelength_step_{coarse:g}"] = dict(ref.compare(rad_f, sun_f, el), time_s=round(t, 3),
                                                                   orders=n, n_wavelengths=int(wlc.size))
        entry["aerial_perspective"] = aerial_perspective(
            prof, lambda d: marcher.radiance(d).radiance, ref.e_h, ref.w, el)
        entry["load_average_1min"] = round(os.getloadavg()[0], 2)
        table.append(entry)
        print(f"sun {el:+5.1f} deg: reference {t_ref:.2f} s, {marcher.field.orders} orders; "
              + ", ".join(f"{k} {v['sky']['high']['de2000_mean']:.2f}/{v['lighting']['de2000']:.2f}"
                          for k, v in entry["effects"].items()), flush=True)
    return {
        "description": "Error caused by switching off or simplifying each effect of the sky, measured with the "
                       "marcher against the everything-on render (see benchmarks/bench_planner.py for the "
                       "conventions: tone mapping, bands, lighting, aerial perspective).",
        "source": "measured: skymodel ray marcher (skymodel/render/marcher.py), this repository",
        "machine": machine(),
        "git_revision": git_revision(),
        "command": command_line(),
        "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "atmosphere": {"location": LOCATION, "month": MONTH},
        "camera": {"camera": "equirectangular", "width": width, "height": width // 2},
        "wavelength_step_nm": step_nm,
        "settings": {k: v for k, v in vars(settings).items()},
        "bands_deg": VIEW_BANDS_DEG,
        "object_albedo": OBJECT_ALBEDO,
        "rows": table,
    }


# --------------------------------------------------------------------------- pixel costs


def measure_pixel_costs(widths_direct=(256, 512), widths_table=(1024, 2048, 4096), sun_elevation_deg=30.0,
                        quality="final", repeats=3):
    """What an environment's pixels add to its build (the planner's ``ENV_SECONDS_PER_PIXEL``,
    ``ENV_SECONDS_PER_PIXEL_TABLE``, ``ENV_TABLE_FIXED_S``): the multiple-scattering solve is
    done once and reused, then each width is timed (median of ``repeats``) as the accuracy
    table's preset render marches it (``SkyMarcher.radiance`` of every pixel, 81
    wavelengths) and as the add-on's build does (``render_sky_reduced`` to RGB: every pixel
    below ``TABLE_MIN_PIXELS``, the sky-view table above). Slopes and intercepts by least
    squares on the pixel count; the intercept of the direct march is the per-sun part every
    size pays."""
    from skymodel import Atmosphere
    from skymodel.render import sky as render_sky
    from skymodel.render.marcher import SkyMarcher, solve_sky
    from skymodel.render.quality import quality_settings
    from skymodel.render.skyview import rgb_reduction
    from skymodel.wavelengths import default_wavelengths

    settings = quality_settings(quality)
    prof = Atmosphere(location=LOCATION, month=MONTH).optical_profile(default_wavelengths(5.0))
    t0, c0 = time.perf_counter(), time.process_time()
    sol = solve_sky(prof, settings)
    t_solve, c_solve = time.perf_counter() - t0, time.process_time() - c0
    rows = []
    from skymodel.render.cameras import make_camera

    # warm-up, not timed: the first render of a process loads the core's tables
    render_sky.render_sky_reduced(prof, make_camera("equirectangular", 16), sun_elevation_deg,
                                  rgb_reduction(prof.wavelengths_nm), 3, quality=settings, solution=sol)

    def med(fn):
        """(median wall s, median CPU s): on a shared machine the CPU time is the better
        estimate of an idle machine's wall time (the renders are single-threaded numpy)."""
        ts, cs = [], []
        for _ in range(repeats):
            t, c = time.perf_counter(), time.process_time()
            fn()
            ts.append(time.perf_counter() - t)
            cs.append(time.process_time() - c)
        return float(np.median(ts)), float(np.median(cs))

    for w in tuple(widths_direct) + tuple(widths_table):
        cam_dirs = None
        if w in widths_direct:
            cam_dirs, _ = sky_directions(w)
            t_marcher, c_marcher = med(lambda: SkyMarcher(prof, sun_elevation_deg, 180.0, 0.0, settings, solution=sol)
                                       .radiance(cam_dirs))
        else:
            t_marcher = c_marcher = None
        cam = make_camera("equirectangular", w, n_wavelengths=3)  # as the environment build: 3 channels a pixel
        t_env, c_env = med(lambda: render_sky.render_sky_reduced(prof, cam, sun_elevation_deg, rgb_reduction(prof.wavelengths_nm),
                                                          3, quality=settings, solution=sol, dtype=np.float32))
        rows.append({"width": w, "pixels": w * (w // 2), "marcher_s": t_marcher, "environment_s": t_env,
                     "marcher_cpu_s": c_marcher, "environment_cpu_s": c_env,
                     "load_average_1min": round(os.getloadavg()[0], 2)})
        print(json.dumps(rows[-1]), flush=True)

    def fit(pairs):
        x = np.array([p for p, _ in pairs], float)
        y = np.array([t for _, t in pairs], float)
        slope, icpt = np.polyfit(x, y, 1)
        return float(slope), float(icpt)

    # fitted on the CPU times (see med)
    k_m, c_m = fit([(r["pixels"], r["marcher_cpu_s"]) for r in rows if r["marcher_cpu_s"] is not None])
    k_d, c_d = fit([(r["pixels"], r["environment_cpu_s"]) for r in rows if r["width"] in widths_direct])
    k_t, c_t = fit([(r["pixels"], r["environment_cpu_s"]) for r in rows if r["width"] in widths_table])
    out = {"quality": quality, "sun_elevation_deg": sun_elevation_deg, "solve_s": round(t_solve, 2),
           "solve_cpu_s": round(c_solve, 2), "rows": rows,
           "marcher_s_per_pixel": k_m, "marcher_intercept_s": c_m, "environment_direct_s_per_pixel": k_d,
           "environment_direct_intercept_s": c_d, "environment_table_s_per_pixel": k_t,
           "environment_table_intercept_s": c_t, "table_fixed_s": c_t - c_d,
           "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"), "machine": machine(),
           "git_revision": git_revision()}
    print(json.dumps({k: v for k, v in out.items() if k != "rows"}, indent=1))
    return out


# --------------------------------------------------------------------------- proof


def proof_scenes():
    """The three example scenes of issue 5 (the product shot also with a tight tolerance),
    as the planner sees them, and a daylight study (the sky seen only as lighting: an
    architect's interior or a building's facade, nothing farther than 50 m); the
    tolerances are ours (the issue names none)."""
    from skymodel.planner import CameraView, SceneDescription

    return {
        "product_noon": SceneDescription(
            cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, -0.1)], fov_deg=40.0)],
            sun_elevation_deg=60.0, farthest_object_m=200.0, sky_visible=True, image_width=1920,
            image_height=1080, tolerance_kind="de2000", tolerance=5.0),
        "product_noon_tight": SceneDescription(
            cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, -0.1)], fov_deg=40.0)],
            sun_elevation_deg=60.0, farthest_object_m=200.0, sky_visible=True, image_width=1920,
            image_height=1080, tolerance_kind="de2000", tolerance=1.0),
        "landscape_sun5": SceneDescription(
            cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, 0.05)], fov_deg=60.0)],
            sun_elevation_deg=5.0, farthest_object_m=30_000.0, sky_visible=True, image_width=1920,
            image_height=1080, tolerance_kind="de2000", tolerance=2.0),
        "twilight_sky": SceneDescription(
            cameras=[CameraView(altitude_m=0.0, min_elevation_deg=0.0, max_elevation_deg=90.0, fov_deg=180.0)],
            sun_elevation_deg=-4.0, farthest_object_m=0.0, sky_visible=True, image_width=2048,
            image_height=1024, tolerance_kind="de2000", tolerance=2.0),
        "daylight_study": SceneDescription(
            cameras=[CameraView(altitude_m=1.7, view_directions=[(0.0, 1.0, 0.0)], fov_deg=70.0)],
            sun_elevation_deg=30.0, farthest_object_m=50.0, sky_visible=False, image_width=1920,
            image_height=1080, tolerance_kind="de2000", tolerance=1.0),
    }


_CPU: list = []  # CPU seconds of the last _timed call


def _timed(fn):
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    _CPU[:] = [time.process_time() - c]
    return out, time.perf_counter() - t


def _cpu_plan(scene):
    """The planner's plan of ``scene`` with the accuracy table's preset wall times replaced
    by their CPU times: its predictions are CPU seconds, to compare with the builds' CPU
    seconds (which a shared machine's load changes far less than wall time), or None when
    the table has no CPU times."""
    import copy

    from skymodel.planner import ACCURACY_PATH, load_table, plan

    acc = load_table(ACCURACY_PATH)
    if not acc or not all(v.get("cpu_s") for per in acc.get("presets", {}).values() for v in per.values()):
        return None
    acc = copy.deepcopy(acc)
    for per in acc["presets"].values():
        for v in per.values():
            v["time_s"] = v["cpu_s"]
    return plan(scene, accuracy=acc)


def run_proof(write: bool, width: int, repeats: int = REPEATS) -> int:
    from skymodel import Atmosphere
    from skymodel.planner import plan
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.sky import QUALITY
    from skymodel.wavelengths import default_wavelengths

    dirs, omega = sky_directions(width)
    atm = Atmosphere(location=LOCATION, month=MONTH)
    wl_all = default_wavelengths(5.0)
    results = {}
    for name, scene in proof_scenes().items():
        p = plan(scene)
        el = scene.sun_elevation_deg

        def everything():
            prof = atm.optical_profile(wl_all)
            m = SkyMarcher(prof, el, 180.0, 0.0, QUALITY["final"])
            return m, m.radiance(dirs)

        def planned():  # as the add-on builds it: the planner's own way of carrying out a plan
            wl = default_wavelengths(p.wavelength_step_nm)
            prof = p.apply_to_atmosphere(atm).optical_profile(wl)
            if p.n_layers:
                prof = volume_shells(prof, p.n_layers)
            m = SkyMarcher(prof, el, 180.0, 0.0, p.march_settings(QUALITY["final"]))
            return m, m.radiance(dirs)

        (m_all, r_all), t_all = _timed(everything)
        cpu_all = list(_CPU)
        (m_plan, r_plan), t_plan = _timed(planned)
        cpu_plan = list(_CPU)
        times_all, times_plan = [t_all], [t_plan]
        for _ in range(repeats - 1):  # alternate, so that a change of the machine's load hits both alike
            times_plan.append(_timed(planned)[1])
            cpu_plan += _CPU
            times_all.append(_timed(everything)[1])
            cpu_all += _CPU
        ref = Reference(r_all.radiance, dirs, omega, r_all.sun_irradiance, el, wl_all)
        cmp = ref.compare(r_plan.radiance, r_plan.sun_irradiance, el, m_plan.profile.wavelengths_nm)
        from skymodel.planner import visible_bands

        bands = visible_bands(scene)
        sky_err = max([cmp["sky"][b]["de2000_mean"] for b in bands] or [0.0])
        err = max(sky_err, cmp["lighting"]["de2000"])
        out = {"scene": {"sun_elevation_deg": el, "farthest_object_m": scene.farthest_object_m,
                         "sky_visible": scene.sky_visible, "view_elevation_deg": scene.elevation_range_deg,
                         "tolerance": scene.tolerance, "tolerance_kind": scene.tolerance_kind},
               "plan": {k: {"on": d.on, "value": d.value, "reason": d.reason,
                            "predicted_error": round(d.predicted_error, 4)} for k, d in p.decisions.items()},
               "predicted_error": round(p.predicted_error, 4),
               "time_everything_s": round(min(times_all), 3), "time_planned_s": round(min(times_plan), 3),
               # the planner's own prediction of these two builds at this size (Plan.predicted_environment_s,
               # what decide_angular_resolution uses), against the median of the timed runs
               "predicted_everything_s": round(p.predicted_environment_s(width, everything_on=True), 3),
               "predicted_planned_s": round(p.predicted_environment_s(width), 3),
               "median_everything_s": round(float(np.median(times_all)), 3),
               "median_planned_s": round(float(np.median(times_plan)), 3),
               "time_basis": p.time_basis,
               "cpu_everything_s": [round(t, 3) for t in cpu_all], "cpu_planned_s": [round(t, 3) for t in cpu_plan],
               "times_everything_s": [round(t, 3) for t in times_all],
               "times_planned_s": [round(t, 3) for t in times_plan],
               "orders_everything": int(m_all.field.orders), "orders_planned": int(m_plan.field.orders),
               "measured_error": round(err, 4), "sky_error_by_band": cmp["sky"], "lighting_error": cmp["lighting"]}
        if scene.farthest_object_m > 0:
            # the farthest object's colour seen through the planned medium vs the everything-on one
            from skymodel.colorimetry import cmf_weights

            e_plan = horizontal_irradiance(r_plan.radiance, dirs, omega, r_plan.sun_irradiance, el)
            wl_p = m_plan.profile.wavelengths_nm
            ap_all = aerial_perspective(m_all.profile, lambda d: m_all.radiance(d).radiance, ref.e_h, ref.w, el)
            ap_plan = aerial_perspective(m_plan.profile, lambda d: m_plan.radiance(d).radiance, e_plan,
                                         cmf_weights(wl_p), el)
            pick = min(range(len(DISTANCES_M)), key=lambda i: abs(DISTANCES_M[i] - scene.farthest_object_m))
            out["object"] = {"distance_m": DISTANCES_M[pick],
                             "transmittance_550_everything": ap_all[pick]["transmittance_550"],
                             "transmittance_550_planned": ap_plan[pick]["transmittance_550"]}
        out["time_saving"] = round(1.0 - out["time_planned_s"] / out["time_everything_s"], 3)
        out["ratio_everything"] = round(out["median_everything_s"] / max(out["predicted_everything_s"], 1e-9), 3)
        out["ratio_planned"] = round(out["median_planned_s"] / max(out["predicted_planned_s"], 1e-9), 3)
        pc = _cpu_plan(scene)
        if pc is not None:  # the same prediction in CPU seconds, against the builds' CPU seconds
            out["predicted_cpu_everything_s"] = round(pc.predicted_environment_s(width, everything_on=True), 3)
            out["predicted_cpu_planned_s"] = round(pc.predicted_environment_s(width), 3)
            out["ratio_cpu_everything"] = round(float(np.median(cpu_all)) / out["predicted_cpu_everything_s"], 3)
            out["ratio_cpu_planned"] = round(float(np.median(cpu_plan)) / out["predicted_cpu_planned_s"], 3)
        out["load_average_1min"] = round(os.getloadavg()[0], 2)
        results[name] = out
        print(f"{name}: everything {out['time_everything_s']:.2f} s, planned {out['time_planned_s']:.2f} s "
              f"({out['time_saving']:.0%} saved); error {err:.2f} (predicted {p.predicted_error:.2f}, "
              f"tolerance {scene.tolerance:g}); median/predicted s: everything {out['median_everything_s']:.2f}/"
              f"{out['predicted_everything_s']:.2f} ({out['ratio_everything']:.2f}x), planned "
              f"{out['median_planned_s']:.2f}/{out['predicted_planned_s']:.2f} ({out['ratio_planned']:.2f}x); "
              f"load {out['load_average_1min']:.1f}", flush=True)
        for line in p.summary():
            print("   ", line)
    meta = {"machine": machine(), "git_revision": git_revision(), "command": command_line(),
            "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "camera": {"camera": "equirectangular", "width": width, "height": width // 2},
            "everything_on": "quality 'final', 5 nm (81 wavelengths), smooth profile, all effects",
            "repeats": repeats,
            "accuracy_table": _accuracy_table_used(),
            "source": "measured: skymodel ray marcher, this repository", "scenes": results}
    if write:
        with open(PROOF_JSON, "w", encoding="utf-8") as f:
            json.dump(meta, f, indent=1, default=str)
            f.write("\n")
        print(f"wrote {PROOF_JSON}")
        write_doc(meta)
    return 0


def _accuracy_table_used():
    """Date and command of ``skymodel/data/presets/accuracy/measured.json`` when the planner reads it, else None."""
    from skymodel.planner import ACCURACY_PATH, load_table

    acc = load_table(ACCURACY_PATH)
    if not acc:
        return None
    # the benchmark's baseline (81 wavelengths, its baseline settings) against its reference, per scene
    base = {r["scene"]: round(float(r["de2000_mean"]), 4) for r in acc.get("rows", [])
            if r.get("knob") == "wavelengths" and r.get("value") == 81 and r.get("de2000_mean") is not None}
    scenes = acc.get("scenes", {})
    return {"date": acc.get("date"), "command": acc.get("command"),
            "baseline_de2000_by_sun_deg": {f"{float(scenes[k]['sun_elevation_deg']):g}": v
                                           for k, v in base.items() if k in scenes}}


def write_doc(meta):
    """The measured sections of docs/planner.md (the prose around them is hand-written)."""
    from common import update_section

    from skymodel.planner import load_table

    cmd = "python benchmarks/bench_planner.py --proof --write"
    cam = meta["camera"]
    lines = [f"Measured {meta['date']} on {meta['machine']} (git {meta['git_revision']}); regenerate with:", "",
             f"    {cmd}", "",
             f"Both builds rendered with the marcher on an equirectangular camera of {cam['width']}x{cam['height']} "
             "(a reduced size; the plan's angular-resolution decision is the width Blender gets). Everything on: "
             + meta["everything_on"] + ". Planned: the plan's spectral grid, orders, atmosphere (effects left out "
             "removed: `Plan.apply_to_atmosphere`, as the add-on builds it) and, with shells, the add-on's shells (`skymodel.optics.shells.volume_shells`). Times: the fastest of "
             + str(meta.get("repeats", 2)) + " alternated runs of each build. Error: the planner's metric (mean "
             "CIEDE2000 of the tone-mapped sky over the view bands the cameras see, or of the light on a horizontal "
             "surface, whichever is larger) of the planned render against the everything-on render. The "
             "tolerances are ours (the issue names none).", "",
             "| scene | sun | tolerance (dE2000) | plan | everything on (s) | planned (s) | time saved | "
             "predicted error | measured error |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, r in meta["scenes"].items():
        pl = r["plan"]
        off = [k for k in ("aerosols", "ozone", "earth_shadow", "ground_reflection") if not pl[k]["on"]]
        ms = pl["multiple_scattering"]
        shells = pl["aerial_perspective"]
        desc = ("shells: " + str(shells["value"]["n_layers"]) + " layers" if shells["on"] else "environment only")
        desc += f"; orders {ms['value'] if ms['value'] is not None else 'until converged'}"
        desc += f"; {pl['spectral_resolution']['value']:g} nm"
        desc += "; off: " + (", ".join(k.replace('_', ' ') for k in off) if off else "none")
        lines.append(f"| {name} | {r['scene']['sun_elevation_deg']:g} | {r['scene']['tolerance']:g} | {desc} | "
                     f"{r['time_everything_s']:.2f} | {r['time_planned_s']:.2f} | {r['time_saving']:.0%} | "
                     f"{r['predicted_error']:.2f} | {r['measured_error']:.2f} |")
    loads = [r.get("load_average_1min") for r in meta["scenes"].values() if r.get("load_average_1min") is not None]
    acc = meta.get("accuracy_table")
    if acc:
        pred = ("The predicted error counts what the tables measure. The plans read `skymodel/data/presets/accuracy/measured.json` "
                f"({acc.get('date')}): its `wavelengths` rows price the spectral grid against the 5 nm (81 "
                "wavelengths) build, its `orders` rows add 5-8 orders and its `layers` rows replace 4, 8 and 16 "
                "shells, each at the worse of its error as lighting (the light on a horizontal surface, sky and sun; "
                "rows measured without it: the whole sky's error) and its errors in the view-elevation bands the "
                "cameras see (none for a sky seen only as lighting; the effect table's rows are read the same way). Its errors "
                "are taken against its own converged reference, so they include the accuracy "
                "bench's baseline error ("
                + ", ".join(f"{v:.2f} dE2000 with the sun at {k}°" for k, v in
                            sorted(acc.get("baseline_de2000_by_sun_deg", {}).items(), key=lambda kv: -float(kv[0])))
                + "), which both builds here share, so the predictions should err high.")
    else:
        pred = ("The predicted error counts what the tables measure: the effect table's reference grid is 10 nm, "
                "so the difference between a 10 nm plan and the 5 nm everything-on build is not predicted until "
                "`skymodel/data/presets/accuracy/measured.json` (its `wavelengths` rows) exists; the measured error includes it.")
    under = [name for name, r in meta["scenes"].items() if r["measured_error"] > r["predicted_error"]]
    if under:
        try:
            with open(EFFECTS_JSON, encoding="utf-8") as f:
                eff_date = json.load(f).get("date", "?")
        except OSError:
            eff_date = "?"
        pred += (" They do not in " + ", ".join(f"`{n}`" for n in under) + ": there the measured error exceeds the "
                 f"prediction. The effect table (`skymodel/data/presets/planner/effects.json`, measured {eff_date}) may predate "
                 "changes to the renderer; `python benchmarks/bench_planner.py --write` re-measures it.")
    lines += ["", pred + " The prediction also counts the aerial-perspective error on objects left to the "
              "environment (product shots: objects 200 m away), which a sky render does not contain. "
              "The machine is shared" + (f" (1-minute load average {min(loads):.1f}-{max(loads):.1f} on its "
                                         f"{os.cpu_count()} cores during the runs)" if loads else "")
              + ": times vary from run to run, the two builds of a scene were timed alternately."]
    timed = [(n, r) for n, r in meta["scenes"].items() if "predicted_everything_s" in r]
    if timed:
        ratios = [x for _, r in timed for x in (r["ratio_everything"], r["ratio_planned"])]
        within = all(0.5 <= x <= 2.0 for x in ratios)
        lines += ["", "Predicted against measured time (issue 23: within a factor of 2). The prediction is the "
                  "planner's own (`Plan.predicted_environment_s`, what the angular-resolution decision uses) for "
                  f"a cold build of {cam['width']}x{cam['height']}: " + timed[0][1]["time_basis"] + " (the plan's "
                  "time), less the pixels of the render that time was measured on, plus this size's "
                  "(`environment_build_time`). Measured: the median of the alternated runs.", "",
                  "| scene | everything on: predicted (s) | measured (s) | measured / predicted | planned: predicted (s) "
                  "| measured (s) | measured / predicted | CPU s measured / predicted: everything, planned | "
                  "load (1 min) |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for name, r in timed:
            cpu = (f"{r['ratio_cpu_everything']:.2f}, {r['ratio_cpu_planned']:.2f}" if "ratio_cpu_everything" in r
                   else "-")
            lines.append(f"| {name} | {r['predicted_everything_s']:.1f} | {r['median_everything_s']:.1f} | "
                         f"{r['ratio_everything']:.2f} | {r['predicted_planned_s']:.1f} | {r['median_planned_s']:.1f} | "
                         f"{r['ratio_planned']:.2f} | {cpu} | {r['load_average_1min']:.1f} |")
        lines += ["", f"Measured / predicted {min(ratios):.2f}-{max(ratios):.2f}: "
                  + ("every case within the factor of 2." if within else "not every case within the factor of 2.")
                  + " The time scale is the accuracy table's preset time, measured at its own load (its rows "
                  "say which): a machine more (or less) loaded than then scales every measured time, not the "
                  "prediction. The CPU column makes the same prediction from the table's CPU seconds "
                  "(`cpu_s`) and compares it with the builds' CPU seconds, which the load changes far less."]
    lines += ["", "Per band and for the light (measured error of the planned build):", "",
              "| scene | ground | horizon (0-10°) | low (10-30°) | high (30-90°) | light dE2000 | light illuminance |",
              "|---|---|---|---|---|---|---|"]
    for name, r in meta["scenes"].items():
        b = r["sky_error_by_band"]
        lines.append(f"| {name} | " + " | ".join(f"{b[k]['de2000_mean']:.2f}" for k in ("ground", "horizon", "low", "high"))
                     + f" | {r['lighting_error']['de2000']:.2f} | {r['lighting_error']['illuminance_rel']:.1%} |")
    update_section(DOC, "## Measured: planned vs everything on", "\n".join(lines))
    eff = load_table(EFFECTS_JSON)
    if eff:
        head = ["ozone_off", "aerosols_off", "ground_albedo_0", "earth_shadow_off", "orders_1", "orders_2",
                "orders_4", "wavelength_step_20", "wavelength_step_40", "layers_8", "layers_16", "layers_24"]
        head = [h for h in head if all(h in row["effects"] for row in eff["rows"])]
        loads = [r["load_average_1min"] for r in eff["rows"] if r.get("load_average_1min") is not None]
        load = f"; 1-minute load average {min(loads):.1f}-{max(loads):.1f}" if loads else ""
        t = [f"From `skymodel/data/presets/planner/effects.json` ({eff['date']}, {eff['machine']}{load}); regenerate with:", "",
             "    python benchmarks/bench_planner.py --write", "",
             "Mean CIEDE2000 of switching one effect off (or simplifying it), for the sky 30-90° above the horizon "
             "/ for the light on a horizontal surface; rural aerosol, June; reference: every effect on, "
             f"{eff['wavelength_step_nm']:g} nm, scattering until an order adds < 1e-4.", "",
             "| sun (°) | " + " | ".join(h.replace("_", " ") for h in head) + " | 30 km aerial (dE mean) |",
             "|---" * (len(head) + 2) + "|"]
        for row in eff["rows"]:
            ap = next((a for a in row["aerial_perspective"] if a["distance_m"] == 30_000), None)
            t.append(f"| {row['sun_elevation_deg']:g} | " + " | ".join(
                f"{row['effects'][h]['sky']['high']['de2000_mean']:.2f} / {row['effects'][h]['lighting']['de2000']:.2f}"
                for h in head) + f" | {ap['de2000_mean']:.1f} |" if ap else " | - |")
        update_section(DOC, "## Measured: what each effect does", "\n".join(t))
    print(f"updated {DOC}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--proof", action="store_true", help="render the example scenes (issue 5's and a daylight study) planned vs everything on")
    ap.add_argument("--write", action="store_true", help="write the results (presets/planner, docs/planner.md)")
    ap.add_argument("--width", type=int, default=64, help="equirectangular width of the effect table's renders")
    ap.add_argument("--step", type=float, default=10.0, help="wavelength step (nm) of the reference")
    ap.add_argument("--doc-only", action="store_true",
                    help="rewrite the measured sections of docs/planner.md from the stored JSON files")
    ap.add_argument("--proof-width", type=int, default=256, help="equirectangular width of the proof renders")
    ap.add_argument("--pixels", action="store_true",
                    help="measure what an environment's pixels add to its build (the planner's per-pixel constants)")
    ap.add_argument("--qualities", default="preview,final", help="qualities of --pixels")
    ap.add_argument("--repeats", type=int, default=REPEATS, help="timed runs of each build in the proof (alternated)")
    ap.add_argument("--elevations", default=",".join(str(e) for e in ELEVATIONS_DEG))
    args = ap.parse_args(argv)
    if args.pixels:
        for q in args.qualities.split(","):
            measure_pixel_costs(quality=q, repeats=args.repeats)
        return 0
    if args.doc_only:
        with open(PROOF_JSON, encoding="utf-8") as f:
            write_doc(json.load(f))
        return 0
    if args.proof:
        return run_proof(args.write, args.proof_width, args.repeats)
    elevations = [float(e) for e in args.elevations.split(",")]
    out = measure_effects(elevations, args.width, args.step)
    text = json.dumps(out, indent=1, default=str)
    if args.write:
        os.makedirs(os.path.dirname(EFFECTS_JSON), exist_ok=True)
        with open(EFFECTS_JSON, "w", encoding="utf-8") as f:
            f.write(text + "\n")
        print(f"wrote {EFFECTS_JSON}")
    else:
        print(text[:2000])
    return 0


if __name__ == "__main__":
    sys.exit(main())
