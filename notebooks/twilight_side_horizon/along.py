"""Where along a view ray the solver's source comes from, with and without the peak term (`final`,
650 nm), in altitude bins at `final`'s lowest altitude nodes: each bin's share of the ray's sum and
the term's part of it. usage: along.py scene views   (e.g. desert:-4 89/90,89/8.666)

The per-sample terms are those `SkyMarcher._gather_ms` sums (its `_column(weight, source)`),
recorded as it makes them."""
import sys

import numpy as np

sys.path[:0] = ["notebooks/sunward_zero"]
import _setup as su  # noqa: E402
from skymodel.render import marcher as mm  # noqa: E402

scene, views = sys.argv[1], sys.argv[2].split(",")
sc, prof, wl, idx = su.scene(scene)
keep = sc.view_rows(views)
rec = {}
orig_gather, orig_column = mm.SkyMarcher._gather_ms, mm._column


def gather(self, rings, D):
    rec.update(h=rings.h, mu=rings.mu, t=np.cumsum(rings.dt, axis=-1), mus=self._sun_cosines(rings, D))
    rec["on"] = True
    try:
        return orig_gather(self, rings, D)
    finally:
        rec["on"] = False


def column(weight, values):
    if rec.get("on"):
        rec["per"] = weight.astype(values.dtype)[:, None] * values  # (G, A, S, W): the summed terms
    return orig_column(weight, values)


mm.SkyMarcher._gather_ms, mm._column = gather, column
res = {}
for tag, var in (("fin", {}), ("nopd", {"peak_diffuse": False})):
    m = su.marcher(sc, prof, **var)
    j650 = int(np.argmin(np.abs(np.asarray(m.field.wavelengths_nm) - 650)))
    res[tag] = []
    for i in keep:
        m.radiance(sc.dirs[i:i + 1])
        res[tag].append((rec["per"][0, 0, :, j650], rec["h"][0], rec["mus"][0, 0], rec["mu"][0], rec["t"][0]))
edges = [0, 43, 86, 129, 265, 411, 566, 1000, 100000]
for k, i in enumerate(keep):
    pf, h, mus, mu, t = res["fin"][k]
    pn = res["nopd"][k][0]
    tot = pf.sum()
    print(f"{su.bt.view_label(sc.views[i])}: solver source fin {pf.sum():.4g} nopd {pn.sum():.4g} (+{100*(pf.sum()/pn.sum()-1):.1f} %)")
    for a, b in zip(edges[:-1], edges[1:]):
        s = (h >= a) & (h < b)
        if s.any():
            print(f"  h {a/1e3:5.1f}-{b/1e3:5.1f} km: t {t[s].min()/1e3:6.0f}-{t[s].max()/1e3:6.0f} km, sun elev {np.degrees(np.arcsin(mus[s])).max():+.1f}..{np.degrees(np.arcsin(mus[s])).min():+.1f}, "
                  f"view elev {np.degrees(np.arcsin(mu[s])).min():.2f}..{np.degrees(np.arcsin(mu[s])).max():.2f}: fin {100*pf[s].sum()/tot:5.1f} %  nopd {100*pn[s].sum()/tot:5.1f} %  term {100*(pf[s].sum()-pn[s].sum())/tot:+5.2f} %")
