"""Auto mode's predicted times against measured ones (issues 21, 23): the environment's build
at several widths and the volume shells' Cycles render of a frame (``volume_render_time``), on
this machine.

    .venv/bin/python benchmarks/bench_blender_auto.py --widths 256 512 1024 2048 \\
        --volume-layers 8 16 --volume-size 64x32 --samples 32

One JSON line per case with predicted, measured and their ratio. The environment's
prediction is the planner's own (``Plan.predicted_environment_s``, what its angular-resolution
decision uses) for a sky-only scene at the sun elevation, tolerance ``--tolerance``: of the
build with every effect on (``everything``: ``physics.render_environment`` at the ``final``
quality, its 5 nm grid) and of the planned build (``planned``: the add-on's
``scene_description.params_from_plan``), each cold (a fresh cache folder: the
multiple-scattering solve included), alternated.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def environment(widths, elevation, tolerance=1.0):
    import dataclasses

    from blender_addon import physics, scene_description
    from skymodel.planner import SceneDescription, plan

    p = plan(SceneDescription(sun_elevation_deg=elevation, farthest_object_m=0.0, tolerance=tolerance))
    base = physics.SkyParams(location="rural", month=6, sun_elevation_deg=elevation, quality="final")
    # warm-up, not counted: the first render of a process loads the core's tables (the add-on pays it once a session)
    physics.render_environment(physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=elevation,
                                                                 image_width=64)), tempfile.mkdtemp())
    for w in widths:
        builds = {"everything": dataclasses.replace(base, image_width=w),
                  "planned": scene_description.params_from_plan(dataclasses.replace(base, image_width=w), p)}
        for name, params in builds.items():
            t0 = time.perf_counter()
            physics.render_environment(physics.resolve(params), tempfile.mkdtemp(prefix="skymodel-bench-"))
            t = time.perf_counter() - t0
            pred = p.predicted_environment_s(w, everything_on=name == "everything")
            print(json.dumps({"kind": "environment", "build": name, "width": w, "predicted_s": round(pred, 2),
                              "measured_s": round(t, 2), "ratio": round(t / pred, 2),
                              "load_1min": round(os.getloadavg()[0], 2)}), flush=True)


def volumetric(layers, size, samples, elevation):
    import bpy

    import blender_addon
    from blender_addon import render as headless
    from skymodel.planner import SceneDescription, decisions

    w, h = (int(v) for v in size.split("x"))
    for n in layers:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        if not hasattr(bpy.types.World, "skymodel"):
            blender_addon.register()
        o = headless.parse_args(["--location", "rural", "--month", "6", "--sun-elevation", str(elevation),
                                 "--mode", "volumetric", "--layers", str(n), "--samples", str(samples),
                                 "--size", size, "--out", os.path.join(tempfile.mkdtemp(), "x.png")])
        sc = headless.build_scene(o, progress=None)
        t0 = time.perf_counter()
        headless.render_linear(sc)
        t = time.perf_counter() - t0
        p = decisions.volume_render_time(SceneDescription(image_width=w, image_height=h, samples=samples), n)
        print(json.dumps({"kind": "volumetric", "layers": n, "size": size, "samples": samples,
                          "predicted_s": round(p, 2), "measured_s": round(t, 2), "ratio": round(t / p, 2)}),
              flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--widths", type=int, nargs="*", default=[256, 512, 1024, 2048])
    ap.add_argument("--volume-layers", type=int, nargs="*", default=[8, 16])
    ap.add_argument("--volume-size", default="64x32")
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--sun-elevation", type=float, default=10.0)
    ap.add_argument("--tolerance", type=float, default=1.0, help="the planned build's tolerance (dE2000)")
    a = ap.parse_args(argv)
    if a.widths:
        environment(a.widths, a.sun_elevation, a.tolerance)
    if a.volume_layers:
        volumetric(a.volume_layers, a.volume_size, a.samples, a.sun_elevation)


if __name__ == "__main__":
    main()
