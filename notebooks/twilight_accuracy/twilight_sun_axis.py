"""Twilight: the multiple-scattering field's sun-angle axis against the Monte Carlo
tracer (README.md beside it, "The sun-angle axis").

A Rayleigh sky (location ``rural``, month 6, no aerosol: no delta-M truncation and no
forward peak to blur the picture), sun at -4 degrees elevation, azimuth 180, six views,
450 and 650 nm. The marcher runs at the Monte Carlo comparison's converged settings with
the coarser tables of revision 7a3823a (``TABLES_7A3823A``: 32 altitudes, 32 x 12 table
nodes, the 12-degree delta-M cone)
with 24 to 192 sun nodes, reading the field between them log-linearly (the previous
form) or with the cubic in log J (now). The MC traces every order, and first single
scattering alone against the marcher's single scattering.

    nice -n 5 python notebooks/twilight_accuracy/twilight_sun_axis.py              # about 20 min
    nice -n 5 python notebooks/twilight_accuracy/twilight_sun_axis.py --mc-dir D   # keep / reuse the MC runs in D
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

from validate_montecarlo import CHUNK_PATHS, CONVERGED  # noqa: E402

from skymodel import Atmosphere  # noqa: E402
from skymodel.render import multiple_scattering as msm  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402

WAVELENGTHS_NM = (450.0, 650.0)
SUN_ELEVATION = -4.0
#: (view zenith deg, azimuth from the sun deg)
VIEWS = ((88.0, 0.0), (80.0, 0.0), (45.0, 0.0), (0.0, 0.0), (70.0, 90.0), (88.0, 180.0))
#: the Monte Carlo comparison's converged marcher with the tables of revision 7a3823a (its
#: *before* settings until revision 2d94d81)
TABLES_7A3823A = replace(CONVERGED, table_altitudes=32, table_mu=32, table_phi=12, delta_m_cutoff_deg=12.0,
                         delta_m_mild_cutoff_deg=0.0)
#: (sun-angle interpolation, table_mus)
ROWS = (("log-linear", 24), ("log-linear", 48), ("log-linear", 96), ("log-linear", 192), ("cubic in log", 24),
        ("cubic in log", 96))


def traced(prof, d, chunks, max_bounces, mc_dir):
    """Mean and standard error of ``chunks`` MC runs of CHUNK_PATHS paths (seeds 5000,
    5001, ...), stored in / read from ``mc_dir`` when given."""
    path = os.path.join(mc_dir, f"twilight_rayleigh_b{max_bounces}.npz") if mc_dir else None
    means, ses = [], []
    if path and os.path.exists(path):
        with np.load(path) as z:
            means, ses = list(z["means"]), list(z["ses"])
    while len(means) < chunks:
        r = trace_radiance(prof, d, SUN_ELEVATION, 180.0, n_paths=CHUNK_PATHS, seed=5000 + len(means),
                           max_bounces=max_bounces)
        means.append(r.radiance)
        ses.append(r.stderr)
        if path:
            os.makedirs(mc_dir, exist_ok=True)
            np.savez(path, means=np.array(means), ses=np.array(ses))
    means, ses = np.array(means[:chunks]), np.array(ses[:chunks])
    return means.mean(axis=0), np.sqrt((ses**2).sum(axis=0)) / chunks


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chunks", type=int, default=40, help=f"MC runs of {CHUNK_PATHS} paths (all orders)")
    ap.add_argument("--mc-dir", default=None)
    a = ap.parse_args(argv)
    prof = Atmosphere(location="rural", month=6, aerosol="none",
                      stratospheric_aod550=0.0).optical_profile(list(WAVELENGTHS_NM))
    d = direction_from_angles(np.array([v[0] for v in VIEWS]), 180.0 + np.array([v[1] for v in VIEWS]))
    lit = np.array([v != (88.0, 180.0) for v in VIEWS])  # 88/180 sees no single scattering (shadow)
    mc1, se1 = traced(prof, d, max(a.chunks // 2, 1), 1, a.mc_dir)
    m1 = SkyMarcher(prof, SUN_ELEVATION, 180.0, 0.0, replace(TABLES_7A3823A, orders=1)).radiance(d).radiance
    mc, se = traced(prof, d, a.chunks, 64, a.mc_dir)
    bands = " / ".join(f"{w:g}" for w in WAVELENGTHS_NM)
    views = [f"{z:g}/{r:g}" for z, r in VIEWS]
    print(f"single scattering, marcher / MC - 1 (%) at {bands} nm, per view (88/180 is in the shadow): "
          + "; ".join(f"{v} {100 * x[0]:+.1f} / {100 * x[1]:+.1f}"
                      for v, x, ok in zip(views, m1 / np.where(mc1 > 0, mc1, 1.0) - 1.0, lit) if ok)
          + f" ({max(a.chunks // 2, 1) * CHUNK_PATHS} paths)")
    print(f"all orders: MC {a.chunks * CHUNK_PATHS} paths; se (%) at {bands} nm: "
          + "; ".join(f"{v} {100 * x[0]:.1f} / {100 * x[1]:.1f}" for v, x in zip(views, se / mc)))
    print()
    print(f"| sun-angle interpolation | sun nodes | {' | '.join(views)} | marcher (s) |")
    print("|---|---|" + "---|" * len(views) + "---|")
    cubic, geometric = msm._sun_interp_cubic, msm._sun_interp
    try:
        for way, n_mus in ROWS:
            msm._sun_interp_cubic = cubic if way == "cubic in log" else (
                lambda lo, hi, slo, shi, dx, f, below: geometric(lo, hi, f, below))
            t = time.perf_counter()
            m = SkyMarcher(prof, SUN_ELEVATION, 180.0, 0.0, replace(TABLES_7A3823A, table_mus=n_mus)).radiance(d).radiance
            t = time.perf_counter() - t
            cells = " | ".join(f"{100 * x[0]:+.1f} / {100 * x[1]:+.1f}" for x in (m / mc - 1.0))
            print(f"| {way} | {n_mus} | {cells} | {t:.0f} |", flush=True)
    finally:
        msm._sun_interp_cubic = cubic


if __name__ == "__main__":
    main()
