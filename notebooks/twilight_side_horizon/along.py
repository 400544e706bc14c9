"""Where along a view ray the solver's source comes from, with and without the peak term (`final`,
650 nm), in altitude bins at `final`'s lowest altitude nodes: each bin's share of the ray's sum and
the term's part of it. usage: along.py scene views   (e.g. desert:-4 89/90,89/8.666)"""
import sys
import numpy as np
sys.path[:0] = ["notebooks/sunward_zero"]
import _setup as su
from skymodel.render.marcher import SkyMarcher
scene, views = sys.argv[1], sys.argv[2].split(",")
sc, prof, wl, idx = su.scene(scene)
keep = sc.view_rows(views)
rec = {}
orig = SkyMarcher._gather_ms
def gm(self, rings, D):
    mus = self._sun_cosines(rings, D)
    mu = np.broadcast_to(rings.mu[:, None, :], mus.shape)
    vs = (D @ self.sun)[..., None]
    den = np.sqrt(np.clip((1 - mu * mu) * (1 - mus * mus), 0.0, None))
    cphi = np.where(den > 1e-12, (vs - mu * mus) / np.where(den > 1e-12, den, 1.0), 1.0)
    phi = np.arccos(np.clip(cphi, -1.0, 1.0))
    from skymodel.render.medium import step_transmittance
    step = self.medium_ms.extinction_scaled.at(rings.h) * rings.dt[..., None]
    weight = step_transmittance(step, dtype=np.float32) * rings.dt[..., None].astype(np.float32)
    scale = None if self.field.scattering is None else self.field.scattering.at(rings.h)[:, None]
    src = self.field.source_at(np.broadcast_to(rings.h[:, None, :], mus.shape), mu, phi, mus, scale=scale)
    rec["per"] = weight[:, None] * src; rec["h"] = rings.h; rec["mus"] = mus; rec["mu"] = mu
    rec["t"] = np.cumsum(rings.dt, axis=-1)
    return orig(self, rings, D)
SkyMarcher._gather_ms = gm
res = {}
for tag, var in (("fin", {}), ("nopd", {"peak_diffuse": False})):
    m = su.marcher(sc, prof, **var)
    wms = np.asarray(m.field.wavelengths_nm); j650 = int(np.argmin(np.abs(wms - 650)))
    res[tag] = []
    for i in keep:
        m.radiance(sc.dirs[i:i+1])
        per = rec["per"][0, 0, :, j650]; res[tag].append((per, rec["h"][0], rec["mus"][0, 0], rec["mu"][0, 0], rec["t"][0]))
for k, i in enumerate(keep):
    pf, h, mus, mu, t = res["fin"][k]; pn = res["nopd"][k][0]
    tot = pf.sum()
    print(f"{su.bt.view_label(sc.views[i])}: solver source fin {pf.sum():.4g} nopd {pn.sum():.4g} (+{100*(pf.sum()/pn.sum()-1):.1f} %)")
    edges = [0, 43, 86, 129, 265, 411, 566, 1000, 100000]
    for a, b in zip(edges[:-1], edges[1:]):
        s = (h >= a) & (h < b)
        if s.any():
            print(f"  h {a/1e3:5.1f}-{b/1e3:5.1f} km: t {t[s].min()/1e3:6.0f}-{t[s].max()/1e3:6.0f} km, sun elev {np.degrees(np.arcsin(mus[s])).max():+.1f}..{np.degrees(np.arcsin(mus[s])).min():+.1f}, "
                  f"view elev {np.degrees(np.arcsin(mu[s])).min():.2f}..{np.degrees(np.arcsin(mu[s])).max():.2f}: fin {100*pf[s].sum()/tot:5.1f} %  nopd {100*pn[s].sum()/tot:5.1f} %  term {100*(pf[s].sum()-pn[s].sum())/tot:+5.2f} %")
