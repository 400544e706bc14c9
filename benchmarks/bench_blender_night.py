"""The night in the add-on (issue 24), headless bpy: one night build (moonlit, moonless) and a
24-hour Bake Time of Day, with the numbers docs/blender.md "The night" quotes: build time, sun and
moon lamp, exposure, and the sky as shown (log-average luminance of the sky above the horizon x
2^exposure, in the colour scale: 1 = 683 cd/m2) per frame.

    PYTHONPATH=$PWD nice -n 5 .venv/bin/python benchmarks/bench_blender_night.py --width 128 --every 3h

``--sheet PATH``: instead, the headless day (``python -m blender_addon.render --date ...``, Cycles
frames of the baked sky) from 00:00 to 23:59 UTC every ``--every``, as one contact sheet PNG
(docs/img/blender_night_24h.png):

    PYTHONPATH=$PWD nice -n 5 .venv/bin/python benchmarks/bench_blender_night.py --every 2h \
        --sheet docs/img/blender_night_24h.png
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="skymodel-blender-user-"))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--location", default="rural")
    ap.add_argument("--date", default="2026-12-21")
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--every", default="3h")
    ap.add_argument("--quality", default="preview")
    ap.add_argument("--sheet", default=None, help="write the headless day's frames as a contact sheet PNG")
    a = ap.parse_args(argv)
    os.environ["SKYMODEL_CACHE_DIR"] = tempfile.mkdtemp(prefix="skymodel-night-bench-")
    if a.sheet:
        return sheet(a)
    import bpy
    import numpy as np

    import blender_addon
    from blender_addon import animation
    from skymodel.render import environment, exposure

    bpy.ops.wm.read_factory_settings(use_empty=True)
    blender_addon.register()
    sc = bpy.context.scene
    sc.world = bpy.data.worlds.new("World")
    s = sc.world.skymodel
    s.location, s.image_width, s.quality = a.location, a.width, a.quality
    s.sun_source, s.timezone, s.moon_lamp = "TIME", "UTC", True
    cam = environment.environment_camera(a.width)

    def shown(rgb):
        return exposure.sky_log_average(rgb, cam) * 2.0 ** sc.view_settings.exposure

    def image():
        img = next(n.image for n in sc.world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment")
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        return px.reshape(h, w, 4)[::-1, :, :3]

    y, m, d = (int(x) for x in a.date.split("-"))
    for label, hour in (("night 20:00Z", 20), ("night 02:00Z", 2), ("noon 12:00Z", 12)):
        s.year, s.month, s.day, s.hour, s.minute = y, m, d, hour, 0
        t0 = time.perf_counter()
        assert bpy.ops.skymodel.build_sky() == {"FINISHED"}
        dt = time.perf_counter() - t0
        lights = {o.name: o.data.energy for o in bpy.data.objects if o.type == "LIGHT"}
        print(f"{label}: build {dt:.1f} s, lamps {lights}, exposure {sc.view_settings.exposure:+.2f} EV, "
              f"sky shown {shown(image()):.4g}")
    t0 = time.perf_counter()
    frames = animation.animate_day(sc, s, a.date, "00:00", "23:59", a.every, "UTC")
    r = animation.bake(bpy.context, folder=tempfile.mkdtemp(prefix="skymodel-night-bake-"))
    print(f"bake: {r['frames']} frames in {time.perf_counter() - t0:.1f} s")
    rec = animation.bake_record(sc)
    for k, f in enumerate(frames, start=1):
        sc.frame_set(k)
        img = bpy.data.images.load(os.path.join(rec["folder"], rec["frames"][str(k)]["file"]), check_existing=False)
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        bpy.data.images.remove(img)
        rgb = px.reshape(h, w, 4)[::-1, :, :3]
        moon = rec["frames"][str(k)]["moon_strength"]
        print(f"  {f.time_utc[11:16]}Z sun {f.elevation_deg:6.1f}  exposure {sc.view_settings.exposure:+6.2f} EV  "
              f"sun lamp {rec['frames'][str(k)]['sun_strength']:.3g}  moon lamp {moon:.3g} ({683 * moon:.3g} lux)  "
              f"sky shown {shown(rgb):.4g}")


def sheet(a):
    import numpy as np
    from PIL import Image

    from blender_addon import render
    from skymodel.cli.timelapse import contact_sheet
    from skymodel.render import image_io

    out = tempfile.mkdtemp(prefix="skymodel-night-day-")
    t0 = time.perf_counter()
    rc = render.main(["--location", a.location, "--date", a.date, "--from", "00:00", "--to", "23:59", "--every",
                      a.every, "--timezone", "UTC", "--size", "128x64", "--samples", "16", "--image-width",
                      str(2 * a.width), "--quality", a.quality, "--out", out])
    assert rc == 0, rc
    frames = sorted(f for f in os.listdir(out) if f.startswith("frame_"))
    images = [np.asarray(Image.open(os.path.join(out, f)).convert("RGB")) for f in frames]
    image_io.write_png(a.sheet, contact_sheet(images))
    print(f"{len(frames)} frames in {time.perf_counter() - t0:.0f} s -> {a.sheet}")


if __name__ == "__main__":
    main()
