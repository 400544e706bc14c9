"""variant.py with the view rays' step crowding power changed (monkeypatch, marcher only): variant_pow.py scene tag power"""
import sys, os
import numpy as np
import skymodel.render.marcher as mm
POW = float(sys.argv.pop(3))
def march_samples(p, d, t0, t1, n, ground_radius):
    p = np.asarray(p, dtype=float); d = np.asarray(d, dtype=float)
    t0 = np.asarray(t0, dtype=float)[..., None]; t1 = np.asarray(t1, dtype=float)[..., None]
    tp = np.clip(-np.einsum("...i,...i->...", p, d)[..., None], t0, t1)
    length = np.maximum(t1 - t0, 1e-300)
    f = np.clip((tp - t0) / length, 0.0, 1.0)
    u = np.linspace(0.0, 1.0, n + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        before = tp - (tp - t0) * (1.0 - np.where(f > 0, u / f, 1.0)) ** POW
        after = tp + (t1 - tp) * np.where(f < 1, (u - f) / (1.0 - f), 0.0) ** POW
    edges = np.where(u < f, before, after)
    edges[..., 0] = t0[..., 0]; edges[..., -1] = t1[..., 0]
    return 0.5 * (edges[..., 1:] + edges[..., :-1]), np.diff(edges, axis=-1)
mm.march_samples = march_samples
sys.argv = sys.argv[:3] + [""]
exec(open("notebooks/truth_misses/variant.py").read())
