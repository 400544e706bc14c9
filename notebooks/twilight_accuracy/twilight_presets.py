"""Twilight in dust at the quality presets' settings: how far the presets are from the
Monte Carlo tracer at the horizon toward a sun below it, and what every order of
spherical transport with 48 sun nodes (the comparison's ``CONVERGED_TWILIGHT``) changes
there (README.md beside it, "The presets at twilight").

The scenes, views and bands of benchmarks/validate_montecarlo.py at sun -4 degrees, its
MC runs (stored by ``validate_montecarlo.py --mc-dir DIR``, read here from the same DIR;
traced here with ``--paths`` paths where absent). Each preset is marched at the views
directly (the image's direction grid and all), as it is and with
``spherical_orders=20, table_mus=48``.

    nice -n 5 python notebooks/twilight_accuracy/twilight_presets.py --mc-dir DIR    # minutes with stored MC runs
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace

import numpy as np

#: the Monte Carlo comparison's settings and helpers live in benchmarks/validate_montecarlo.py
_BENCHMARKS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "benchmarks")
sys.path.insert(0, _BENCHMARKS)

from common import git_revision  # noqa: E402
from validate_montecarlo import (AEROSOLS, CONVERGED_TWILIGHT, SUN_AZIMUTH, VIEWS, profile_for,  # noqa: E402
                                 trace_scene_mc, view_directions)

from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.sky import QUALITY  # noqa: E402

SUN_ELEVATION = -4.0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mc-dir", default=None, help="validate_montecarlo.py's stored MC runs")
    ap.add_argument("--paths", type=int, default=3_000_000, help="MC paths per view and band where none is stored")
    a = ap.parse_args(argv)
    d = view_directions()
    views = [f"{z:g}/{r:g}" for z, r in VIEWS]
    print(f"revision {git_revision()}; sun {SUN_ELEVATION:g} deg; marcher / MC - 1 (%), mean over the bands "
          f"(450 nm in brackets)\n")
    print("| aerosol | preset | " + " | ".join(views) + " | median abs | marcher (s) |")
    print("|---|---|" + "---|" * len(views) + "---|---|")
    for k, (aerosol, aod) in enumerate(AEROSOLS):
        prof = profile_for(aerosol, aod)
        mc, se, paths, _ = trace_scene_mc(prof, aerosol, SUN_ELEVATION, a.paths, 100 + k, a.mc_dir)
        for name in ("preview", "final", "reference"):
            for label, s in ((name, QUALITY[name]),
                             (f"{name}, every order, {CONVERGED_TWILIGHT.table_mus} sun nodes",
                              replace(QUALITY[name], spherical_orders=CONVERGED_TWILIGHT.spherical_orders,
                                      table_mus=CONVERGED_TWILIGHT.table_mus))):
                t = time.perf_counter()
                m = SkyMarcher(prof, SUN_ELEVATION, SUN_AZIMUTH, 0.0, s).radiance(d).radiance
                secs = time.perf_counter() - t
                rel = m / mc - 1.0
                cells = [f"{100 * r.mean():+.1f} ({100 * r[0]:+.1f})" for r in rel]
                print(f"| {aerosol} | {label} | " + " | ".join(cells) + f" | {100 * np.median(np.abs(rel)):.1f} | "
                      f"{secs:.0f} |", flush=True)
        print(f"| {aerosol} | MC se (%) | " + " | ".join(f"{100 * x.mean():.1f}" for x in se / mc) + f" | {paths} paths | |")


if __name__ == "__main__":
    main()
