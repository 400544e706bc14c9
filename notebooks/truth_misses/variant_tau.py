"""variant.py with the view rays' steps placed by optical depth (monkeypatch, marcher only):
variant_tau.py scenes tag share [n_fine]

Edges at equal steps of share * tau(t) / tau_total + (1 - share) * u, where u is the usual
quadratic map's coordinate and tau the total extinction's optical depth at the profile's
middle wavelength along the ray (from a fine u**2 march of n_fine steps, default 1024)."""
import sys
import numpy as np
import skymodel.render.marcher as mm
from skymodel.render.medium import march_samples
from skymodel.render.rays import altitude_along, atmosphere_segment

SHARE = float(sys.argv.pop(3))
N_FINE = int(sys.argv.pop(3)) if len(sys.argv) > 3 and sys.argv[3].isdigit() else 1024


def _rings(self, cos_zenith):
    cz = np.asarray(cos_zenith, dtype=float)
    d0 = np.stack([np.sqrt(np.clip(1.0 - cz * cz, 0.0, None)), np.zeros_like(cz), cz], axis=-1)
    p = np.broadcast_to(self.origin, d0.shape)
    t0, t1, hits = atmosphere_segment(p, d0, self.R, self.R + self.top)
    tf, dtf = march_samples(p, d0, t0, t1, N_FINE, self.R)
    ext = self.medium.extinction
    k = ext.weights.shape[1] // 2
    sig = ext.basis_at(np.maximum(altitude_along(p, d0, tf, self.R), 0.0)) @ ext.weights[:, k]
    tau = np.concatenate([np.zeros((cz.size, 1)), np.cumsum(sig * dtf, axis=1)], axis=1)
    edges_f = np.concatenate([t0[:, None], t0[:, None] + np.cumsum(dtf, axis=1)], axis=1)
    u = np.linspace(0.0, 1.0, N_FINE + 1)
    c = SHARE * tau / np.maximum(tau[:, -1:], 1e-300) + (1 - SHARE) * u
    n = self.settings.view_steps
    ck = np.linspace(0.0, 1.0, n + 1)
    edges = np.stack([np.interp(ck, c[g], edges_f[g]) for g in range(cz.size)])
    t = 0.5 * (edges[:, 1:] + edges[:, :-1])
    dt = np.diff(edges, axis=1)
    h = altitude_along(p, d0, t, self.R)
    x = p[:, None, :] + t[..., None] * d0[:, None, :]
    r = np.linalg.norm(x, axis=-1)
    mu = np.einsum("gsi,gi->gs", x, d0) / r
    r1 = np.linalg.norm(p + t1[:, None] * d0, axis=-1)
    return mm._Rings(t, dt, np.maximum(h, 0.0), r, x[..., 2], mu, hits, t1, r1)


mm.SkyMarcher._rings = _rings
sys.argv = sys.argv[:3] + [""]
exec(open("notebooks/truth_misses/variant.py").read())
