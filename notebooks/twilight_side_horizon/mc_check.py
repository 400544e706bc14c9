"""An independent real-medium MC run at some truth views (other seeds, other sun_guide).
usage: mc_check.py scene views paths seed sun_guide out.npz [estimator, default proxy]"""
import os, sys, time
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.validation.montecarlo import trace_radiance
scene, views, paths, seed, guide, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]), sys.argv[6]
estimator = sys.argv[7] if len(sys.argv) > 7 else "proxy"
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
keep = sc.view_rows(views)
prof = sc.atm.optical_profile(list(bt.MC_WAVELENGTHS_NM))
t = time.time()
r = trace_radiance(prof, sc.dirs[keep], sc.elev, bt.SUN_AZIMUTH, n_paths=paths, seed=seed, estimator=estimator, sun_guide=guide)
np.savez(out, mean=r.radiance, se=r.stderr, keep=keep, seconds=time.time() - t, n=paths)
print(f"done {time.time()-t:.0f} s")
