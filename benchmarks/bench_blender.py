"""Blender add-on: accuracy of the RGB volumetric approximation, and timings.

    python benchmarks/bench_blender.py projection [--location desert --elevations 60,20,5,1]
    python benchmarks/bench_blender.py cycles     [--size 128x64 --samples 256 --layers 8]
    python benchmarks/bench_blender.py timings

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


def _bpy_scene(location, month, elevation, mode, layers, bounces, width, samples, azimuth=180.0):
    import bpy

    import blender_addon
    from blender_addon import render as headless

    if not hasattr(bpy.types.World, "skymodel"):
        blender_addon.register()
    opts = headless.parse_args(["--location", location, "--month", str(month), "--sun-elevation", str(elevation),
                                "--sun-azimuth", str(azimuth), "--mode", mode, "--layers", str(layers),
                                "--volume-bounces", str(bounces), "--samples", str(samples),
                                "--size", f"{width}x{width // 2}", "--out", os.path.join(tempfile.mkdtemp(), "x.png")])
    t0 = time.perf_counter()
    scene = headless.build_scene(opts)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    rgb = headless.render_linear(scene)
    return rgb, t_build, time.perf_counter() - t0


def cycles(args):
    from blender_addon import volumetric
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky

    out = {"machine": machine(), "cases": []}
    for el in args.elevations:
        rgb_c, tb, tr = _bpy_scene(args.location, args.month, el, "volumetric", args.layers, args.bounces,
                                   args.width, args.samples)
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["projection", "cycles", "timings"])
    ap.add_argument("--location", default="desert")
    ap.add_argument("--month", type=int, default=1)
    ap.add_argument("--elevations", type=lambda t: [float(v) for v in t.split(",")], default=[60.0, 20.0, 5.0, 1.0])
    ap.add_argument("--layers", type=int, default=8)
    ap.add_argument("--bounces", type=int, default=8)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--quality", default="final")
    ap.add_argument("--json", default=None, help="write the results here")
    args = ap.parse_args(argv)
    res = {"projection": projection, "cycles": cycles, "timings": timings}[args.what](args)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
