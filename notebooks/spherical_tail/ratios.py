"""The spherical correction of every order (spherical_orders=20) against order 3's, node by node:
how far the later orders' factor is from the one spherical_tail would reuse, and what share of each
order's light sits at the nodes where it is more than 5 % off.
usage: TRUTH_CACHE=... python notebooks/spherical_tail/ratios.py desert:5 final|reference"""
import os
import sys, numpy as np
sys.path[:0]=["benchmarks"]
import bench_truth as bt
from dataclasses import replace
import skymodel.render.multiple_scattering as ms
from skymodel.render.marcher import solve_sky
from skymodel.render.quality import QUALITIES
orig = ms._SphericalTransport.correction
rat, cols = [], []
def corr(self, j, lg, col):
    r = orig(self, j, lg, col)
    rat.append(r[..., :self.n_sub].copy()); cols.append(col[..., :self.n_sub].copy())
    return r
ms._SphericalTransport.correction = corr
scene, preset = sys.argv[1], sys.argv[2]
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
sol = solve_sky(prof, replace(QUALITIES[preset].settings, spherical_orders=20, spherical_tail=False))
r3 = rat[1]
for k in range(2, len(rat)):
    rk = rat[k]; ck = cols[k]
    w = ck * r3  # light the tail would put there
    rel = np.abs(rk / r3 - 1)
    big = rel > 0.05
    print(f"order {k+2}: |r_k/r_3-1| median {np.median(rel):.4f} p99 {np.percentile(rel,99):.3f} max {rel.max():.3g}; share of order-{k+2} light at nodes off >5%: {(w*big).sum()/w.sum():.4f}; r3 max {r3.max():.3g}")
