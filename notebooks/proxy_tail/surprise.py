"""Where does the "proxy" estimator's heavy tail come from at desert -4 deg? (issue 23)

Traces paths of one view and wavelength with every line sample recorded: the line's kind
(``sun``: a sunlit line integral; ``collide``: the forced first collision), its intervals,
its proxy mass G (the density's normalisation, which approximates the integral) and the
sample's f / pdf. The surprise s = (f / pdf) / G is ~1 where the density follows the
integrand; a heavy tail of s is a heavy tail of the estimator.

usage: surprise.py scene view wl_index paths [seed]   e.g. desert:-4 85/0 2 20000
"""
import os
import sys

import numpy as np

from _setup import bt, mcm, one_view

scene, view, wi, n = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
seed = int(sys.argv[5]) if len(sys.argv) > 5 else 1
sc, k, med, px, sun, origin = one_view(scene, view, wi)

REC = []
_orig = mcm._Line.sample


def sample(self, rows, rng):
    u, f = _orig(self, rows, rng)
    G = self.total[rows]
    L = self.length[rows]
    x = self.p[rows] + self.t_of(rows, u)[:, None] * self.d[rows]
    h = np.sqrt(mcm._rowdot(x, x)) - med.R
    hp = np.sqrt(mcm._rowdot(self.p[rows], self.p[rows])) - med.R
    el = np.degrees(np.arcsin(mcm._rowdot(self.d[rows], self.p[rows]) / (hp + med.R)))
    REC.append(np.column_stack([np.full(rows.size, 0 if self.kind == "sun" else 1), np.full(rows.size, self.n),
                                f, G, L, h, hp, el, self.d[rows] @ sun, self.p[rows], self.d[rows], u, self.w[rows]]))
    return u, f


mcm._Line.sample = sample
rng = np.random.default_rng(seed)
dirs = np.repeat(sc.dirs[k:k + 1], n, axis=0)
c = mcm._trace_batch_sunlit(med, origin, dirs, np.zeros(n, dtype=int), sun, 64, rng, proxy=px,
                            sun_guide=sc.sun_guide)
r = np.concatenate(REC)
kind, nint, f, G, L, h, hp, el, mu = r.T[:9]
s = np.where(G > 0, f / np.where(G > 0, G, 1), 0)
print(f"{scene} {view} wl {bt.MC_WAVELENGTHS_NM[wi]:g} nm, {n} paths: mean {c.mean():.4e} se {c.std(ddof=1) / np.sqrt(n) / c.mean():.2%}"
      f", top paths' share of the sum: {np.sort(c)[::-1][:5] / c.sum()}")
for kk, name in ((0, "sun"), (1, "collide")):
    for ni in np.unique(nint[kind == kk]):
        m = (kind == kk) & (nint == ni) & (G > 0)
        ss = s[m]
        q = np.quantile(ss, [0.5, 0.9, 0.99, 0.999, 0.9999]) if ss.size else []
        print(f"  {name} n={ni:.0f}: {m.sum()} samples, s mean {ss.mean():.3f}, quantiles 50/90/99/99.9/99.99 %"
              f" {np.round(q, 2)}, max {ss.max():.1f}; E[s^2] {np.mean(ss ** 2):.2f}")
np.savez(os.environ.get("OUT", "/tmp") + f"/surprise_{sc.name}_{view.replace('/', '_')}_{wi}_{n}_{seed}.npz", r=r, c=c)
