"""Twilight in dust: is the marcher's deficit at the horizon toward a sun below it in
the forward peak, or in the multiple-scattering solver? (README.md beside
it, "It is not the forward peak").

Desert aerosol (month 6, its default AOD), 450 nm, sun at -4 degrees, four views toward
the sun. Marcher and Monte Carlo tracer see two media:

* *full*: the desert medium as it is;
* *no peak*: the same medium with the delta-M truncation at the marcher's 3-degree cone
  applied to the medium itself (aerosol scattering times 1 - f, the capped and
  renormalised phase function). The marcher's own truncation then removes nothing and
  its peak aureole is zero, so any difference from the MC is the solver's.

The marcher runs at the Monte Carlo comparison's converged settings (``CONVERGED`` in
benchmarks/validate_montecarlo.py), and on the medium without the peak also with finer
sun-angle tables and with the spherical transport for more orders.

    nice -n 5 python notebooks/twilight_accuracy/twilight_peak_or_solver.py        # about 25 min on 2 cores
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
from skymodel.render.medium import truncate_forward_peak  # noqa: E402
from skymodel.validation.delta_m_medium import delta_m_profile  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402

WAVELENGTH_NM = 450.0
SUN_ELEVATION = -4.0
#: (view zenith deg, azimuth from the sun deg)
VIEWS = ((88.0, 0.0), (80.0, 0.0), (45.0, 0.0), (0.0, 0.0))
#: marcher rows on the medium without the peak: (label, changes to CONVERGED)
SOLVER_ROWS = (("converged settings", {}), ("48 sun nodes (24)", dict(table_mus=48)),
               ("spherical transport of orders 1-3 (1-2)", dict(spherical_orders=3)),
               ("spherical transport of every order", dict(spherical_orders=CONVERGED.max_orders)),
               ("every order spherical, 48 sun nodes", dict(spherical_orders=CONVERGED.max_orders, table_mus=48)))


def media():
    prof = Atmosphere(location="desert", month=6).optical_profile([WAVELENGTH_NM])
    f, _ = truncate_forward_peak(prof.aerosol_phase_angles_deg, prof.aerosol_phase, CONVERGED.delta_m_cutoff_deg)
    return prof, delta_m_profile(prof, CONVERGED.delta_m_cutoff_deg), f


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=1_000_000, help="MC paths per view and medium")
    a = ap.parse_args(argv)
    prof, no_peak, f = media()
    d = direction_from_angles(np.array([v[0] for v in VIEWS]), 180.0 + np.array([v[1] for v in VIEWS]))
    views = [f"{z:g}/{r:g}" for z, r in VIEWS]
    mc = {}
    for name, p in (("full", prof), ("no peak", no_peak)):
        t = time.perf_counter()
        r = trace_radiance(p, d, SUN_ELEVATION, 180.0, n_paths=a.paths, seed=4242)
        mc[name] = (r.radiance[:, 0], r.stderr[:, 0])
        print(f"MC {name}: {a.paths} paths, se (%) " + ", ".join(
            f"{v} {100 * s / m:.1f}" for v, m, s in zip(views, *mc[name])) + f" ({time.perf_counter() - t:.0f} s)",
            flush=True)
    print(f"\npeak fraction cut by the {CONVERGED.delta_m_cutoff_deg:g}-degree cone at {WAVELENGTH_NM:g} nm: "
          f"tropospheric aerosol {f[0, 0]:.3f}; MC full / no peak - 1 (%): " + ", ".join(
              f"{v} {100 * (x / y - 1):+.1f}" for v, x, y in zip(views, mc["full"][0], mc["no peak"][0])))
    print(f"\n| medium | marcher | {' | '.join(views)} | marcher (s) |")
    print("|---|---|" + "---|" * len(views) + "---|")
    rows = [("full", "converged settings", {})] + [("no peak", label, kw) for label, kw in SOLVER_ROWS]
    for medium, label, kw in rows:
        t = time.perf_counter()
        m = SkyMarcher(prof if medium == "full" else no_peak, SUN_ELEVATION, 180.0, 0.0,
                       replace(CONVERGED, **kw)).radiance(d).radiance[:, 0]
        t = time.perf_counter() - t
        cells = " | ".join(f"{100 * (x / y - 1):+.1f}" for x, y in zip(m, mc[medium][0]))
        print(f"| {medium} | {label} | {cells} | {t:.0f} |", flush=True)


if __name__ == "__main__":
    main()
