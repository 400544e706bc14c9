"""Large environment maps and sun-only rebuilds (issue #23): what the sky-view table costs
and how far it is from direct marching.

    python benchmarks/bench_skyview.py error   [--size 512] [--quality preview]
    python benchmarks/bench_skyview.py sizes   [--sizes 512,1024,2048,4096] [--qualities final]
    python benchmarks/bench_skyview.py warm    [--quality final] [--size 1024]
    python benchmarks/bench_skyview.py blender [--sizes 512,1024,2048,4096]

* ``error``: the table (``method="table"``) against direct marching of every pixel
  (``method="direct"``) of one equirectangular image in CIE XYZ, outside the sun disc
  (0.3 degrees): mean and max of |table / direct - 1| over pixels and channels, in the
  8-degree sun cap and everywhere, for rural and desert skies at several suns.
* ``sizes``: ``skymodel render --camera equirectangular --size WxH --quality Q`` in a child
  process each (cold: imports, solve, march, EXR and PNG), wall time and peak resident
  memory (GNU time's %M).
* ``warm``: :func:`skymodel.render.environment.render_environment` (the add-on's build) at
  sun 30, then 25 and 20 degrees (``--suns``): the first solves, the next reuse the solution;
  ``--sun-exact-deg`` replaces the preset's sun cap (to time its cost).
* ``blender``: Blender 5.0's Sky Texture (Multiple Scattering) rendered to an equirectangular
  image of the same size with Cycles at 1 sample (``skymodel.models.blender_sky``, a child
  process with ``bpy``), wall time.

Results are printed as Markdown rows (docs/benchmarks.md, "Large environment maps").
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = (("rural", 30.0), ("rural", 3.0), ("rural", 1.0), ("rural", -4.0), ("urban", 4.0), ("desert", 60.0), ("desert", 20.0),
          ("desert", 5.0), ("desert", 0.0))


def cmd_error(args):
    from skymodel import Atmosphere
    from skymodel.render.cameras import make_camera
    from skymodel.render.marcher import solve_sky
    from skymodel.render.quality import quality_settings
    from skymodel.render.rays import sun_direction
    from skymodel.render.sky import render_sky_reduced
    from skymodel.render.skyview import xyz_reduction
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(args.step)
    s = quality_settings(args.quality)
    cam = make_camera("equirectangular", args.size, n_wavelengths=3)
    dirs, valid = cam.directions()
    red = xyz_reduction(wl)
    solutions = {}
    print("| scene | pixels in the cap | marched exactly | mean all (%) | max all (%) | mean cap (%) | max cap (%) "
          "| table s | direct s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for aerosol, sun in SCENES:
        prof = Atmosphere(location=aerosol, month=6).optical_profile(wl)
        if aerosol not in solutions:
            solutions[aerosol] = solve_sky(prof, s)
        out, secs, info = {}, {}, {}
        for m in ("table", "direct"):
            t = time.perf_counter()
            out[m], _, info[m] = render_sky_reduced(prof, cam, sun, red, 3, 180.0, 0.0, s, solution=solutions[aerosol],
                                                    method=m, band_pixels=1 << 20)
            secs[m] = time.perf_counter() - t
        gam = np.degrees(np.arccos(np.clip(dirs @ sun_direction(sun, 180.0), -1, 1)))
        keep = valid & (gam > 0.3) & np.all(out["direct"] > 0, axis=-1)
        rel = np.abs(out["table"][keep] / out["direct"][keep] - 1.0)
        cap = (gam < s.sun_exact_deg)[keep]
        print(f"| {aerosol} sun {sun:g} | {int(cap.sum())} | {info['table'].get('table_exact_pixels')} "
              f"| {100 * rel.mean():.5f} | {100 * rel.max():.3f} | {100 * rel[cap].mean():.4f} "
              f"| {100 * rel[cap].max():.3f} | {secs['table']:.1f} | {secs['direct']:.1f} |", flush=True)


def cmd_sizes(args):
    print("| size | quality | wall s | peak memory (GiB) |")
    print("|---|---|---|---|")
    exe = os.path.join(os.path.dirname(sys.executable), "skymodel")
    with tempfile.TemporaryDirectory() as tmp:
        for q in args.qualities.split(","):
            for w in (int(x) for x in args.sizes.split(",")):
                cmd = ["/usr/bin/time", "-f", "%e %M", exe, "render", "--camera", "equirectangular", "--size",
                       f"{w}x{w // 2}", "--quality", q, "--out", os.path.join(tmp, "sky.exr"), "--quiet"]
                p = subprocess.run(cmd, capture_output=True, text=True)
                if p.returncode != 0:
                    print(f"| {w}x{w // 2} | {q} | failed: {p.stderr.strip().splitlines()[-1:]} | |", flush=True)
                    continue
                wall, kb = p.stderr.strip().splitlines()[-1].split()
                print(f"| {w}x{w // 2} | {q} | {float(wall):.1f} | {int(kb) / 2**20:.2f} |", flush=True)


def cmd_warm(args):
    from skymodel import Atmosphere
    from skymodel.render.environment import render_environment

    if args.sun_exact_deg is not None:  # the preset with another sun cap (a study, not a user knob)
        from dataclasses import replace

        from skymodel.render import quality as q

        preset = q.QUALITIES[args.quality]
        q.QUALITIES[args.quality] = replace(preset, settings=replace(preset.settings,
                                                                      sun_exact_deg=args.sun_exact_deg))
    atm = Atmosphere(location="rural", month=6)
    with tempfile.TemporaryDirectory() as tmp:
        print("| build | quality | size | sun (deg) | wall s | solve s | method |")
        print("|---|---|---|---|---|---|---|")
        for k, sun in enumerate(float(x) for x in args.suns.split(",")):
            t = time.perf_counter()
            _, env = render_environment(atm, sun, 180.0, quality=args.quality, width=args.size, cache_dir=tmp)
            print(f"| {'cold' if k == 0 else 'sun only'} | {args.quality} | {args.size}x{args.size // 2} | {sun:g} "
                  f"| {time.perf_counter() - t:.1f} | {env.info.get('solution_s')} | {env.info.get('method')} |",
                  flush=True)


def cmd_blender(args):
    from skymodel.models.blender_sky import bpy_available, render_equirectangular

    if not bpy_available():
        print("bpy is not installed: skipped")
        return
    print("| size | Blender Sky Texture (Multiple Scattering), wall s |")
    print("|---|---|")
    for w in (int(x) for x in args.sizes.split(",")):
        t = time.perf_counter()
        img = render_equirectangular("MULTIPLE_SCATTERING", 30.0, w, timeout_s=1800)
        print(f"| {img.shape[1]}x{img.shape[0]} | {time.perf_counter() - t:.1f} |", flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("what", choices=("error", "sizes", "warm", "blender"))
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--sizes", default="512,1024,2048,4096")
    p.add_argument("--quality", default="preview")
    p.add_argument("--qualities", default="final")
    p.add_argument("--step", type=float, default=10.0, help="wavelength step, nm (error)")
    p.add_argument("--suns", default="30,25,20", help="warm: sun elevations, deg (the first solves)")
    p.add_argument("--sun-exact-deg", type=float, default=None, help="warm: the preset's sun cap, deg")
    args = p.parse_args(argv)
    {"error": cmd_error, "sizes": cmd_sizes, "warm": cmd_warm, "blender": cmd_blender}[args.what](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
