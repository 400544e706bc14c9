"""compare saved variants with the MC: cmp.py scene tag1,tag2,..."""
import sys
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.validation.truth import truth_statistics
import os
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
a, e = sys.argv[1].split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof, mc = sc.load_mc()
e0 = np.asarray(prof.solar_irradiance)[None, :]
truth, se = mc["mean"] / e0, mc["se"] / e0
tags = sys.argv[2].split(",")
rs = {t: np.load(f"{OUT}/var_{sc.name}_{t}.npz")["r"] for t in tags}
print(f"{sc.name}: MC paths {mc['n'].min()}..{mc['n'].max()}, rel se median {100*np.median(se/truth):.2f} max {100*np.max(se/truth):.2f}")
for t, r in rs.items():
    st = truth_statistics(r, truth, se, sc.angle)
    print(f"{t}: median " + "/".join(f"{100*x:.2f}" for x in st["median"]) + " (+- " + "/".join(f"{100*x:.2f}" for x in st["median_noise"]) + ")"
          + " mean " + "/".join(f"{100*x:+.2f}" for x in st["mean_signed"]), end="")
    print("  worst " + "/".join(f"{100*x:+.2f}" for x in st["worst"]) + " at " + ", ".join(sorted({bt.view_label(sc.views[i]) for i in st["worst_index"]})))
if "-v" in sys.argv:
    print("view | angle | " + " | ".join(tags) + " | se")
    for i, v in enumerate(sc.views):
        print(f"{bt.view_label(v)} | {sc.angle[i]:.1f} | " + " | ".join("/".join(f"{100*x:+.2f}" for x in rs[t][i] / truth[i] - 1) for t in tags)
              + " | " + "/".join(f"{100*x:.2f}" for x in se[i] / truth[i]))
