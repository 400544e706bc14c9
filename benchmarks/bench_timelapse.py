"""A sequence of skies (issue #19): one shared multiple-scattering solve vs independent renders.

    .venv/bin/python benchmarks/bench_timelapse.py [--quality final] [--frames 24] \\
        [--independent 6] [--size 512x256] [--repeat 1] [--write]

The frames: Zaragoza, 2026-06-21 from 19:00 CEST every 10 minutes (24 frames: sun 27 deg
down to -11 deg), each as ``skymodel render --time`` makes it (the atmosphere of the UTC
date, the solar spectrum at the date's distance, the sun where it is), equirectangular at
``--size``. Two ways, in one run, on the same profiles:

* sequence: :func:`skymodel.render.sequence.render_frame` with one
  :class:`~skymodel.render.sequence.SolutionCache` (what ``skymodel timelapse`` does; one
  solve, then each frame marches its pixels);
* independent: :func:`skymodel.render.sky.render_sky` per frame (a solve each).

``--independent K`` renders only K of the frames independently, evenly spread, and
projects the N-frame time as the median per frame x N (stated as a projection); 0 = all.
Every independently rendered frame is compared with the sequence's frame (max |difference|,
it should be 0: the same arithmetic). Excludes image writing. Before anything is timed, one
untimed 16x8 ``preview`` render warms the process (:func:`warm_up`), so neither way pays the
one-time costs (about 4.6 s at ``final`` on 2026-11-26: the sequence's first frame 27.4 s against
22.8 s for each later independent render). ``--repeat R`` repeats the
whole comparison and reports medians. ``--write`` puts the table into docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from benchmarks.common import command_line, git_revision, machine, update_section  # noqa: E402


def frames(n: int):
    from skymodel.render import timeline

    last = 19 * 60 + 10 * (n - 1)
    return timeline.day_frames(41.65, -0.88, "2026-06-21", "19:00", f"{last // 60:02d}:{last % 60:02d}", "10min",
                               "Europe/Madrid")


def profiles(suns, wl):
    from dataclasses import replace

    from skymodel.optics.atmosphere import Atmosphere

    out, atm = [], {}
    for s in suns:
        if s.day_of_year not in atm:
            atm[s.day_of_year] = Atmosphere(location="zaragoza", month=s.month, day_of_year=s.day_of_year)
        p = atm[s.day_of_year].optical_profile(wl)
        out.append(replace(p, solar_irradiance=p.solar_irradiance / s.earth_sun_distance_au**2))
    return out


def warm_up(suns, wl) -> None:
    """One untimed tiny render before anything is timed: the process's one-time costs
    (tables loaded and cached on first use, first allocations) would otherwise be paid by
    whichever way runs first, the sequence. A 16x8 ``preview`` sky of the first frame's
    profile: other settings, so no solve is shared with either way timed after it."""
    from skymodel.render.cameras import make_camera
    from skymodel.render.sky import render_sky

    p = profiles(suns[:1], wl)[0]
    render_sky(p, make_camera("equirectangular", 16, 8, n_wavelengths=wl.size), suns[0].elevation_deg,
               suns[0].azimuth_deg, 0.0, "preview", solutions=False)


def run_once(args, suns, cam, wl):
    from skymodel.render.sequence import SolutionCache, render_frame
    from skymodel.render.sky import render_sky

    t0 = time.perf_counter()
    profs = profiles(suns, wl)
    cache = SolutionCache()
    seq, per_frame = [], []
    for s, p in zip(suns, profs):
        t = time.perf_counter()
        seq.append(render_frame(p, cam, s.elevation_deg, s.azimuth_deg, 0.0, args.quality, cache=cache).radiance)
        per_frame.append(time.perf_counter() - t)
    t_seq = time.perf_counter() - t0
    k = len(suns) if args.independent <= 0 else min(args.independent, len(suns))
    picks = sorted({int(round(i)) for i in np.linspace(0, len(suns) - 1, k)})
    alone, diff = [], 0.0
    for i in picks:
        t = time.perf_counter()
        p = profiles([suns[i]], wl)[0]
        img = render_sky(p, cam, suns[i].elevation_deg, suns[i].azimuth_deg, 0.0, args.quality,
                         solutions=False)  # a solve of its own (render_sky shares the process's by default)
        alone.append(time.perf_counter() - t)
        diff = max(diff, float(np.max(np.abs(img.radiance - seq[i]))))
    return {"sequence_s": t_seq, "first_frame_s": per_frame[0], "extra_frame_s": statistics.median(per_frame[1:]),
            "solve_s": cache.stats["solve_s"], "solves": cache.stats["solves"],
            "independent_per_frame_s": statistics.median(alone), "independent_measured": len(picks),
            "independent_total_s": sum(alone) if len(picks) == len(suns) else statistics.median(alone) * len(suns),
            "max_abs_difference": diff}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quality", default="final")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--independent", type=int, default=0)
    ap.add_argument("--size", default="512x256")
    ap.add_argument("--wavelength-step", type=float, default=None)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args(argv)

    from skymodel.render.cameras import make_camera
    from skymodel.render.quality import quality
    from skymodel.wavelengths import default_wavelengths

    w, h = (int(v) for v in args.size.split("x"))
    step = args.wavelength_step or quality(args.quality).wavelength_step_nm
    wl = default_wavelengths(step)
    cam = make_camera("equirectangular", w, h, n_wavelengths=wl.size)
    suns = frames(args.frames)
    warm_up(suns, wl)
    runs = []
    for r in range(args.repeat):
        runs.append(run_once(args, suns, cam, wl))
        print(f"run {r + 1}: {runs[-1]}", file=sys.stderr, flush=True)
    med = {k: statistics.median(run[k] for run in runs) for k in runs[0]}
    ratio = med["independent_total_s"] / med["sequence_s"]
    projected = med["independent_measured"] < args.frames
    load = os.getloadavg()[0]
    body = f"""Machine: {machine()}; revision {git_revision()}; {time.strftime('%Y-%m-%d')}; 1-min load average {load:.1f} at the end (a machine shared with other jobs: treat times as upper bounds).

Command:

    {command_line()}

{args.frames} frames of Zaragoza, 2026-06-21 from 19:00 CEST every 10 min (sun {suns[0].elevation_deg:.1f}° to {suns[-1].elevation_deg:.1f}°), {w}x{h} equirectangular, `{args.quality}`, {wl.size} wavelengths; the core's render only (no image files); median of {args.repeat} run(s).

| | sequence (one shared solve) | independent renders | independent / sequence |
|---|---|---|---|
| {args.frames} frames | {med['sequence_s']:.1f} s | {med['independent_total_s']:.1f} s{' (projected: median of ' + str(med['independent_measured']) + ' frames × ' + str(args.frames) + ')' if projected else ''} | **{ratio:.1f}x** |
| per frame | first {med['first_frame_s']:.1f} s (solve {med['solve_s']:.1f} s), then {med['extra_frame_s']:.2f} s each | {med['independent_per_frame_s']:.1f} s each | {med['independent_per_frame_s'] / med['extra_frame_s']:.1f}x per extra frame |

Solves in the sequence: {int(med['solves'])}. Largest |difference| between a sequence frame and the independent render of the same instant: {med['max_abs_difference']:.3g} W m⁻² sr⁻¹ nm⁻¹ (the same arithmetic on the same arrays).
"""
    print(body)
    if args.write:
        update_section(os.path.join(os.path.dirname(__file__), "..", "docs", "benchmarks.md"),
                       f"## Time-lapse: {args.quality}", body)


if __name__ == "__main__":
    main()
