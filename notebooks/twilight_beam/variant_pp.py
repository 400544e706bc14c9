"""`final` with module constants of skymodel.render.peak_paths changed, against the Monte Carlo truth
of bench_truth (docs/accuracy.md), per scene: statistics, and per view with V=1.

usage: variant_pp.py SCENES TAG [NAME=VALUE ...]     (run from the repository root, PYTHONPATH=$PWD)
  SCENES  e.g. desert:-4 or rural:60,desert:-4
  TAG     name of the saved result ($TRUTH_MISSES_OUT/var_<scene>_<tag>.npz, as truth_misses/cmp.py reads)
  NAME=VALUE  a constant of peak_paths, e.g. OFFSET_FIRST_DEG=0.1 OFFSET_RATIO=1.2
env SOLVER=1: the bent beam's columns go into the solver's delta-M medium too (the table's
medium 1, its first order and so every later one), not only the marcher's (medium 2).
The 'base' rows are bench_truth's cached `final` march of the tree as it is ($TRUTH_CACHE).
"""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
import skymodel.render.marcher as mm  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.validation.truth import truth_statistics  # noqa: E402
from _beam import beam_in_solver_if_asked, set_constants  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
scenes, tag = sys.argv[1], sys.argv[2]
set_constants(sys.argv[3:])
beam_in_solver_if_asked()


def fmt(x, sign=True):
    return "/".join(f"{100 * v:{'+' if sign else ''}.2f}" for v in x)


for s in scenes.split(","):
    a, e = s.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    prof, mc = sc.load_mc()
    e0 = np.asarray(prof.solar_irradiance)[None, :]
    truth, se = mc["mean"] / e0, mc["se"] / e0
    p = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    m = mm.SkyMarcher(p, sc.elev, bt.SUN_AZIMUTH, 0.0, QUALITIES["final"].settings)
    rad = m.radiance(sc.dirs).radiance
    wl = np.asarray(p.wavelengths_nm)
    idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
    r = rad[:, idx] / np.asarray(p.solar_irradiance)[idx][None, :]
    np.savez(f"{OUT}/var_{sc.name}_{tag}.npz", r=r)
    base = bt.run_march(sc, "final")[0]
    for t, rr in (("base", base), (tag, r)):
        st = truth_statistics(rr, truth, se, sc.angle)
        print(f"{sc.name} {t}: median {fmt(st['median'], False)} mean {fmt(st['mean_signed'])} worst {fmt(st['worst'])}"
              f" at {', '.join(bt.view_label(sc.views[i]) for i in st['worst_index'])}")
    if os.environ.get("V"):
        print("view | base | " + tag + " | MC se (%)")
        for i, v in enumerate(sc.views):
            print(f"{bt.view_label(v)} | {fmt(base[i] / truth[i] - 1)} | {fmt(r[i] / truth[i] - 1)} | {fmt(se[i] / truth[i], False)}")
