"""Blender add-on: accuracy of the RGB volumetric approximation, and timings.

    python benchmarks/bench_blender.py projection [--location desert --elevations 60,20,5,1]
    python benchmarks/bench_blender.py cycles     [--size 128x64 --samples 256 --layers 8]
    python benchmarks/bench_blender.py timings
    python benchmarks/bench_blender.py crossval   [--without-fixes] [--case-aerosol rural --case-layers 8
                                               --case-samples 64 --no-converged]
    python benchmarks/bench_blender.py issue      [--write]   (~10 min on a loaded 2-core machine)
    python benchmarks/bench_blender.py environment [--write --qualities preview,final,reference]  (~8 min)

``projection`` (no bpy): what Cycles is asked to render vs the spectral truth, both
computed by the core's marcher so that no Monte Carlo noise enters:

* truth: the spectral render of the *layered* profile (the same layers the volumes use,
  10 nm grid, tabulated Mie phase, depolarised Rayleigh) converted to Rec.709;
* RGB model: the same marcher on a three-"wavelength" profile whose coefficients are the
  add-on's projected RGB coefficients, with the add-on's phase functions (Rayleigh without
  depolarisation, the double-HG aerosol lobes) and the RGB sun. This is exactly the medium
  the Cycles volumes hold; the difference is the error of the RGB projection + phase fit.

``cycles`` (bpy): renders the volumetric scene with Cycles and compares it with the RGB
model (same directions): the error of geometry, layering into meshes and Cycles' own
transport (volume bounces) on top of the projection.

``timings``: Build Sky in both modes and a small Cycles render of each.

``crossval`` (bpy): the case of ``tests/test_addon_crossval.py`` with its numbers: Cycles / marcher
per region, the Monte Carlo noise, and the marcher's own error (test settings vs a 4096-node march
with finer sun tables); ``--without-fixes`` renders it with the add-on's two Cycles fixes switched
off (volume apex on the axis, species' own coefficients in the closures) to show what they fix.
The ``--case-*`` options render another case than the test's (tropospheric aerosol, layers,
samples per seed), ``--no-converged`` skips the 4096-node march (docs/blender.md, "Cycles against
the marcher").

``environment`` (bpy): only that first item, plus the banded-vs-unbanded check of the add-on's
environment at 512x256 (no bpy); ``--write`` replaces only its table in docs/benchmarks.md.

``issue`` (bpy): the benchmarks of issue 4, written to docs/benchmarks.md (section "Blender")
with ``--write``:

* Build Sky in environment mode at each quality (cold cache: the core's render and the EXR; the
  Blender side adds < 1 s), each in a fresh Python process (``env-row``, internal) for its time,
  its peak resident memory (VmHWM; ru_maxrss would carry the parent's) and an image check
  (finite, >= 0, zenith bluer than the horizon);
* a volumetric Cycles render at 256x128 for 16/64/256 samples (single scattering, the
  cross-validation medium), its time and its difference from the marcher's image of the same
  RGB shells (per region, with the noise, and per pixel);
* aerial perspective: a grey (albedo 0.5) diffuse square 1, 10 and 50 km away, seen at the
  horizon with a narrow camera, in environment mode (no air between) and volumetric mode,
  against the marcher's ``T(d) L_surface + L_path(d)`` along the same line of sight.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from common import machine  # noqa: E402

from blender_addon.volumetric import TO_RGB, rgb_model_profile  # noqa: E402
from skymodel.validation.accuracy import peak_memory_mb  # noqa: E402  (VmHWM of this process, MiB)


def _plan(location, month, elevation, azimuth=180.0, n_layers=8, mode="VOLUMETRIC"):
    from blender_addon import physics

    return physics.resolve(physics.SkyParams(location=location, month=month, sun_elevation_deg=elevation,
                                             sun_azimuth_deg=azimuth, mode=mode, n_layers=n_layers))


def _stats(rgb_test, rgb_ref, cam):
    """Luminance and chromaticity differences over the sky (upper hemisphere)."""
    luma = np.array([0.2126, 0.7152, 0.0722])
    dirs, valid = cam.directions()
    up = valid & (dirs[..., 2] > 0.02)
    yt, yr = rgb_test @ luma, rgb_ref @ luma
    rel = (yt - yr) / yr
    ct = rgb_test / rgb_test.sum(-1, keepdims=True)
    cr = rgb_ref / rgb_ref.sum(-1, keepdims=True)
    dc = np.abs(ct - cr).max(-1)
    h = rgb_ref.shape[0]
    return {
        "zenith_Y_rel": float(rel[0].mean()),
        "horizon_Y_rel": float(rel[h // 2 - 1].mean()),
        "sky_Y_rel_rms": float(np.sqrt(np.mean(rel[up] ** 2))),
        "sky_Y_rel_max": float(np.abs(rel[up]).max()),
        "sky_chroma_max": float(dc[up].max()),
        "zenith_rgb_ref": [round(float(v), 4) for v in rgb_ref[0].mean(0)],
        "zenith_rgb_test": [round(float(v), 4) for v in rgb_test[0].mean(0)],
    }


def projection(args):
    from blender_addon import volumetric
    from blender_addon.physics import spectrum_rgb
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky

    out = {"machine": machine(), "location": args.location, "month": args.month, "layers": args.layers, "cases": []}
    for el in args.elevations:
        plan = _plan(args.location, args.month, el, n_layers=args.layers)
        vol = volumetric.volume_layers(plan, args.layers)
        cam = make_camera("equirectangular", args.width, center_azimuth_deg=90.0)
        t0 = time.perf_counter()
        truth = render_sky(vol["layered"], cam, el, 180.0, 0.0, args.quality, include_sun=False)
        rgb_truth = spectrum_rgb(truth.radiance, vol["profile"].wavelengths_nm)
        model = render_sky(rgb_model_profile(vol), cam, el, 180.0, 0.0, args.quality, include_sun=False)
        rgb_model = model.radiance[..., TO_RGB]
        smooth = render_sky(vol["profile"], cam, el, 180.0, 0.0, args.quality, include_sun=False)
        rgb_smooth = spectrum_rgb(smooth.radiance, vol["profile"].wavelengths_nm)
        sun_truth = spectrum_rgb(truth.sun_irradiance, vol["profile"].wavelengths_nm)
        sun_model = model.sun_irradiance[TO_RGB]
        case = {
            "sun_elevation_deg": el,
            "rgb_model_vs_spectral_layered": _stats(rgb_model, rgb_truth, cam),
            "spectral_layered_vs_smooth": _stats(rgb_truth, rgb_smooth, cam),
            # per channel, relative to the sun's luminance (a channel can be ~0 at a low sun)
            "sun_at_observer_rgb_rel": [float(v) for v in (sun_model - sun_truth)
                                        / max(float(sun_truth @ [0.2126, 0.7152, 0.0722]), 1e-30)],
            "phases": vol["phases"],
            "seconds": round(time.perf_counter() - t0, 1),
        }
        out["cases"].append(case)
        print(json.dumps({k: case[k] for k in ("sun_elevation_deg", "rgb_model_vs_spectral_layered",
                                                "spectral_layered_vs_smooth", "sun_at_observer_rgb_rel")}),
              flush=True)
    return out


def _bpy_scene(location, month, elevation, mode, layers, bounces, width, samples, azimuth=180.0, center_azimuth=None):
    import bpy

    import blender_addon
    from blender_addon import render as headless

    if not hasattr(bpy.types.World, "skymodel"):
        blender_addon.register()
    opts = headless.parse_args(["--location", location, "--month", str(month), "--sun-elevation", str(elevation),
                                "--sun-azimuth", str(azimuth), "--mode", mode, "--layers", str(layers),
                                "--volume-bounces", str(bounces), "--samples", str(samples),
                                "--size", f"{width}x{width // 2}", "--out", os.path.join(tempfile.mkdtemp(), "x.png")]
                               + ([] if center_azimuth is None else ["--center-azimuth", str(center_azimuth)]))
    t0 = time.perf_counter()
    scene = headless.build_scene(opts)
    t_build = time.perf_counter() - t0
    if center_azimuth is not None:  # a measurement: each pixel the mean over its own footprint
        scene.cycles.pixel_filter_type = "BOX"
        scene.cycles.filter_width = 1.0
    t0 = time.perf_counter()
    rgb = headless.render_linear(scene)
    return rgb, t_build, time.perf_counter() - t0


def cycles(args):
    from blender_addon import volumetric
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky

    out = {"machine": machine(), "cases": []}
    for el in args.elevations:
        # same pixel directions as the core camera below (centre azimuth 90)
        rgb_c, tb, tr = _bpy_scene(args.location, args.month, el, "volumetric", args.layers, args.bounces,
                                   args.width, args.samples, center_azimuth=90.0)
        plan = _plan(args.location, args.month, el, n_layers=args.layers)
        vol = volumetric.volume_layers(plan, args.layers)
        cam = make_camera("equirectangular", args.width, center_azimuth_deg=90.0)
        model = render_sky(rgb_model_profile(vol), cam, el, 180.0, 1.7, args.quality, include_sun=False)
        rgb_m = model.radiance[..., TO_RGB]
        # average rows into 8 elevation bands to beat Monte Carlo noise
        h = rgb_m.shape[0]
        bands = []
        for lo in range(0, h // 2, max(1, h // 16)):
            hi = lo + max(1, h // 16)
            bands.append({"zenith_deg": round(90 * (lo + hi) / h, 1),
                          "cycles_Y": float((rgb_c[lo:hi] @ [0.2126, 0.7152, 0.0722]).mean()),
                          "model_Y": float((rgb_m[lo:hi] @ [0.2126, 0.7152, 0.0722]).mean()),
                          "cycles_rgb": [round(float(v), 4) for v in rgb_c[lo:hi].mean((0, 1))],
                          "model_rgb": [round(float(v), 4) for v in rgb_m[lo:hi].mean((0, 1))]})
        case = {"sun_elevation_deg": el, "build_s": round(tb, 1), "render_s": round(tr, 1),
                "samples": args.samples, "volume_bounces": args.bounces, "bands": bands,
                "stats": _stats(rgb_c, rgb_m, cam)}
        out["cases"].append(case)
        print(json.dumps(case), flush=True)
    return out


def timings(args):
    out = {"machine": machine(), "runs": []}
    for mode in ("environment", "volumetric"):
        for quality_width in (128, 512):
            rgb, tb, tr = _bpy_scene(args.location, args.month, 20.0, mode, args.layers, args.bounces,
                                     quality_width, args.samples)
            run = {"mode": mode, "size": f"{quality_width}x{quality_width // 2}", "samples": args.samples,
                   "build_s": round(tb, 2), "render_s": round(tr, 2)}
            out["runs"].append(run)
            print(json.dumps(run), flush=True)
    return out


# --------------------------------------------------------------------------- issue 4 benchmarks

LUMA = np.array([0.2126, 0.7152, 0.0722])


def _crossval_module():
    sys.path.insert(0, str(ROOT / "tests"))
    import test_addon_crossval as T

    return T


def _region_table(c1, c2, model, masks):
    out = {}
    for name, mask in masks.items():
        n = int(mask.sum())
        c = 0.5 * (c1 + c2)[mask].mean(axis=0)
        sigma = np.sqrt((0.25 * (c1 - c2)[mask] ** 2).mean(axis=0) / n)
        m = model[mask].mean(axis=0)
        out[name] = {"pixels": n, "cycles_over_marcher_minus_1_pct": [round(float(v), 2) for v in 100 * (c / m - 1)],
                     "noise_1sigma_pct": [round(float(v), 2) for v in 100 * sigma / m]}
    return out


def crossval(args):
    """The test case, with its numbers (and optionally without the add-on's two fixes, or
    another case: --case-aerosol / --case-layers / --case-samples)."""
    T = _crossval_module()
    from blender_addon import volumetric

    # other cases than the test's first
    if args.case_aerosol is not None:
        T.CASE = dict(T.CASE, aerosol=args.case_aerosol)
    if args.case_layers is not None:
        T.CASE = dict(T.CASE, layers=args.case_layers)
    if args.case_samples is not None:
        T.SAMPLES = args.case_samples
    if args.without_fixes:
        plain_sphere = volumetric.sphere_arrays
        volumetric.sphere_arrays = lambda *a, **k: plain_sphere(*a, **dict(k, apex_off_axis=False))
        volumetric.closure_split = lambda species, u: [np.maximum(np.asarray(c, float), 0.0) for c in species]
    t0 = time.perf_counter()
    gen = T.cycles_images.__wrapped__(T.CASE)
    c1, c2 = next(gen)
    t_cycles = time.perf_counter() - t0
    t0 = time.perf_counter()
    model = T.marcher_image.__wrapped__(T.CASE)
    t_marcher = time.perf_counter() - t0
    masks = T.regions(T.HEIGHT, T.WIDTH)
    out = {"machine": machine(), "case": T.CASE, "samples": T.SAMPLES, "without_fixes": bool(args.without_fixes),
           "cycles_s": round(t_cycles, 1),
           "marcher_s": round(t_marcher, 1), "regions": _region_table(c1, c2, model, masks)}
    if args.no_converged:
        for _ in gen:
            pass
        print(json.dumps(out, indent=1), flush=True)
        return out
    # the marcher's own error: the test's settings vs a converged march (same directions)
    from skymodel.render import marcher as marcher_module

    fine_settings = marcher_module.MarchSettings
    T.VIEW_STEPS = 4096
    marcher_module.MarchSettings = lambda **k: fine_settings(**k, sun_table_altitudes=256, sun_table_x=384,
                                                              sun_table_steps=640)
    try:
        fine = T.marcher_image.__wrapped__(T.CASE)
    finally:
        marcher_module.MarchSettings = fine_settings
    out["marcher_test_settings_vs_converged_pct"] = {
        name: [round(float(v), 3) for v in 100 * (model[m].mean(axis=0) / fine[m].mean(axis=0) - 1)]
        for name, m in masks.items()}
    out["cycles_vs_converged_marcher"] = _region_table(c1, c2, fine, masks)
    for _ in gen:
        pass
    print(json.dumps(out, indent=1), flush=True)
    return out


def _env_build_row(q):
    """One Build Sky (environment mode) at quality ``q``, cold cache, in this (fresh) process:
    time, peak resident memory (VmHWM: before the build, i.e. Python + numpy + bpy + the
    add-on, and after it) and the image's sanity (finite; zenith bluer than the horizon)."""
    os.environ["SKYMODEL_CACHE_DIR"] = cache = tempfile.mkdtemp(prefix="skymodel-bench-cache-")
    import bpy

    from blender_addon import physics
    from blender_addon import render as headless
    from skymodel.errors import SkymodelInputError

    headless._ensure_registered()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    headless._ensure_registered()
    o = headless.parse_args(["--location", "rural", "--month", "6", "--sun-elevation", "30", "--mode",
                             "environment", "--quality", q, "--out", os.path.join(tempfile.mkdtemp(), "x.png")])
    w = physics.IMAGE_WIDTH[q]
    row = {"quality": q, "image": f"{w}x{w // 2}", "wavelength_step_nm": physics.WAVELENGTH_STEP_NM[q],
           "load_before": [round(v, 2) for v in os.getloadavg()], "baseline_peak_MiB": round(peak_memory_mb(), 1)}
    t0 = time.perf_counter()
    try:
        headless.build_scene(o, progress=None)
        row["build_s"] = round(time.perf_counter() - t0, 1)
    except SkymodelInputError as ex:  # e.g. the core's memory guard
        row["refused"] = str(ex)
    row["peak_MiB"] = round(peak_memory_mb(), 1)
    row["load_after"] = [round(v, 2) for v in os.getloadavg()]
    if "build_s" in row:
        exr = next(Path(cache).glob("sky-*.exr"))
        img = bpy.data.images.load(str(exr), check_existing=False)
        iw, ih = img.size
        px = np.empty(iw * ih * 4, np.float32)
        img.pixels.foreach_get(px)
        rgb = px.reshape(ih, iw, 4)[::-1, :, :3].astype(float)  # row 0 at the top (zenith)
        zen, hor = rgb[0].mean(axis=0), rgb[ih // 2 - 1].mean(axis=0)
        row["check"] = {"finite": bool(np.isfinite(rgb).all()), "min": float(rgb.min()),
                        "zenith_rgb": [round(float(v), 4) for v in zen],
                        "horizon_rgb": [round(float(v), 4) for v in hor],
                        "zenith_blue_share": round(float(zen[2] / zen.sum()), 4),
                        "horizon_blue_share": round(float(hor[2] / hor.sum()), 4)}
        row["check"]["sane"] = bool(row["check"]["finite"] and row["check"]["min"] >= 0.0
                                    and row["check"]["zenith_blue_share"] > row["check"]["horizon_blue_share"])
    return row


def _env_build_times(qualities):
    """Build Sky (environment mode) at each quality, cold cache, each in a fresh Python process
    (so that the peak memory is that build's: ru_maxrss / VmHWM would carry the parent's)."""
    import subprocess

    rows = []
    for q in qualities:
        proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "env-row", "--quality", q],
                              capture_output=True, text=True)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if proc.returncode != 0 or not lines:
            raise RuntimeError(f"environment build at quality {q} failed:\n{proc.stdout[-2000:]}{proc.stderr[-4000:]}")
        row = json.loads(lines[-1])
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def _env_markdown(rows, command, standalone=False, banded=None) -> str:
    """The environment build table (a block of the "## Blender" section)."""
    from common import git_revision

    loads = [v for r in rows for v in (r["load_before"][0], r["load_after"][0])]
    base = sorted({round(r["baseline_peak_MiB"]) for r in rows})
    span = lambda lo, hi, f: f"{lo:{f}}" if f"{lo:{f}}" == f"{hi:{f}}" else f"{lo:{f}}–{hi:{f}}"  # noqa: E731
    head = ("**Build Sky, environment mode** (rural, June, sun 30°; cold cache: the core's render of the "
            "equirectangular image (our sky is marched band by band straight to RGB, 3 values per pixel) and "
            "the EXR; through `blender_addon.render.build_scene`; each quality in a fresh Python process: the "
            "peak resident memory is that process's VmHWM, of which Python + numpy + bpy + the add-on before "
            f"the build is {span(base[0], base[-1], '.0f')} MiB; 1-min load average "
            f"{span(min(loads), max(loads), '.1f')} before and after the builds")
    if standalone:
        import datetime as dt

        head += (f"; {machine()}; revision {git_revision()}; {dt.date.today().isoformat()}; `nice -n 10`). "
                 f"Command:\n\n    {command}\n\nThe image check: finite, ≥ 0, and the zenith row's blue share "
                 f"B/(R+G+B) above the horizon row's:")
    else:
        head += "):"
    lines = [head, "", "| quality | image | wavelength step | build time | peak memory | zenith / horizon blue share |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        took = f"{r['build_s']:.1f} s" if "build_s" in r else f"refused: {r['refused']}"
        c = r.get("check")
        chk = (f"{c['zenith_blue_share']:.3f} / {c['horizon_blue_share']:.3f}" + ("" if c["sane"] else " (FAILED)")
               if c else "—")
        lines.append(f"| {r['quality']} | {r['image']} | {r['wavelength_step_nm']:g} nm | {took} | "
                     f"{r['peak_MiB'] / 1024:.2f} GiB | {chk} |")
    if banded:
        lines += ["", f"The banded environment equals the unbanded one: at {banded['width']}×{banded['width'] // 2} "
                  f"({banded['quality']}, {banded['bands']} bands) `physics.render_environment` differs from the RGB of the full spectral "
                  f"`render_sky` image by at most " + (f"{banded['max_rel_diff']:.1e} (relative; the EXR is float32)."
                                                 if banded["max_rel_diff"] else "0 (identical pixels).")]
    return "\n".join(lines)


def _replace_env_block(path, body):
    """Replace the environment table of the "## Blender" section of ``path`` (from its bold
    heading to the next bold heading), leaving the rest of the file as it is."""
    text = open(path, encoding="utf-8").read()
    sec = text.index("\n## Blender")
    start = text.index("**Build Sky, environment mode**", sec)
    end = text.index("\n**", start + 2)
    nxt = text.find("\n## ", sec + 1)
    if nxt != -1 and end > nxt:
        end = nxt
    with open(path, "w", encoding="utf-8") as f:
        f.write(text[:start] + body.rstrip() + "\n" + text[end:])


def _env_banded_check(width=512, quality="preview"):
    """The add-on's banded environment (``physics.render_environment``: band by band straight to
    RGB, 65536 pixels a band: 2 bands at 512x256) against reducing the full spectral cube of
    ``render_sky`` for the same plan, camera and wavelengths (the unbanded path); no bpy."""
    from blender_addon import physics
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky
    from skymodel.wavelengths import default_wavelengths

    plan = physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=30.0,
                                             sun_azimuth_deg=180.0, mode="ENVIRONMENT", quality=quality,
                                             image_width=width))
    t0 = time.perf_counter()
    banded, _ = physics.render_environment(plan, tempfile.mkdtemp(prefix="skymodel-bench-cache-"))
    wl = default_wavelengths(physics.WAVELENGTH_STEP_NM[quality])
    cam = make_camera("equirectangular", width, center_azimuth_deg=90.0)
    full = render_sky(plan.profile(wl), cam, plan.sun_elevation_deg, plan.sun_azimuth_deg,
                      plan.params.observer_altitude_m, quality, include_sun=False)
    ref = physics.fit_into_gamut(physics.spectrum_rgb(full.radiance, wl)).astype(np.float32)
    rel = np.abs(banded.astype(float) - ref) / np.maximum(np.abs(ref), 1e-30)
    row = {"width": width, "quality": quality, "bands": -(-width * (width // 2) // 65536),
           "max_rel_diff": float(rel.max()),
           "equal_to_float32": bool(np.allclose(banded, ref, rtol=1e-6, atol=0.0)),
           "seconds": round(time.perf_counter() - t0, 1)}
    print(json.dumps({"banded_vs_unbanded": row}), flush=True)
    return row


def environment(args):
    """Only the environment build at each quality; ``--write`` replaces its table in docs/benchmarks.md."""
    from common import command_line

    res = {"machine": machine(), "command": command_line(), "environment": _env_build_times(args.qualities),
           "banded_vs_unbanded": _env_banded_check()}
    if args.write:
        _replace_env_block(str(ROOT / "docs" / "benchmarks.md"),
                           _env_markdown(res["environment"], res["command"], standalone=True,
                                         banded=res["banded_vs_unbanded"]))
    return res


def _volumetric_sweep(samples_list, width):
    """Cycles at width x width/2 for each sample count vs the marcher on the same RGB shells."""
    import bpy

    T = _crossval_module()
    from blender_addon import physics, volumetric
    from blender_addon import render as headless
    from skymodel.render.marcher import MarchSettings, SkyMarcher

    h = width // 2
    bpy.ops.wm.read_factory_settings(use_empty=True)
    headless._ensure_registered()
    c = T.CASE
    o = headless.parse_args([
        "--location", c["location"], "--month", str(c["month"]), "--sun-elevation", str(c["sun_elevation"]),
        "--sun-azimuth", str(c["sun_azimuth"]), "--aerosol", c["aerosol"], "--albedo", "0", "--mode", "volumetric",
        "--layers", str(c["layers"]), "--volume-bounces", "0", "--size", f"{width}x{h}",
        "--camera-height", str(T.CAMERA_HEIGHT_M), "--center-azimuth", str(T.CENTER_AZIMUTH),
        "--out", os.path.join(tempfile.mkdtemp(), "x.png")])
    t0 = time.perf_counter()
    scene = headless.build_scene(o, progress=None)
    t_build = time.perf_counter() - t0
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    plan = physics.resolve(physics.SkyParams(location=c["location"], month=c["month"],
                                             sun_elevation_deg=c["sun_elevation"], sun_azimuth_deg=c["sun_azimuth"],
                                             aerosol=c["aerosol"], albedo=0.0, mode="VOLUMETRIC", n_layers=c["layers"]))
    prof = volumetric.rgb_model_profile(volumetric.volume_layers(plan, c["layers"]))
    t0 = time.perf_counter()
    m = SkyMarcher(prof, c["sun_elevation"], c["sun_azimuth"], T.CAMERA_HEIGHT_M,
                   MarchSettings(orders=1, exact=True, view_steps=T.VIEW_STEPS))
    ii, jj = np.meshgrid(np.arange(h), np.arange(width), indexing="ij")
    d = T.pixel_directions(ii.ravel(), jj.ravel(), h, width, T.CENTER_AZIMUTH)[:, 0]
    model = m.radiance(d).radiance[:, volumetric.TO_RGB].reshape(h, width, 3)
    t_marcher = time.perf_counter() - t0
    masks = T.regions(h, width)
    sky = np.zeros((h, width), bool)
    sky[: h // 2] = True
    rows = []
    for spp in samples_list:
        scene.cycles.samples = int(spp)
        imgs, times = [], []
        for seed in (1, 2):
            scene.cycles.seed = seed
            t0 = time.perf_counter()
            imgs.append(headless.render_linear(scene).astype(float))
            times.append(time.perf_counter() - t0)
        y1, ym = imgs[0] @ LUMA, model @ LUMA
        row = {"samples": int(spp), "render_s": round(min(times), 1), "build_s": round(t_build, 1),
               "marcher_s": round(t_marcher, 1),
               "pixel_Y_rel_rms_pct": round(float(100 * np.sqrt(np.mean((y1[sky] / ym[sky] - 1) ** 2))), 2),
               "regions": _region_table(imgs[0], imgs[1], model, masks)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def _line_of_sight(prof, marcher, direction, distance_m, observer_m, n=4000):
    """Marcher pieces along a finite line of sight (RGB, the profile's B, G, R order):
    transmittance T and single-scattering path radiance L_path from 0 to ``distance_m``."""
    from skymodel.render.rays import altitude_along

    R = prof.planet_radius_m
    p = np.array([0.0, 0.0, R + observer_m])
    ds = distance_m / n
    s = (np.arange(n) + 0.5) * ds
    h = altitude_along(p[None], direction[None], s[None], R)[0]
    x = p + s[:, None] * direction
    up = x / np.linalg.norm(x, axis=1, keepdims=True)
    med = prof.sample(np.maximum(h, 0.0))
    ext = med.extinction
    tau = np.cumsum(ext * ds, axis=0) - 0.5 * ext * ds
    t_sun = marcher.sun_table.transmittance(h, up @ marcher.sun, which=0)
    cos_t = float(direction @ marcher.sun)
    scat = med.rayleigh_scattering * prof.rayleigh_phase(np.array(cos_t))
    pa = prof.aerosol_phase_at(np.array(cos_t))
    for r in range(med.aerosol_scattering_by_regime.shape[0]):
        scat = scat + med.aerosol_scattering_by_regime[r] * pa[r]
    path = prof.solar_irradiance * (np.exp(-tau) * t_sun * scat * ds).sum(axis=0)
    return np.exp(-(ext * ds).sum(axis=0)), path, float(h[-1])


def _aerial(distances_km, samples, layers, albedo=0.5, half_angle_deg=2.0):
    """A grey square at each distance, north of the camera (the sun in the south lights its
    face), centred on the horizontal line of sight; environment vs volumetric vs marcher."""
    import bpy

    from blender_addon import physics, volumetric
    from blender_addon import render as headless
    from skymodel.render.marcher import MarchSettings, SkyMarcher

    el, az = 30.0, 180.0
    cam_h = 1.7
    rows = []
    plan = physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=el, sun_azimuth_deg=az,
                                             albedo=0.0, mode="VOLUMETRIC", n_layers=layers))
    vol = volumetric.volume_layers(plan, layers)
    prof = volumetric.rgb_model_profile(vol)
    marcher = SkyMarcher(prof, el, az, cam_h, MarchSettings(orders=1, exact=True, view_steps=512))
    view = np.array([0.0, math.cos(math.radians(0.5)), math.sin(math.radians(0.5))])  # the rows averaged
    sky_behind = marcher.radiance(view[None]).radiance[0]  # single scattering, to the end of the air
    normal = np.array([0.0, -1.0, 0.0])
    # single-scattered sky light on the object's face (with volume_bounces = 0 Cycles still
    # lights a surface with light scattered once in the air along its diffuse rays): the
    # marcher's radiance over a 128x64 grid of directions, cosine-weighted on the face's side
    from skymodel.render.cameras import make_camera

    grid = make_camera("equirectangular", 128)
    gdirs, gvalid = grid.directions()
    gcos = np.maximum(gdirs @ normal, 0.0) * gvalid
    pick = gcos > 0
    e_sky = (marcher.radiance(gdirs[pick]).radiance
             * (gcos * grid.pixel_solid_angles())[pick][:, None]).sum(axis=0)
    for mode in ("environment", "volumetric"):
        for d_km in distances_km:
            d = d_km * 1000.0
            bpy.ops.wm.read_factory_settings(use_empty=True)
            headless._ensure_registered()
            o = headless.parse_args(["--location", "rural", "--month", "6", "--sun-elevation", str(el),
                                     "--sun-azimuth", str(az), "--mode", mode, "--layers", str(layers),
                                     "--volume-bounces", "0", "--samples", str(samples), "--size", "16x16",
                                     "--albedo", "0",
                                     "--camera-height", str(cam_h), "--out", os.path.join(tempfile.mkdtemp(), "x.png")])
            scene = headless.build_scene(o, progress=None)
            cam = scene.camera
            cam.data.type = "PERSP"
            cam.data.angle = math.radians(half_angle_deg)  # the square spans 2 x half_angle: fills the frame
            cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)  # look north, horizontally
            side = 2.0 * d * math.tan(math.radians(half_angle_deg))
            me = bpy.data.meshes.new("Target")
            me.from_pydata([(-side / 2, 0, -side / 2), (side / 2, 0, -side / 2), (side / 2, 0, side / 2),
                            (-side / 2, 0, side / 2)], [], [(0, 1, 2, 3)])
            mat = bpy.data.materials.new("Grey")
            nt = mat.node_tree
            nt.nodes.clear()
            bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
            bsdf.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
            nt.links.new(bsdf.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
            me.materials.append(mat)
            obj = bpy.data.objects.new("Target", me)
            obj.location = (0.0, d, cam_h)
            scene.collection.objects.link(obj)
            scene.cycles.pixel_filter_type = "BOX"
            scene.cycles.filter_width = 1.0
            t0 = time.perf_counter()
            img = headless.render_linear(scene).astype(float)
            t_render = time.perf_counter() - t0
            # rows above the image's centre line only (elevation 0.125-0.875 deg): below it the
            # near ground hides the object
            rgb = img[1:7, 4:12].reshape(-1, 3).mean(axis=0)
            row = {"mode": mode, "distance_km": d_km, "samples": samples, "render_s": round(t_render, 1),
                   "object_rgb": [round(float(v), 4) for v in rgb], "object_Y": round(float(rgb @ LUMA), 4)}
            if mode == "volumetric":
                t, path, h_obj = _line_of_sight(prof, marcher, view, d, cam_h)
                up_obj = np.array([0.0, d, prof.planet_radius_m + cam_h])
                up_obj /= np.linalg.norm(up_obj)
                e_obj = prof.solar_irradiance * marcher.sun_table.transmittance(
                    np.array([h_obj]), np.array([up_obj @ marcher.sun]))[0]
                surface = albedo / math.pi * (e_obj * max(float(normal @ marcher.sun), 0.0) + e_sky)
                model = (t * surface + path)[volumetric.TO_RGB]
                row.update({"marcher_rgb": [round(float(v), 4) for v in model],
                            "cycles_over_marcher_minus_1_pct": [round(float(v), 2) for v in 100 * (rgb / model - 1)],
                            "transmittance_rgb": [round(float(v), 4) for v in t[volumetric.TO_RGB]],
                            "path_share_Y": round(float((path[volumetric.TO_RGB] @ LUMA) / (model @ LUMA)), 3),
                            "contrast_vs_horizon_sky_Y": round(float(
                                (rgb @ LUMA) / (sky_behind[volumetric.TO_RGB] @ LUMA) - 1), 3)})
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def _issue_markdown(res) -> str:
    from common import git_revision

    lines = [f"Machine: {res['machine']}; revision {git_revision()}; {res['date']}. Wall-clock seconds on a 2-core "
             f"machine shared with other jobs (`nice -n 10`): treat them as upper bounds.", "",
             "Command:", "", f"    {res['command']}", "",
             _env_markdown(res["environment"], res["command"])]
    v = res["volumetric"]
    lines += ["", f"**Volumetric Cycles render, 256×128** (the cross-validation medium of "
              f"`tests/test_addon_crossval.py`: rural, June, sun 30°, no tropospheric aerosol, 2 layers, "
              f"single scattering; CPU; build {v[0]['build_s']:.1f} s; the marcher's image of the same RGB shells "
              f"took {v[0]['marcher_s']:.1f} s). Difference from the marcher per region (R, G, B; mean of two "
              f"seeds) with the 1σ Monte Carlo noise of that mean, and the per-pixel luminance rms (one seed, "
              f"noise-dominated):", "",
              "| samples | render time | zenith: Cycles/marcher − 1 (noise) | horizon band | sun side | per-pixel Y rms |",
              "|---|---|---|---|---|---|"]
    for r in v:
        cells = []
        for name in ("zenith", "horizon", "sun side"):
            g = r["regions"][name]
            cells.append(", ".join(f"{x:+.2f}" for x in g["cycles_over_marcher_minus_1_pct"])
                         + f" % (±{max(g['noise_1sigma_pct']):.2f} %)")
        lines.append(f"| {r['samples']} | {r['render_s']:.1f} s | " + " | ".join(cells)
                     + f" | {r['pixel_Y_rel_rms_pct']:.1f} % |")
    lines += ["", "**Environment vs volumetric: aerial perspective.** A grey (albedo 0.5) diffuse square "
              "north of the camera, centred on the horizontal line of sight, filling a 2° camera (16×16 px; the "
              "object's colour is the mean of the pixels 0.1–0.9° above the horizon, the marcher's line of sight "
              "0.5° up; "
              f"{res['aerial'][0]['samples']} samples, single scattering); rural aerosol, 8 layers, sun 30° in the "
              "south lighting its face, ground albedo 0. Environment mode lights the object with the sun lamp "
              "and the sky image (all orders of scattering) and has no air between the camera and the object; "
              "volumetric mode lights it with the sun through the shells and the light its diffuse rays pick "
              "up scattered once in the air, and has the shells in front of it. The marcher's prediction is "
              "`T(d) L_surface + L_path(d)` on the same RGB medium (sun and single-scattered sky light on the "
              "object's face, single-scattering path radiance). Contrast is object Y / horizon sky Y − 1 "
              "(sky: the marcher, single scattering).", "",
              "| distance | environment: object RGB | volumetric: object RGB | marcher RGB | Cycles/marcher − 1 | "
              "transmittance (G) | path share of Y | contrast (volumetric) | render time env / vol |",
              "|---|---|---|---|---|---|---|---|---|"]
    env = {r["distance_km"]: r for r in res["aerial"] if r["mode"] == "environment"}
    for r in (r for r in res["aerial"] if r["mode"] == "volumetric"):
        e = env[r["distance_km"]]
        fmt = lambda v: ", ".join(f"{x:.3f}" for x in v)  # noqa: E731
        lines.append(f"| {r['distance_km']:g} km | {fmt(e['object_rgb'])} | {fmt(r['object_rgb'])} | "
                     f"{fmt(r['marcher_rgb'])} | " + ", ".join(f"{x:+.1f}" for x in r["cycles_over_marcher_minus_1_pct"])
                     + f" % | {r['transmittance_rgb'][1]:.3f} | {r['path_share_Y']:.2f} | "
                     f"{r['contrast_vs_horizon_sky_Y']:+.2f} | {e['render_s']:.1f} s / {r['render_s']:.1f} s |")
    return "\n".join(lines)


def issue(args):
    import datetime as dt

    from common import command_line

    res = {"machine": machine(), "command": command_line(), "date": dt.date.today().isoformat()}
    res["environment"] = _env_build_times(args.qualities)
    res["volumetric"] = _volumetric_sweep(args.sweep_samples, 256)
    res["aerial"] = _aerial(args.distances, args.aerial_samples, 8)
    if args.write:
        from common import update_section

        update_section(str(ROOT / "docs" / "benchmarks.md"), "## Blender", _issue_markdown(res))
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["projection", "cycles", "timings", "crossval", "issue", "environment", "env-row"])
    ap.add_argument("--location", default="desert")
    ap.add_argument("--month", type=int, default=1)
    ap.add_argument("--elevations", type=lambda t: [float(v) for v in t.split(",")], default=[60.0, 20.0, 5.0, 1.0])
    ap.add_argument("--layers", type=int, default=8)
    ap.add_argument("--bounces", type=int, default=8)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--quality", default="final")
    ap.add_argument("--json", default=None, help="write the results here")
    ap.add_argument("--without-fixes", action="store_true", help="crossval: switch the add-on's two fixes off")
    ap.add_argument("--case-aerosol", default=None, help="crossval: tropospheric aerosol instead of the test's 'none'")
    ap.add_argument("--case-layers", type=int, default=None, help="crossval: layers instead of the test's 2")
    ap.add_argument("--case-samples", type=int, default=None, help="crossval: samples per seed instead of 16")
    ap.add_argument("--no-converged", action="store_true", help="crossval: skip the converged (4096-node) march")
    ap.add_argument("--qualities", type=lambda t: t.split(","), default=["preview", "final", "reference"])
    ap.add_argument("--sweep-samples", type=lambda t: [int(v) for v in t.split(",")], default=[16, 64, 256])
    ap.add_argument("--distances", type=lambda t: [float(v) for v in t.split(",")], default=[1.0, 10.0, 50.0])
    ap.add_argument("--aerial-samples", type=int, default=64)
    ap.add_argument("--write", action="store_true", help="issue, environment: update docs/benchmarks.md "
                    "(section Blender; environment: only its environment table)")
    args = ap.parse_args(argv)
    if args.what == "env-row":  # internal: one environment build in this fresh process, one JSON line
        print(json.dumps(_env_build_row(args.quality)), flush=True)
        return 0
    res = {"projection": projection, "cycles": cycles, "timings": timings, "crossval": crossval,
           "issue": issue, "environment": environment}[args.what](args)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
