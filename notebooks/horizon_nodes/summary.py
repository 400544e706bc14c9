"""Saved variants (notebooks/truth_misses/variant.py) against the Monte Carlo truth and against
one another, per scene of the truth table.

usage: summary.py truth TAG1,TAG2,...             mean |marcher / MC - 1| over the views outside
                                                  the sun's first 2.27 deg, and the worst, %
       summary.py converged REF TAG1,... SCENES   against the variant REF (no MC noise): mean and
                                                  largest |rel| over the upper sky (view zenith
                                                  < 80 deg) and the horizon (>= 80 deg), %
env: TRUTH_CACHE (the truth's cache), TRUTH_MISSES_OUT (the variants' files), as variant.py."""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402

CACHE = os.environ.get("TRUTH_CACHE", ".cache/truth")
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
ALL = "rural:60,rural:20,rural:5,rural:0,rural:-4,desert:60,desert:20,desert:5,desert:0,desert:-4"


def fmt(values, spec=".2f"):
    return "/".join(format(x, spec) for x in values)


def scene(name):
    a, e = name.split(":")
    return bt.Scene(a, float(e), CACHE)


def load(sc, tag):
    return np.load(f"{OUT}/var_{sc.name}_{tag}.npz")["r"]


if sys.argv[1] == "truth":
    tags = sys.argv[2].split(",")
    print("scene | " + " | ".join(tags) + "  (mean |rel| 450/550/650 nm, then w = worst |rel|, %)")
    for name in ALL.split(","):
        sc = scene(name)
        prof, mc = sc.load_mc()
        truth = mc["mean"] / np.asarray(prof.solar_irradiance)[None, :]
        ok = sc.angle > 2.27
        cells = []
        for t in tags:
            rel = 100 * np.abs(load(sc, t) / truth - 1)[ok]
            cells.append(fmt(rel.mean(0)) + " w" + fmt(rel.max(0), ".1f"))
        print(sc.name, "|", " | ".join(cells))
else:
    ref, tags = sys.argv[2], sys.argv[3].split(",")
    for name in sys.argv[4].split(","):
        sc = scene(name)
        r0 = load(sc, ref)
        zen = np.array([v[0] for v in sc.views])
        ok = sc.angle > 2.27
        for t in tags:
            rel = 100 * (load(sc, t) / r0 - 1)
            parts = []
            for label, m in (("upper", ok & (zen < 80)), ("horizon", ok & (zen >= 80))):
                big = rel[m][np.abs(rel[m]).argmax(0), [0, 1, 2]]
                parts.append(f"{label} {fmt(np.abs(rel[m]).mean(0))} max {fmt(big, '+.2f')}")
            print(f"{sc.name} {t}: " + " | ".join(parts))
