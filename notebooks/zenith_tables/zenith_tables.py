"""The zenith's multiple scattering against the Monte Carlo tracer as the solver's tables
grow (README.md beside it).

Rural aerosol at AOD 0.2 (month 6), sun at 20 degrees elevation, azimuth 180, ground
albedo 0 in both estimators, zenith view, 450 and 750 nm. The marcher runs at the Monte
Carlo comparison's settings (benchmarks/validate_montecarlo.py) with the delta-M cone,
zenith x azimuth nodes and altitude nodes of each row; the MC traces every order (and,
first, single scattering alone against the marcher's single scattering).

    nice -n 5 python notebooks/zenith_tables/zenith_tables.py      # prints the markdown table (about 15 min)
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

from validate_montecarlo import CONVERGED  # noqa: E402

from skymodel import Atmosphere  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402

WAVELENGTHS_NM = (450.0, 750.0)
SUN_ELEVATION = 20.0
#: (cone in degrees, table_mu, table_phi, table_altitudes)
ROWS = ((12.0, 32, 12, 32), (12.0, 64, 48, 32), (3.0, 64, 48, 32), (3.0, 64, 48, 48), (3.0, 96, 72, 32),
        (3.0, 96, 72, 48))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=400_000, help="MC paths per band")
    ap.add_argument("--seed", type=int, default=77)
    a = ap.parse_args(argv)
    prof = Atmosphere(location="rural", month=6, aod550=0.2).optical_profile(list(WAVELENGTHS_NM))
    prof = replace(prof, ground_albedo=np.zeros(len(WAVELENGTHS_NM)))
    d = direction_from_angles(np.array([0.0]), np.array([180.0]))
    first = replace(CONVERGED, table_mu=32, table_phi=12, table_altitudes=32, delta_m_cutoff_deg=12.0,
                    delta_m_mild_cutoff_deg=0.0, orders=1)
    mc1 = trace_radiance(prof, d, SUN_ELEVATION, 180.0, n_paths=a.paths, seed=a.seed, max_bounces=1)
    m1 = SkyMarcher(prof, SUN_ELEVATION, 180.0, 0.0, first).radiance(d).radiance
    mc = trace_radiance(prof, d, SUN_ELEVATION, 180.0, n_paths=a.paths, seed=a.seed)
    bands = " / ".join(f"{w:g}" for w in WAVELENGTHS_NM)
    print(f"single scattering, marcher / MC - 1 (%) at {bands} nm: "
          + " / ".join(f"{100 * x:+.2f}" for x in (m1 / mc1.radiance - 1.0)[0])
          + "; MC se " + " / ".join(f"{100 * x:.2f}" for x in (mc1.stderr / mc1.radiance)[0]))
    print(f"all orders: MC {a.paths} paths, se (%) " + " / ".join(f"{100 * x:.2f}" for x in (mc.stderr / mc.radiance)[0]))
    print()
    print(f"| cone (deg) | zenith x azimuth nodes | altitudes | zenith, marcher / MC - 1 at {bands} nm (%) | marcher (s) |")
    print("|---|---|---|---|---|")
    for cone, n_mu, n_phi, n_h in ROWS:
        s = replace(CONVERGED, delta_m_cutoff_deg=cone, table_mu=n_mu, table_phi=n_phi, table_altitudes=n_h)
        t = time.perf_counter()
        m = SkyMarcher(prof, SUN_ELEVATION, 180.0, 0.0, s).radiance(d).radiance
        t = time.perf_counter() - t
        cells = " / ".join(f"{100 * x:+.2f}" for x in (m / mc.radiance - 1.0)[0])
        print(f"| {cone:g} | {n_mu} x {n_phi} | {n_h} | {cells} | {t:.0f} |", flush=True)


if __name__ == "__main__":
    main()
