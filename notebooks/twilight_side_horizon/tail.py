"""Each path's score of a real-medium MC run at some truth views, one wavelength: how heavy is the tail?
usage: tail.py scene views wavelength_nm paths seed sun_guide out.npz [estimator, default proxy]
Saves, per view, the mean, the standard error and the paths' scores sorted (float64, for the tail
statistics of tail_stats.py); the run goes through trace_radiance itself, its batch function only
wrapped to keep what it returns."""
import os
import sys
import time

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
import skymodel.validation.montecarlo as mcm  # noqa: E402

scene, views, wl = sys.argv[1], sys.argv[2], float(sys.argv[3])
paths, seed, guide, out = int(sys.argv[4]), int(sys.argv[5]), float(sys.argv[6]), sys.argv[7]
estimator = sys.argv[8] if len(sys.argv) > 8 else "proxy"
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
keep = sc.view_rows(views)
prof = sc.atm.optical_profile([wl])

kept = []
batch = mcm._trace_batch_sunlit if estimator != "nee" else mcm._trace_batch


def recording(med, origin, dirs, *rest, **kw):
    c = batch(med, origin, dirs, *rest, **kw)
    kept.append((dirs.copy(), c.copy()))
    return c


if estimator == "nee":
    mcm._trace_batch = recording
else:
    mcm._trace_batch_sunlit = recording
t = time.time()
r = mcm.trace_radiance(prof, sc.dirs[keep], sc.elev, bt.SUN_AZIMUTH, n_paths=paths, seed=seed,
                       estimator=estimator, sun_guide=guide)
# each batch's rows are paths of some of the views: sort them to their view by direction
views_unit = sc.dirs[keep] / np.linalg.norm(sc.dirs[keep], axis=1, keepdims=True)
per_view = [[] for _ in keep]
for d, c in kept:
    which = np.argmax(d @ views_unit.T, axis=1)
    for j in range(len(keep)):
        per_view[j].append(c[which == j])
scores = np.stack([np.concatenate(v) for v in per_view])
assert np.allclose(scores.mean(axis=1), r.radiance[:, 0], rtol=1e-12, atol=0)
np.savez_compressed(out, scores=np.sort(scores, axis=1), mean=r.radiance[:, 0], se=r.stderr[:, 0],
                    keep=keep, wl=wl, guide=guide, seed=seed, seconds=time.time() - t, n=paths,
                    e_sun=np.asarray(prof.solar_irradiance)[0])
print(f"done {time.time() - t:.0f} s")
