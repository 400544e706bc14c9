"""The Monte Carlo tracer of two source trees side by side on some views of a truth scene
(issue 23: what a change to the tracer buys): per seed, each tree traces the same views with
the same seed in its own process (its own skymodel and bench_truth), one tree after the other;
then time per path, per-path variance and the efficiency ratio 1 / (se^2 x time) per view and
wavelength, and how far the means differ in combined standard errors.

usage: side_by_side.py TREE_A TREE_B SCENE VIEWS PATHS SEEDS
  TREE_A/B  repository roots (e.g. a `git worktree add /tmp/before <rev>` and .), at 182366f
            or later (bench_truth's view names)
  SCENE     e.g. desert:-4       VIEWS  e.g. 0/0,85/0,89/0,89/90,88/135
  PATHS     per view and seed    SEEDS  e.g. 21-24
Runs are kept under $OUT (default /tmp/side_by_side) and reused; TRUTH_CACHE as for
notebooks/truth_misses (the scene's profile only, no run of it is needed).
"""
import hashlib
import os
import subprocess
import sys

import numpy as np

OUT = os.environ.get("OUT", "/tmp/side_by_side")
ONE = r"""
import sys, numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.validation.montecarlo import trace_radiance
scene, views, n, seed, out = sys.argv[1:6]
a, e = scene.split(":")
sc = bt.Scene(a, float(e), bt.os.environ.get("TRUTH_CACHE", ".cache/truth"))
rows = sc.view_rows(views)
r = trace_radiance(sc.mc_profile(), sc.dirs[rows], sc.elev, bt.SUN_AZIMUTH, n_paths=int(n), seed=int(seed),
                   sun_guide=sc.sun_guide, estimator=sc.estimator)
np.savez(out, mean=r.radiance, se=r.stderr, t=r.time_s, names=[bt.view_label(sc.views[i]) for i in rows])
"""


def run(tree, tag, scene, views, n, seed):
    key = hashlib.sha1(f"{os.path.abspath(tree)} {views}".encode()).hexdigest()[:8]
    f = os.path.join(OUT, f"{tag}_{scene.replace(':', '')}_{key}_{n}_{seed}.npz")
    if not os.path.exists(f):
        env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=os.path.abspath(tree))
        subprocess.run([sys.executable, "-c", ONE, scene, views, str(n), str(seed), f], cwd=tree, env=env, check=True)
    return np.load(f)


def main():
    tree_a, tree_b, scene, views, n, seeds = sys.argv[1:7]
    n = int(n)
    lo, hi = (int(x) for x in seeds.split("-"))
    os.makedirs(OUT, exist_ok=True)
    res = {"A": [], "B": []}
    for seed in range(lo, hi + 1):
        for tag, tree in (("A", tree_a), ("B", tree_b)):
            res[tag].append(run(tree, tag, scene, views, n, seed))
    stats = {}
    for tag, runs in res.items():
        mean = np.mean([r["mean"] for r in runs], axis=0)
        var = np.mean([r["se"] ** 2 * n for r in runs], axis=0)  # per-path variance, pooled
        t = np.sum([float(r["t"]) for r in runs]) / (len(runs) * n * runs[0]["mean"].shape[0])
        stats[tag] = (mean, var, t)
        print(f"{tag} ({tree_a if tag == 'A' else tree_b}): {len(runs)} seeds, {t * 1e6:.0f} us per path")
    (ma, va, ta), (mb, vb, tb) = stats["A"], stats["B"]
    k = hi - lo + 1
    gain = va * ta / (vb * tb)
    print("view | rel sd per path A | B | efficiency B / A | (B - A) / combined se  (per wavelength)")
    for i, name in enumerate(res["A"][0]["names"]):  # the scene's order
        z = (mb[i] - ma[i]) / np.sqrt((va[i] + vb[i]) / (k * n))
        print(f"{name} | {np.round(np.sqrt(va[i]) / ma[i], 2)} | {np.round(np.sqrt(vb[i]) / mb[i], 2)} | "
              f"{np.round(gain[i], 2)} | {np.round(z, 1)}")
    print(f"time per path B / A {tb / ta:.3f}; efficiency B / A median {np.median(gain):.2f} "
          f"(range {gain.min():.2f}-{gain.max():.2f}); largest |z| {np.max(np.abs((mb - ma) / np.sqrt((va + vb) / (k * n)))):.1f}")


if __name__ == "__main__":
    main()
