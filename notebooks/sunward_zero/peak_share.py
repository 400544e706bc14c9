"""What the cut forward peak adds to the sky, the truth against the marcher (desert 0 deg).

The real medium's truth (bench_truth's Monte Carlo run) minus the Monte Carlo on the delta-M
medium (orders.py ... dm: the peak cut at final's cone, scattering times 1 - f) is the light the
cut peak adds; the marcher's share is its real-medium render (variant.py's ``fin``) minus its
render of the delta-M medium (orders.py's tag). Both in % of the real truth, per view, with the
two Monte Carlo runs' combined noise, the marcher's own error on the delta-M medium, and the
peak's light itself (radiance per unit solar irradiance, 1e-3 sr^-1), truth and marcher.

usage (after variant.py <scene> fin "" and, per group of views, VIEWS=... orders.py <scene> all
<paths> "" "" dm0 dm):
    TRUTH_CACHE=... TRUTH_MISSES_OUT=... python notebooks/sunward_zero/peak_share.py desert:0 400000 \
        87/0,89/4.899,84/0,85/0 89/9.95,89/19.976,88/45,89/44.991
"""
import hashlib
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
scene, paths, groups = sys.argv[1], sys.argv[2], sys.argv[3:]
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof, mc = sc.load_mc()
e0 = np.asarray(prof.solar_irradiance)[None, :]
truth, truth_se = mc["mean"] / e0, mc["se"] / e0
fin = np.load(f"{OUT}/var_{sc.name}_fin.npz")["r"]
print("view | truth: peak share (%, 450/550/650) | noise | marcher: peak share | marcher on the delta-M medium / MC - 1"
      " | truth: peak light (1e-3 / sr) | marcher: peak light")
for g in groups:
    name = sc.name + "_v" + hashlib.sha1(g.encode()).hexdigest()[:6]
    dm_mc = np.load(f"{OUT}/mcb_{name}_ball_ax_n{paths}_dm.npz")
    dm_m = np.load(f"{OUT}/var_{name}_dm0.npz")
    for j, v in enumerate(dm_m["views"]):
        i = int(np.flatnonzero(np.all(np.isclose(sc.views, v), axis=1))[0])
        d, d_se = dm_mc["mean"][j] / e0[0], dm_mc["se"][j] / e0[0]
        t = truth[i]
        f = lambda x: "/".join(f"{100 * y:+.1f}" for y in x)  # noqa: E731
        print(f"{bt.view_label(v)} | {f((t - d) / t)} | {f(np.hypot(truth_se[i], d_se) / t)} | "
              f"{f((fin[i] - dm_m['r'][j]) / t)} | {f(dm_m['r'][j] / d - 1)} | "
              + "/".join(f"{1e3 * y:.3f}" for y in t - d) + " | " + "/".join(f"{1e3 * y:.3f}" for y in fin[i] - dm_m["r"][j]))
