"""Latency of the Blender panel's Live Update (blender_addon/live.py), headless.

A "drag" is ``--changes`` sun-elevation changes ``--interval`` s apart (real time, through
the settings' update callbacks, as the UI does); then the live update's timer body
(``live.tick``) is called every 20 ms, as Blender's timer would, until it is idle. Reported
per drag: seconds from the last change to the preview sky shown in the scene, and to the
chosen quality shown; the longest single tick (main-thread time: reading the settings,
loading and packing the image, the scene update) and the builds made. The first drag
includes the multiple-scattering solve (cold); later drags reuse it (warm: only the sun moved).

    .venv/bin/python benchmarks/bench_blender_live.py --quality final --drags 3
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
import time


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quality", default="final", help="the panel's quality (the final stage)")
    ap.add_argument("--width", type=int, default=0, help="the panel's image width (0: the quality's)")
    ap.add_argument("--location", default="rural")
    ap.add_argument("--drags", type=int, default=3)
    ap.add_argument("--changes", type=int, default=5, help="changes per drag")
    ap.add_argument("--interval", type=float, default=0.05, help="seconds between the changes of a drag")
    ap.add_argument("--interrupt", action="store_true",
                    help="in every drag after the first, change the sun again 2 s into the final build "
                         "(the latency is then from that change)")
    ap.add_argument("--long-drag", type=float, default=0.0, metavar="SECONDS",
                    help="after the drags, one continuous drag: a change every --interval s for SECONDS "
                         "(ticking meanwhile); reports the previews shown during it and how old their values were")
    args = ap.parse_args(argv)

    os.environ.setdefault("SKYMODEL_CACHE_DIR", tempfile.mkdtemp(prefix="skymodel-live-bench-"))
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="skymodel-live-user-"))
    import bpy

    import blender_addon
    from blender_addon import live

    blender_addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.world = bpy.data.worlds.new("World")
    s = sc.world.skymodel
    s.location, s.quality, s.image_width = args.location, args.quality, args.width
    s.live_update = True
    live.stop()  # only the drags count
    rows = []
    elevation = 20.0
    for drag in range(args.drags):
        for _ in range(args.changes):
            elevation += 0.7
            s.sun_elevation = math.radians(elevation)
            time.sleep(args.interval)
        longest, interrupted = 0.0, not (args.interrupt and drag > 0)
        final_started = None
        while True:
            t0 = time.perf_counter()
            interval = live.tick()
            longest = max(longest, time.perf_counter() - t0)
            if interval is None:
                break
            job = live.STATE.job
            if not interrupted and job is not None and job.stage == "final" and job.running:
                final_started = final_started or time.perf_counter()
                if time.perf_counter() - final_started > 2.0:
                    elevation += 0.7
                    s.sun_elevation = math.radians(elevation)
                    live.STATE.latency.clear()
                    interrupted = True
                    print(f"  changed again 2 s into the {args.quality} build", flush=True)
            time.sleep(0.02)
        t_last = live.STATE.changed_at
        lat = dict(live.STATE.latency)
        rows.append((drag, lat.get("preview"), lat.get("final"), longest, dict(live.STATE.builds)))
        live.STATE.latency.clear()
        print(f"drag {drag + 1}: preview shown {lat.get('preview', float('nan')):.2f} s after the last change, "
              f"{args.quality} {lat.get('final', float('nan')):.2f} s; longest tick {1000 * longest:.0f} ms; "
              f"builds so far {live.STATE.builds}", flush=True)
        assert live.STATE.changed_at == t_last
    if args.long_drag > 0:
        changed = {}  # generation -> time of its change
        shown_at = []  # (time shown, generation)
        seen = len(live.STATE.history)
        t_end = time.perf_counter() + args.long_drag
        next_change = time.perf_counter()
        while time.perf_counter() < t_end:
            now = time.perf_counter()
            if now >= next_change:
                elevation += 0.2
                s.sun_elevation = math.radians(elevation)
                changed[live.STATE.generation] = now
                next_change = now + args.interval
            live.tick()
            if len(live.STATE.history) > seen:
                shown_at.extend((time.perf_counter(), g) for g, _ in live.STATE.history[seen:])
                seen = len(live.STATE.history)
            time.sleep(0.02)
        ages = [t - changed[g] for t, g in shown_at if g in changed]
        print(f"long drag {args.long_drag:.0f} s ({len(changed)} changes): {len(shown_at)} previews shown during it"
              + (f", their values {min(ages):.2f}..{max(ages):.2f} s old when shown (median "
                 f"{statistics.median(ages):.2f} s)" if ages else ""), flush=True)
        while live.tick() is not None:
            time.sleep(0.02)
    warm = rows[1:]
    if warm:
        print(f"warm median: preview {statistics.median(r[1] for r in warm):.2f} s, "
              f"{args.quality} {statistics.median(r[2] for r in warm):.2f} s")
    blender_addon.unregister()


if __name__ == "__main__":
    main()
