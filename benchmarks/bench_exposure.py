"""The add-on's exposure at a low sun: display brightness and colour of the sky, before
(incident-light rule alone) and after (the incident rule capped by the sky meter,
:func:`skymodel.render.exposure.display_exposure`).

    .venv/bin/python benchmarks/bench_exposure.py [--elevations 30,5,0,-2,-4,-8] \\
        [--image docs/img/exposure_before_after.png]

For each sun elevation: Build Sky in environment mode (headless, rural, June, sun azimuth
180, quality preview) and a Cycles render of a 256x128 equirectangular panorama centred on the
sun (``blender_addon.render``, 16 samples), once at the incident rule's exposure ("before")
and once at the add-on's ("after"), through AgX to an 8-bit PNG. Over the sky pixels above
the horizon (the top half of the panorama): the mean of the largest display channel and the
mean HSV saturation ``(max - min) / max``. Prints a Markdown table; ``--image`` writes the
panoramas side by side (rows: elevations; left before, right after).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="skymodel-blender-user-"))
os.environ.setdefault("SKYMODEL_CACHE_DIR", tempfile.mkdtemp(prefix="skymodel-cache-"))

import bpy  # noqa: E402


def display_png(scene, path):
    """Render ``scene`` to an 8-bit PNG through its view transform; (H, W, 3) in [0, 1], row 0 on top."""
    from blender_addon.render import _render, read_rgb

    scene.render.image_settings.color_depth = "8"
    _render(scene, path, "PNG")
    return read_rgb(path)


def sky_metrics(png):
    """(mean largest channel, mean HSV saturation) of the top half (the sky above the horizon)."""
    sky = png[: png.shape[0] // 2]
    mx, mn = sky.max(axis=-1), sky.min(axis=-1)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-12), 0.0)
    return float(mx.mean()), float(sat.mean())


def measure(elevation, folder, samples=16, size=(256, 128)):
    from blender_addon import render

    o = render.parse_args(["--location", "rural", "--month", "6", "--sun-elevation", str(elevation),
                           "--mode", "environment", "--samples", str(samples), "--size", f"{size[0]}x{size[1]}",
                           "--out", os.path.join(folder, "x.png")])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = render.build_scene(o, progress=None)
    s = scene.world.skymodel
    from blender_addon import builder  # noqa: F401

    after_ev = scene.view_settings.exposure
    info = {}
    # the numbers the build used (its cached JSON): incident and sky meters
    import json
    import glob

    for meta in glob.glob(os.path.join(os.environ["SKYMODEL_CACHE_DIR"], "sky-*.json")):
        with open(meta) as f:
            m = json.load(f)
        if abs(m["result"]["sun_elevation_deg"] - elevation) < 1e-6 and m["info"].get("size") == "512x256":
            info = m["info"]
    before_ev = info.get("exposure_incident", after_ev)
    scene.view_settings.exposure = before_ev
    before = display_png(scene, os.path.join(folder, f"before_{elevation}.png"))
    scene.view_settings.exposure = after_ev
    after = display_png(scene, os.path.join(folder, f"after_{elevation}.png"))
    assert s.exposure_rule == "SKY"
    return {"elevation": elevation, "before_ev": before_ev, "after_ev": after_ev,
            "before": sky_metrics(before), "after": sky_metrics(after), "images": (before, after)}


def mosaic(rows, path):
    tiles = [np.concatenate([r["images"][0], np.ones((r["images"][0].shape[0], 4, 3)), r["images"][1]], axis=1)
             for r in rows]
    sep = np.ones((4, tiles[0].shape[1], 3))
    img = np.concatenate([x for t in tiles for x in (t, sep)][:-1], axis=0)
    h, w = img.shape[:2]
    out = bpy.data.images.new("mosaic", w, h, alpha=False)
    rgba = np.concatenate([img[::-1], np.ones((h, w, 1))], axis=-1).astype(np.float32)
    out.pixels.foreach_set(rgba.ravel())
    out.filepath_raw = os.path.abspath(path)
    out.file_format = "PNG"
    out.save()
    bpy.data.images.remove(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elevations", default="30,5,0,-2,-4,-8")
    ap.add_argument("--image", default=None)
    ap.add_argument("--samples", type=int, default=16)
    a = ap.parse_args(argv)
    import blender_addon

    if not hasattr(bpy.types.World, "skymodel"):
        blender_addon.register()
    folder = tempfile.mkdtemp(prefix="skymodel-exposure-")
    rows = [measure(float(e), folder, a.samples) for e in a.elevations.split(",")]
    print("| sun elevation | exposure before → after (EV) | sky max channel before → after | "
          "sky saturation before → after |")
    print("|---|---|---|---|")
    for r in rows:
        print(f"| {r['elevation']:g}° | {r['before_ev']:+.2f} → {r['after_ev']:+.2f} ({r['after_ev'] - r['before_ev']:+.2f}) "
              f"| {r['before'][0]:.2f} → {r['after'][0]:.2f} | {r['before'][1]:.2f} → {r['after'][1]:.2f} |")
    if a.image:
        mosaic(rows, a.image)
        print(f"wrote {a.image}")


if __name__ == "__main__":
    main()
