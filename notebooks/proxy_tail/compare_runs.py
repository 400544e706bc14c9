"""Two Monte Carlo runs of one scene, direction by direction (issue 23: the desert -4 deg
truth traced with the roulette as it was against a run traced after the fix).

usage: compare_runs.py A.npz B.npz     (bench_truth's run files; B - A relative to A)
Prints per wavelength the mean over directions of B / A - 1 with its standard error (from the
runs' own) and its median, how many directions differ by more than 2 and 3 combined standard errors, the
runs' paths and relative standard errors, and the directions that differ the most.
"""
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402

a, b = (bt.read_run(p) for p in sys.argv[1:3])
if not np.array_equal(a["views"], b["views"]):
    raise SystemExit("the runs have different views")
r = b["mean"] / a["mean"] - 1.0
s = np.hypot(a["se"] / a["mean"], b["se"] / b["mean"]) * (1.0 + r)
z = r / s
for i, wl in enumerate(bt.MC_WAVELENGTHS_NM):
    m = r[:, i].mean()
    e = np.sqrt(np.sum(s[:, i] ** 2)) / r.shape[0]
    print(f"{wl:g} nm: B/A - 1 mean over {r.shape[0]} directions {100 * m:+.2f} ± {100 * e:.2f} %, "
          f"median {100 * np.median(r[:, i]):+.2f} %, |z| > 2: {np.sum(np.abs(z[:, i]) > 2)}, > 3: {np.sum(np.abs(z[:, i]) > 3)}; "
          f"rel se A median {100 * np.median(a['se'][:, i] / a['mean'][:, i]):.2f} max "
          f"{100 * np.max(a['se'][:, i] / a['mean'][:, i]):.2f} %, B median "
          f"{100 * np.median(b['se'][:, i] / b['mean'][:, i]):.2f} max {100 * np.max(b['se'][:, i] / b['mean'][:, i]):.2f} %")
print(f"paths A {a['n'].min()}..{a['n'].max()}, B {b['n'].min()}..{b['n'].max()}")
for k in np.argsort(-np.abs(z).max(axis=1))[:6]:
    v = a["views"][k]
    print(f"  {bt.view_label(v)}: B/A - 1 {np.round(100 * r[k], 2)} %, z {np.round(z[k], 1)}")
