"""How much of a scene's worst direction is the truth's noise: the worst |marcher / MC - 1| with each
direction's error shrunk toward the scene's mean by its own noise (normal-normal empirical Bayes:
the spread of the true errors over the directions is the observed spread less the mean squared
standard error), and the replicate pair of desert -4 (89/90 and 89/89.93 lie 0.07 deg apart).
usage: selection.py [quality] [scenes]   (default final, every scene of docs/accuracy.md; env TRUTH_CACHE)"""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
from skymodel.validation.truth import EXCLUDE_DEG  # noqa: E402

quality = sys.argv[1] if len(sys.argv) > 1 else "final"
scenes = bt.scenes_from(sys.argv[2] if len(sys.argv) > 2 else "all")
cache = os.environ.get("TRUTH_CACHE", ".cache/truth")
print(f"{quality}: worst |rel| (signed, %) at 450/550/650 nm, as observed and shrunk; the shrinkage factor "
      "tau^2 / (tau^2 + se^2) at the worst")
print("scene | observed worst | at | shrunk worst | at | factor")
for aerosol, elev in scenes:
    sc = bt.Scene(aerosol, elev, cache)
    prof, mc = sc.load_mc()
    e0 = np.asarray(prof.solar_irradiance)[None, :]
    rad, _, _ = bt.run_march(sc, quality)
    truth = mc["mean"] / e0
    ok = sc.angle > EXCLUDE_DEG
    o = 100 * (rad / truth - 1)[ok]
    s = 100 * (mc["se"] / mc["mean"])[ok]
    tau2 = np.maximum(o.var(axis=0, ddof=1) - (s ** 2).mean(axis=0), 0.0)
    mu = o.mean(axis=0)
    fac = tau2 / (tau2 + s ** 2)
    shr = mu + fac * (o - mu)
    lab = [bt.view_label(v) for v in sc.views[ok]]
    i_o, i_s = np.abs(o).argmax(axis=0), np.abs(shr).argmax(axis=0)
    w = np.arange(o.shape[1])
    print(f"{aerosol} {elev:g} | " + "/".join(f"{x:+.2f}" for x in o[i_o, w]) + " | " + ", ".join(lab[i] for i in i_o)
          + " | " + "/".join(f"{x:+.2f}" for x in shr[i_s, w]) + " | " + ", ".join(lab[i] for i in i_s)
          + " | " + "/".join(f"{x:.2f}" for x in fac[i_s, w]))
    if (aerosol, elev) == ("desert", -4.0):
        names = [bt.view_label(v) for v in sc.views]
        a, b = names.index("89/90"), names.index("89/89.93")
        rel = 100 * (rad / truth - 1)
        se = 100 * mc["se"] / mc["mean"]
        print("  replicate pair 89/90, 89/89.93 (0.07 deg apart): marcher / MC - 1 "
              + "/".join(f"{x:+.2f}" for x in rel[a]) + " and " + "/".join(f"{x:+.2f}" for x in rel[b])
              + "; the marcher's two radiances differ by " + "/".join(f"{100 * x:+.3f}" for x in rad[a] / rad[b] - 1)
              + " %, the truth's by " + "/".join(f"{100 * x:+.2f}" for x in truth[a] / truth[b] - 1)
              + " % (combined se " + "/".join(f"{x:.2f}" for x in np.hypot(se[a], se[b])) + ")")
