"""What the proxy_tail scripts share: one view and wavelength of a truth scene of
benchmarks/bench_truth.py as the tracer's internals see it."""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
from skymodel.render.rays import sun_direction  # noqa: E402
from skymodel.validation import montecarlo as mcm  # noqa: E402


def one_view(scene, view, wi):
    """'desert:-4', '85/0', wavelength index -> (Scene, view index, medium of that wavelength,
    the proxy estimator's approximate optical depths (since 2026-11-27 its table,
    ``_DepthTable``; the measurements of the README were made with the 26-piece coarse
    profile before it), sun direction, observer at the ground)."""
    a, e = scene.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    k = sc.view_rows([view])[0]
    prof = sc.mc_profile()
    med = mcm._Medium(prof, np.array([wi]))
    sun = sun_direction(sc.elev, bt.SUN_AZIMUTH).astype(float).reshape(3)
    return sc, k, med, mcm._DepthTable(med), sun, np.array([0.0, 0.0, float(prof.planet_radius_m)])
