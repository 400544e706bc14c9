"""Components of `final` (exact directions) at chosen views of a truth scene: single, the
solver's source gathered along the view ray, the peak aureole, the rest of `multiple`, ground.
usage: decomp.py scene views [variant]"""
import os
import sys
import numpy as np
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
scene = sys.argv[1]; views = sys.argv[2].split(","); var = sys.argv[3] if len(sys.argv) > 3 else ""
sc, prof, wl, idx = su.scene(scene)
keep = sc.view_rows(views)
m = su.marcher(sc, prof, **su.bt._parse_variant(var))
rec = {}
orig_a = SkyMarcher._aureole_gather
def ag(self, *a, **k):
    out = orig_a(self, *a, **k); rec.setdefault("aur", []).append(out); return out
SkyMarcher._aureole_gather = ag
orig_g = SkyMarcher._gather_ms
def gm(self, rings, D):
    out = orig_g(self, rings, D); rec.setdefault("ms", []).append(self.to_full(out) * self.profile.solar_irradiance); return out
SkyMarcher._gather_ms = gm
norm = np.asarray(prof.solar_irradiance)[idx]
for i in keep:
    rec.clear()
    r = m.radiance(sc.dirs[i:i+1])
    aur = rec["aur"][0].reshape(-1, len(wl))[0]; ms = rec["ms"][0].reshape(-1, len(wl))[0]
    tot = r.radiance[0]
    print(f"{su.bt.view_label(sc.views[i])}: total " + " ".join(f"{tot[j]/norm[k]:.4g}" for k, j in enumerate(idx)))
    for name, x in (("single", r.single[0]), ("ms src", ms), ("aureole", aur), ("rest mult", r.multiple[0] - ms - aur), ("ground", r.ground[0])):
        print(f"   {name:10s} " + " ".join(f"{100*x[j]/tot[j]:6.1f}%" for j in idx))
