"""Tail statistics of tail.py's runs, each against the committed truth of the scene.
usage: tail_stats.py scene run1.npz,run2.npz,... [--keep DIR]   (env TRUTH_CACHE as variant.py)

Per run and view: the mean over the truth's (both per unit solar irradiance: the one-wavelength
profile's band-averaged irradiance differs from the three-wavelength one's, the optics do not),
its standard error; the share of the sum the largest 1, 10 and 100 paths carry; the Hill
estimate of the scores' tail index from the largest k (a tail index below 2 is an infinite
variance: the standard error is then no measure of the error, and a finite run's mean reads
low more often than high); and the median over blocks of n paths of the block's mean over the
run's mean (for a light tail ~1 at every n; for a heavy one it climbs with n; only from a run's
full file). Last, every run pooled (weighted by paths; ``mc_check.py``'s three-wavelength runs may
be listed too, their 650 nm column read) against the truth and against `final` (the march cache).
``--keep DIR``: also write each run's summary to DIR (its mean, standard error, the
largest 1001 scores and their sum: a few tens of kB where the full file is tens of MB); the
summaries read back here like the runs, without the block medians."""
import os
import sys

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402

TOP = 1001
args = sys.argv[1:]
keep_dir = None
if "--keep" in args:
    i = args.index("--keep")
    keep_dir = args[i + 1]
    del args[i:i + 2]
a, e = args[0].split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof, mc = sc.load_mc()
wls = list(bt.MC_WAVELENGTHS_NM)
e0 = np.asarray(prof.solar_irradiance)


def hill(top, k):
    """Hill's estimate of the tail index from the largest k of the ascending ``top``."""
    if top.size < k + 1 or top[-k - 1] <= 0:
        return float("nan")
    return 1.0 / np.mean(np.log(top[-k:] / top[-k - 1]))


rng = np.random.default_rng(0)
pooled = []  # (keep, mean per unit irradiance, se per unit irradiance, paths, wavelength index)
for f in args[1].split(","):
    d = dict(np.load(f))
    if "wl" not in d:  # an mc_check.py run: the truth's three wavelengths, pooled at 650 nm
        w = wls.index(650.0)
        pooled.append((d["keep"], d["mean"][:, w] / e0[w], d["se"][:, w] / e0[w], float(d["n"]), w))
        continue
    full = "scores" in d
    top_all = d["scores"][:, -TOP:] if full else d["scores_top"]
    sums = d["scores"].sum(axis=1) if full else d["sum"]
    n = int(d["n"])
    if keep_dir:
        name = os.path.join(keep_dir, os.path.basename(f).replace(".npz", "_summary.npz"))
        np.savez_compressed(name, scores_top=top_all, sum=sums, **{k: d[k] for k in d if k != "scores"})
    print(f"{os.path.basename(f)}: sun_guide {float(d['guide'])}, seed {int(d['seed'])}, {n} paths, {float(d['seconds']):.0f} s")
    print("view | run / truth - 1 (%) | run se, truth se (%) | top 1/10/100 share (%) | Hill alpha k=100/1000"
          + (" | median block mean / mean, n=1e3/1e4/1e5" if full else ""))
    wi = wls.index(float(d["wl"]))
    pooled.append((d["keep"], sums / n / float(d["e_sun"]), d["se"] / float(d["e_sun"]), float(n), wi))
    for j, i in enumerate(d["keep"]):
        m = sums[j] / n
        rel = (m / float(d["e_sun"])) / (mc["mean"][i, wi] / e0[wi]) - 1
        top = top_all[j]
        share = [top[-k:].sum() / sums[j] for k in (1, 10, 100)]
        line = (f"{bt.view_label(sc.views[i])} | {100 * rel:+.2f} | {100 * float(d['se'][j]) / m:.2f}, "
                f"{100 * mc['se'][i, wi] / mc['mean'][i, wi]:.2f} | " + "/".join(f"{100 * t:.2f}" for t in share)
                + " | " + "/".join(f"{hill(top, k):.2f}" for k in (100, 1000)))
        if full:
            perm = rng.permutation(d["scores"][j])  # the run's order is lost in the sorted scores; any order will do
            blocks = [np.median(perm[: n // b * b].reshape(-1, b).mean(axis=1)) / m for b in (1000, 10000, 100000) if n // b >= 5]
            line += " | " + "/".join(f"{x:.3f}" for x in blocks)
        print(line)

march, _, _ = bt.run_march(sc, "final")
views = sorted(set(int(i) for k, *_ in pooled for i in k))
wi = {p[-1] for p in pooled}
if len(wi) != 1:
    sys.exit("tail_stats.py: the runs to pool must be at one wavelength")
wi = wi.pop()
print(f"pooled, {len(pooled)} runs, {wls[wi]:.0f} nm: view | paths | pooled / truth - 1 (combined se) | final / pooled - 1 (pooled se), %")
for i in views:
    m = s = n = 0.0
    for k, mk, sk, nk, _ in pooled:  # weighted by paths, as bench_truth pools its runs
        if i in k:
            j = list(k).index(i)
            m, s = bt._pooled(m, s, n, mk[j], sk[j], nk)
            n += nk
    t, ts = mc["mean"][i, wi] / e0[wi], mc["se"][i, wi] / e0[wi]
    print(f"{bt.view_label(sc.views[i])} | {int(n)} | {100 * (m / t - 1):+.2f} ({100 * np.hypot(s / m, ts / t):.2f}) | "
          f"{100 * (march[i, wi] / m - 1):+.2f} ({100 * s / m:.2f})")
