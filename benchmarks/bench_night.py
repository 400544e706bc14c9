"""The night's cost (issue #24): a night frame, and a 24-hour sequence against its daytime part.

    nice -n 5 .venv/bin/python benchmarks/bench_night.py [--quality preview] [--frames 96] \\
        [--size 512x256] [--date 2026-01-03] [--write]

Zaragoza, ``--date`` (default 2026-01-03: a full moon up all night) from 00:00 UTC, ``--frames``
frames evenly over 24 hours (96: every 15 minutes), through ``skymodel timelapse`` itself
(in-process, ``--no-video``; the frames' EXR, PNG and the contact sheet written as a user gets
them) at ``--size`` and ``--quality``, ``--night auto``. Then the same sequence restricted to
daytime: the frames with the sun at or above 0 deg, as one ``skymodel timelapse --night off``
over that span (what the command did before the night existed). Per-frame times come from
frames.json's ``render_s`` (the render of a frame; the first frame of each atmosphere also pays
its multiple-scattering solve), grouped by what the frame holds: day (sun >= 0), twilight (sun
-18..0: sunlit sky plus the night's light), night with the moonlit sky, night without it.
Also one ``skymodel render`` of a moonlit night frame alone (its solve included) and one of a
moonless one. Prints Markdown; ``--write`` puts it into docs/benchmarks.md under
"## The night".
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import command_line, git_revision, machine, update_section  # noqa: E402


def run(argv) -> float:
    from skymodel.cli.main import main

    t0 = time.perf_counter()
    rc = main(argv)
    if rc != 0:
        raise SystemExit(f"failed ({rc}): {' '.join(argv)}")
    return time.perf_counter() - t0


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quality", default="preview")
    ap.add_argument("--frames", type=int, default=96)
    ap.add_argument("--size", default="512x256")
    ap.add_argument("--date", default="2026-01-03")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args(argv)
    step_min = 24 * 60 // args.frames
    last = step_min * (args.frames - 1)
    common = ["--location", "zaragoza", "--size", args.size, "--quality", args.quality, "--quiet", "--timezone", "UTC"]
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "day24"
        wall24 = run(["timelapse", *common, "--no-video", "--date", args.date, "--from", "00:00", "--to",
                      f"{last // 60:02d}:{last % 60:02d}", "--every", f"{step_min}min", "--out", str(out)])
        frames = json.loads((out / "frames.json").read_text())["frames"]
        groups = {"day (sun >= 0)": [], "twilight (sun -18..0)": [], "night, moonlit sky": [],
                  "night, no moonlit sky": []}
        for f in frames[1:]:  # the first frame pays the solve
            el = f["sun_elevation_deg"]
            key = ("day (sun >= 0)" if el >= 0 else "twilight (sun -18..0)" if el >= -18 else
                   "night, moonlit sky" if f["night"]["moonlit_sky"] else "night, no moonlit sky")
            groups[key].append(f["render_s"])
        day = [f for f in frames if f["sun_elevation_deg"] >= 0]
        t_from, t_to = day[0]["time_utc"][11:16], day[-1]["time_utc"][11:16]
        out_day = Path(tmp) / "daytime"
        wall_day = run(["timelapse", *common, "--no-video", "--date", args.date, "--from", t_from, "--to", t_to, "--every",
                        f"{step_min}min", "--night", "off", "--out", str(out_day)])
        day_frames = json.loads((out_day / "frames.json").read_text())["frames"]
        day_off = [f["render_s"] for f in day_frames[1:]]
        moonlit_t = next((f["time_utc"] for f in frames if f["sun_elevation_deg"] < -18 and f["night"]["moonlit_sky"]),
                         None)
        single = {}
        for name, t in (("moonlit night frame", moonlit_t), ("moonless night frame", "2026-01-18T23:00:00Z")):
            if t is None:
                continue
            from skymodel.render import sky  # a fresh process's cache: its solve is paid here

            sky._SHARED.clear()
            single[name] = run(["render", *common[:-2], "--time", t, "--out", str(Path(tmp) / "one.exr")])
    lines = [f"Machine: {machine()}; revision {git_revision()}; load average before {load[0]:.1f}. Command: "
             f"`{command_line()}`.", "",
             f"Zaragoza, {args.date} from 00:00 UTC, {len(frames)} frames every {step_min} min, {args.size} "
             f"{args.quality}, `skymodel timelapse` in-process (EXR + PNG + contact sheet, no video).", "",
             "| sequence | frames | wall time | per frame |", "|---|---|---|---|",
             f"| 24 hours, `--night auto` | {len(frames)} | {wall24:.0f} s | {wall24 / len(frames):.2f} s |",
             f"| its daytime ({t_from}-{t_to} UTC), `--night off` | {len(day_frames)} | {wall_day:.0f} s | "
             f"{wall_day / len(day_frames):.2f} s |", "",
             "Median `render_s` per frame in the 24-hour sequence (first frame left out: it pays the solve):", "",
             "| frames | count | median render_s |", "|---|---|---|"]
    for k, v in groups.items():
        lines.append(f"| {k} | {len(v)} | {median(v):.2f} s |")
    lines.append(f"| daytime sequence, `--night off` | {len(day_off)} | {median(day_off):.2f} s |")
    lines += ["", "One `skymodel render --time` alone (its solve included when the moonlit sky needs one):", "",
              "| frame | wall time |", "|---|---|"]
    lines += [f"| {k} | {v:.1f} s |" for k, v in single.items()]
    body = "\n".join(lines)
    print(body)
    if args.write:
        path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "benchmarks.md")
        update_section(path, f"## The night: {args.quality}", body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
