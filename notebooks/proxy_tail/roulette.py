"""The sunlit/proxy estimator's Russian roulette with and without the sun guide's weighing
(issue 23, desert -4 deg): the potential score of each vertex and the paths' contributions.

At every vertex of the guided sum the path's weight before scattering times 4 pi x the sun
guide's density at its incoming direction bounds what that vertex can score relative to a
typical path (the next line integral along a direction drawn around the sun scores ~ the
aerosol phase function there). Plain roulette (``plain``) promotes a small weight heading
into the sun's forward peak to 1; the guided roulette (``guided``, what trace_radiance does
now) does not.

usage: roulette.py plain|guided scene view wl_index paths seed
  e.g. roulette.py plain desert:-4 85/0 2 500000 11
"""
import sys
import time

import numpy as np

from _setup import bt, mcm, one_view

mode, scene, view, wi, n, seed = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6])
sc, k, med, px, sun, origin = one_view(scene, view, wi)

if mode == "plain":
    def plain(med_, beta, D, Wl, sun_, sun_guide, keep, rng, _guided=mcm._roulette):
        return _guided(med_, beta, D, Wl, sun_, 0.0, keep, rng)
    mcm._roulette = plain
elif mode != "guided":
    raise SystemExit("mode: plain or guided")

X = []
_gs = mcm._guided_sum


def guided_sum(med_, guide, rows, P, Din, D, Wl, ev, beta, beta_pre, sun_, rng, line=None, sun_guide=0.0):
    X.append(beta_pre * 4.0 * np.pi * mcm._guide_pdf(med_, Din, Wl, sun_))
    return _gs(med_, guide, rows, P, Din, D, Wl, ev, beta, beta_pre, sun_, rng, line, sun_guide)


mcm._guided_sum = guided_sum
rng = np.random.default_rng(seed)
t0 = time.perf_counter()
c = mcm._trace_batch_sunlit(med, origin, np.repeat(sc.dirs[k:k + 1], n, axis=0), np.zeros(n, dtype=int), sun, 64, rng,
                            proxy=px, sun_guide=sc.sun_guide)
dt = time.perf_counter() - t0
x = np.concatenate(X)
m = c.mean()
top = np.sort(c)[::-1][:3] / m
print(f"{mode} {scene} {view} {bt.MC_WAVELENGTHS_NM[wi]:g} nm seed {seed}: {n} paths {dt:.0f} s, mean {m:.5e}, "
      f"se {c.std(ddof=1) / np.sqrt(n) / m:.3%}, top paths / mean {np.round(top, 1)}; vertices {x.size}, "
      f"weight x 4 pi guide: max {x.max():.3g}, > 10: {np.sum(x > 10)}, > 100: {np.sum(x > 100)}")
