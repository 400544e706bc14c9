"""Auto mode's predicted times against measured ones (issue 21): the environment's build at
several widths (``skymodel.planner.decisions.environment_build_time``) and the volume shells'
Cycles render of a frame (``volume_render_time``), on this machine.

    .venv/bin/python benchmarks/bench_blender_auto.py --widths 256 512 1024 2048 \\
        --volume-layers 8 16 --volume-size 64x32 --samples 32

One JSON line per case with predicted, measured and their ratio. The environment's predicted
time is the effect table's render time at the sun elevation (64x32, preview tables) plus
``ENV_SECONDS_PER_PIXEL`` per further pixel; it is measured here at ``preview`` quality
(accuracy table not used, as its time scale is the ``final`` preset's).
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


def environment(widths, elevation):
    from blender_addon import physics
    from skymodel.planner import decisions
    from skymodel.planner.tables import EFFECTS_PATH, _EffectTable, load_table

    t_table = _EffectTable(load_table(EFFECTS_PATH)).time("reference", elevation)  # x ENV_FIXED_PER_TABLE below
    # warm-up, not counted: the first render of a process loads the core's tables (the add-on pays it once a session)
    physics.render_environment(physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=elevation,
                                                                 image_width=64)), tempfile.mkdtemp())
    for w in widths:
        sky = physics.resolve(physics.SkyParams(location="rural", month=6, sun_elevation_deg=elevation,
                                                image_width=w, quality="preview"))
        t0 = time.perf_counter()
        physics.render_environment(sky, tempfile.mkdtemp(prefix="skymodel-bench-"))
        t = time.perf_counter() - t0
        p = decisions.environment_build_time(t_table, w)
        print(json.dumps({"kind": "environment", "width": w, "predicted_s": round(p, 2), "measured_s": round(t, 2),
                          "ratio": round(t / p, 2)}), flush=True)


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
    a = ap.parse_args(argv)
    if a.widths:
        environment(a.widths, a.sun_elevation)
    if a.volume_layers:
        volumetric(a.volume_layers, a.volume_size, a.samples, a.sun_elevation)


if __name__ == "__main__":
    main()
