"""The fixed per-atmosphere cost of a solve: ``solve_sky``'s tables (the sun table and the
peak paths' columns) and its multiple-scattering solve, per quality preset.

    python benchmarks/bench_solve_tables.py [--qualities preview,final] [--repeat 3] [--peak-paths 1,0]
                                            [--location rural|desert]

Solves ``Atmosphere(location="rural", month=6, aod550=0.2)`` (``--location desert``: AOD 0.5,
coarse dust, the 12-degree cone) on the default 81-wavelength grid
(:func:`skymodel.render.marcher.solve_sky`, nothing cached) ``--repeat`` times per preset and
per ``--peak-paths`` setting, alternated, after one solve not counted, and prints
each solve's ``timings`` (``tables_s``, ``multiple_scattering_s``) and the wall time, with
their medians. Only public names are used, so the same file measures an older revision
(put that revision's tree first on ``PYTHONPATH``) for a before/after in one session.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--qualities", default="preview,final")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--peak-paths", default="1", help="comma list of 1/0: MarchSettings.peak_paths")
    ap.add_argument("--location", default="rural", choices=("rural", "desert"),
                    help="the sky solved: rural AOD 0.2 or desert AOD 0.5 (June)")
    args = ap.parse_args(argv)

    import skymodel
    from skymodel import Atmosphere
    from skymodel.render.marcher import solve_sky
    from skymodel.render.quality import quality_settings

    aod = {"rural": 0.2, "desert": 0.5}[args.location]
    profile = Atmosphere(location=args.location, month=6, aod550=aod).optical_profile()
    print(f"skymodel from {skymodel.__file__}; {args.location} AOD {aod}; {profile.wavelengths_nm.size} wavelengths")
    for q in args.qualities.split(","):
        runs = {flag: [] for flag in args.peak_paths.split(",")}
        settings = {flag: replace(quality_settings(q), peak_paths=flag == "1") for flag in runs}
        solve_sky(profile, settings[next(iter(runs))])  # not counted: first touch of every table
        for _ in range(args.repeat):
            for flag, s in settings.items():
                t = time.perf_counter()
                sol = solve_sky(profile, s)
                runs[flag].append((sol.timings["tables_s"], sol.timings["multiple_scattering_s"],
                                   time.perf_counter() - t))
        for flag, rows in runs.items():
            med = [statistics.median(r[k] for r in rows) for k in range(3)]
            each = ", ".join(f"{r[0]:.2f}/{r[1]:.2f}/{r[2]:.2f}" for r in rows)
            print(f"{q} peak_paths={flag}: median tables {med[0]:.2f} s, solve {med[1]:.2f} s, "
                  f"wall {med[2]:.2f} s  (each tables/solve/wall: {each})")


if __name__ == "__main__":
    main()
