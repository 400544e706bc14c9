"""The per-sun cost of a sky whose multiple-scattering solution is reused (issues #19, #23).

    python benchmarks/bench_warm_march.py [--quality final] [--suns 30,20,5,-4] [--threads 1,2] [--profile]

Solves the default atmosphere once (:func:`skymodel.render.marcher.solve_sky`, 81
wavelengths at ``final``), then builds ``SkyMarcher(profile, sun, 180, settings=...,
solution=...)`` (what every new sun position of a sequence or a sun-only rebuild costs: the
direction grid, marched at the frame's sun) at each sun, with
``skymodel.render.marcher.MARCH_THREADS`` set to each ``--threads``; prints the wall and
CPU seconds of each build and their medians. ``--profile``: a cProfile of one more
single-threaded build (sun 20 degrees), by internal time.

Only public names are used, so the same file measures an older revision (run it with that
revision's tree first on ``PYTHONPATH``) for a before/after in one session.
"""

from __future__ import annotations

import argparse
import statistics
import time


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quality", default="final")
    ap.add_argument("--suns", default="30,20,5,-4")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args(argv)

    import skymodel.render.marcher as marcher
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.render.quality import QUALITIES, quality_settings
    from skymodel.wavelengths import default_wavelengths

    s = quality_settings(args.quality)
    wl = default_wavelengths(QUALITIES[args.quality].wavelength_step_nm)
    prof = Atmosphere().optical_profile(wl)
    t = time.perf_counter()
    sol = marcher.solve_sky(prof, s)
    print(f"solve_sky ({args.quality}, {wl.size} wavelengths): {time.perf_counter() - t:.1f} s")
    suns = [float(x) for x in args.suns.split(",")]
    marcher.SkyMarcher(prof, suns[0], 180.0, settings=s, solution=sol)  # warm-up (lazy tables)
    for n in (int(x) for x in args.threads.split(",")):
        marcher.MARCH_THREADS = n
        walls, cpus = [], []
        for sun in suns:
            t, c = time.perf_counter(), time.process_time()
            marcher.SkyMarcher(prof, sun, 180.0, settings=s, solution=sol)
            walls.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
            print(f"  threads {n}, sun {sun:g}: wall {walls[-1]:.2f} s, cpu {cpus[-1]:.2f} s", flush=True)
        print(f"threads {n}: median wall {statistics.median(walls):.2f} s, median cpu {statistics.median(cpus):.2f} s")
    if args.profile:
        import cProfile
        import pstats

        marcher.MARCH_THREADS = 1
        pr = cProfile.Profile()
        pr.runcall(marcher.SkyMarcher, prof, 20.0, 180.0, settings=s, solution=sol)
        pstats.Stats(pr).sort_stats("tottime").print_stats(16)
    return 0


if __name__ == "__main__":
    main()
