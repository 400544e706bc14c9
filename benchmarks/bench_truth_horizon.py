"""The near-horizon deficit of docs/accuracy.md ("One degree above the horizon over a bright
ground"): the marcher against the cached Monte Carlo truth of benchmarks/bench_truth.py on a
few views, one MarchSettings change at a time, and the same with the ground albedo at 0 in
both (a fresh MC run). Uses the MC's own 3-wavelength profile and every direction exact.

    nice -n 5 python benchmarks/bench_truth_horizon.py knobs desert:60 \\
        "table_altitudes=64,table_steps=192;spherical_orders=20;table_mu=64;view_steps=256;peak_aureole=0"
    nice -n 5 python benchmarks/bench_truth_horizon.py knobs desert:60 \\
        "delta_m_cutoff_deg=3,table_mu=64,table_phi=48;delta_m_cutoff_deg=30"
    nice -n 5 python benchmarks/bench_truth_horizon.py albedo0 desert:60 40000

Prints marcher / MC - 1 (%) at 450/550/650 nm per view. Run bench_truth.py mc first.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import bench_truth as b  # noqa: E402

from skymodel.validation.montecarlo import trace_radiance  # noqa: E402

VIEWS = [(89, 180), (89, 90), (88, 135), (88, 45), (85, 180), (0, 0)]


def _rows(sc, views):
    return [int(np.flatnonzero((np.abs(sc.views[:, 0] - z) < 1e-6) & (np.abs(sc.views[:, 1] - az) < 1e-6))[0])
            for z, az in views]


def _line(label, secs, rel):
    print(f"{label:45s} {secs:5.0f}s", " | ".join("/".join(f"{100 * x:+.1f}" for x in rr) for rr in rel), flush=True)


def main(argv):
    what, scene = argv[0], argv[1]
    a, e = scene.split(":")
    sc = b.Scene(a, float(e), os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".cache", "truth"))
    base = replace(b.QUALITIES["final"].settings, exact=True, ms_wavelength_step_nm=1.0,
                   ms_wavelength_outer_step_nm=0.0)
    if what == "knobs":
        prof, mc = sc.load_mc()
        if mc is None:
            raise SystemExit(f"no MC for {sc.name}: run bench_truth.py mc first")
        rows = _rows(sc, VIEWS)
        t, se = mc["mean"][rows], mc["se"][rows]
        print(sc.name, "views", VIEWS, "MC se %", np.round(100 * (se / t).max(1), 2))
        variants = [""] + (argv[2].split(";") if len(argv) > 2 else [])
    else:
        views = VIEWS[:3] + VIEWS[4:5]
        rows = _rows(sc, views)
        prof = replace(sc.mc_profile(), ground_albedo=np.zeros(3))
        res = trace_radiance(prof, sc.dirs[rows], sc.elev, b.SUN_AZIMUTH, n_paths=int(argv[2]), seed=77,
                             sun_guide=b.SUN_GUIDE[sc.aerosol])
        t = res.radiance
        print(sc.name, "albedo 0, views", views, f"MC {res.time_s:.0f} s, se %",
              np.round(100 * (res.stderr / t).max(1), 2))
        variants = ["", "view_steps=256"]
    for v in variants:
        s = replace(base, **b._parse_variant(v))
        t0 = time.perf_counter()
        r = b.SkyMarcher(prof, sc.elev, b.SUN_AZIMUTH, 0.0, s).radiance(sc.dirs[rows]).radiance
        _line(v or "final, exact", time.perf_counter() - t0, r / t - 1.0)


if __name__ == "__main__":
    main(sys.argv[1:])
