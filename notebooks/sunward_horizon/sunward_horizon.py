"""The sky 2 and 10 degrees above a setting sun in desert dust: the marcher against the
Monte Carlo tracer for several delta-M cone widths and table sizes (README.md beside
it).

Desert aerosol (month 6, its default AOD), sun at 0 degrees elevation, azimuth 180,
ground albedo 0 in both estimators, views 88/0 and 80/0 (zenith angle / azimuth from the
sun, degrees) at 450, 550, 650 and 750 nm. The marcher runs at the Monte Carlo
comparison's converged settings (benchmarks/validate_montecarlo.py) with the cone and
the zenith x azimuth table nodes of each row; the MC traces every order.

    nice -n 10 python notebooks/sunward_horizon/sunward_horizon.py            # prints the markdown table (about 15 min)
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

from validate_montecarlo import BANDS_NM, CONVERGED, SUN_AZIMUTH, profile_for  # noqa: E402

from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402

#: (cone in degrees, table_mu, table_phi)
ROWS = ((12.0, 32, 12), (12.0, 32, 48), (6.0, 32, 12), (3.0, 32, 12), (3.0, 64, 48), (2.0, 64, 48), (3.0, 96, 72))
VIEWS = ((88.0, 0.0), (80.0, 0.0))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=300_000, help="MC paths per direction and band")
    ap.add_argument("--seed", type=int, default=11)
    a = ap.parse_args(argv)
    prof = profile_for("desert", None)
    prof = replace(prof, ground_albedo=np.zeros_like(prof.ground_albedo))
    d = direction_from_angles(np.array([v[0] for v in VIEWS]), SUN_AZIMUTH + np.array([v[1] for v in VIEWS]))
    mc = trace_radiance(prof, d, 0.0, SUN_AZIMUTH, n_paths=a.paths, seed=a.seed)
    se = mc.stderr / mc.radiance
    print(f"MC: {a.paths} paths, {mc.time_s:.0f} s; relative se (%) "
          + "; ".join(f"{z:g}/{r:g}: " + " / ".join(f"{100 * x:.1f}" for x in row) for (z, r), row in zip(VIEWS, se)))
    print()
    print("| cone (deg) | tables zenith x azimuth | " + " | ".join(f"{z:g}/{r:g} (%)" for z, r in VIEWS) + " | marcher (s) |")
    print("|---|---|" + "---|" * len(VIEWS) + "---|")
    for cone, n_mu, n_phi in ROWS:
        s = replace(CONVERGED, delta_m_cutoff_deg=cone, table_mu=n_mu, table_phi=n_phi)
        t = time.perf_counter()
        m = SkyMarcher(prof, 0.0, SUN_AZIMUTH, 0.0, s).radiance(d).radiance
        t = time.perf_counter() - t
        rel = m / mc.radiance - 1.0
        cells = [" / ".join(f"{100 * x:+.1f}" for x in row) for row in rel]
        print(f"| {cone:g} | {n_mu} x {n_phi} | " + " | ".join(cells) + f" | {t:.0f} |", flush=True)
    print()
    print(f"bands: {' / '.join(f'{b:g}' for b in BANDS_NM)} nm")


if __name__ == "__main__":
    main()
