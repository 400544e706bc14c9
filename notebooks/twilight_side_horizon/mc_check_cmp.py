"""Pool mc_check.py runs and compare them with the committed truth and with `final` (variant.py's fin).
usage: mc_check_cmp.py scene run1.npz,run2.npz,...   (env TRUTH_CACHE, TRUTH_MISSES_OUT as variant.py)"""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402

a, e = sys.argv[1].split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof, mc = sc.load_mc()
e0 = np.asarray(prof.solar_irradiance)[None, :]
runs = [np.load(f) for f in sys.argv[2].split(",")]
keep = runs[0]["keep"]
mean, se, n = runs[0]["mean"], runs[0]["se"], float(runs[0]["n"])
for r in runs[1:]:  # weighted by paths, as bench_truth pools its runs
    mean, se = bt._pooled(mean, se, n, r["mean"], r["se"], float(r["n"]))
    n += float(r["n"])
fin = np.load(os.path.join(os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses"), f"var_{sc.name}_fin.npz"))["r"]
print(f"{len(runs)} runs, {int(n)} paths per view; % at 450/550/650 nm")
print("view | new / truth - 1 | combined se | final / new - 1 | final / truth - 1")
f = lambda x: "/".join(f"{100 * y:+.2f}" for y in x)  # noqa: E731
for j, i in enumerate(keep):
    t, ts = mc["mean"][i], mc["se"][i]
    print(f"{bt.view_label(sc.views[i])} | {f(mean[j] / t - 1)} | " + "/".join(f"{100 * y:.2f}" for y in np.hypot(se[j] / mean[j], ts / t))
          + f" | {f(fin[i] / (mean[j] / e0[0]) - 1)} | {f(fin[i] / (t / e0[0]) - 1)}")
