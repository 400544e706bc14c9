"""Where the near-sun deficit of desert 20 degrees lives: the Monte Carlo tracer and `final`'s
marcher (every direction exact) on three media, each on the scene's true phase functions and on
the delta-M medium (each aerosol's phase function cut at final's cone and renormalised, its
scattering times 1 - f: there the marcher cuts nothing, so the difference of the two media is
what the cut peak adds, in the truth and in the marcher).

usage: peak_media.py MEDIUM PATHS      (env SCENE=desert:20, WL=450, VIEWS=70/5.321,64/0,...)
  MEDIUM  base      the scene as it is
          noray     Rayleigh scattering removed (x 1e-6)
          peakonly  Rayleigh removed, the dust's phase function its cut peak alone (renormalised,
                    scattering x f), the background aerosol removed: the marcher's sky is then
                    its single scattering and the peak aureole alone
The MC runs (one wavelength, seed 11, bench_truth's sun_guide) are cached in $TRUTH_MISSES_OUT.
"""
import hashlib
import os
import sys
from dataclasses import replace

import numpy as np

sys.path[:0] = ["benchmarks", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "twilight_beam")]
import bench_truth as bt  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.medium import delta_m_cone_deg  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.validation.delta_m_medium import delta_m_profile  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from _beam import dust_peak_only  # noqa: E402  (the dust's cut peak alone)

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
mod, paths = sys.argv[1], int(sys.argv[2])
a, e = os.environ.get("SCENE", "desert:20").split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
V = os.environ.get("VIEWS", "70/5.321,64/0,60/0,75/0,67/0,30/0,70/21.298").split(",")
keep = sc.view_rows(V)
dirs, names = sc.dirs[keep], [bt.view_label(sc.views[i]) for i in keep]
fin = QUALITIES["final"].settings
wl = float(os.environ.get("WL", 450))


def modify(p):
    if mod == "noray":
        return p.with_(rayleigh_scattering=p.rayleigh_scattering * 1e-6)
    if mod == "peakonly":
        return dust_peak_only(p).with_(rayleigh_scattering=p.rayleigh_scattering * 1e-6)
    return p


def delta_m(p):
    return delta_m_profile(p, delta_m_cone_deg(p, fin.delta_m_cutoff_deg, fin.delta_m_mild_cutoff_deg))


res = {}
for kind in ("real", "dm"):
    pm = modify(sc.atm.optical_profile([wl]))
    pm = delta_m(pm) if kind == "dm" else pm
    fn = f"{OUT}/pm_{sc.name}_{mod}_{kind}_{wl:g}_{paths}_{hashlib.sha1(','.join(V).encode()).hexdigest()[:6]}.npz"
    if os.path.exists(fn):
        z = np.load(fn)
        mc, se = z["mc"], z["se"]
    else:
        r = trace_radiance(pm, dirs, sc.elev, bt.SUN_AZIMUTH, n_paths=paths, max_bounces=64, seed=11,
                           sun_guide=bt.SUN_GUIDE[a])
        mc, se = r.radiance[:, 0] / pm.solar_irradiance[0], r.stderr[:, 0] / pm.solar_irradiance[0]
        np.savez(fn, mc=mc, se=se)
    p = modify(sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM)))
    p = delta_m(p) if kind == "dm" else p
    j = int(np.argmin(np.abs(np.asarray(p.wavelengths_nm) - wl)))
    sr = SkyMarcher(p, sc.elev, bt.SUN_AZIMUTH, 0.0, replace(fin, exact=True)).radiance(dirs)
    res[kind] = (mc, se, sr.radiance[:, j] / p.solar_irradiance[j])
mr, sr_, Mr = res["real"]
md, sd, Md = res["dm"]
print(f"{sc.name} {mod} {wl:g} nm, {paths} paths per view")
print("view | marcher/MC - 1, true medium (%) | delta-M medium (%) | the cut peak's light, marcher - MC "
      "(% of the true sky) | the cut peak's share of the true sky (MC, %) | MC se true/delta-M (%)")
for k, n in enumerate(names):
    print(f"{n} | {100 * (Mr[k] / mr[k] - 1):+.2f} | {100 * (Md[k] / md[k] - 1):+.2f} | "
          f"{100 * ((Mr[k] - Md[k]) - (mr[k] - md[k])) / mr[k]:+.2f} | {100 * (mr[k] - md[k]) / mr[k]:.1f} | "
          f"{100 * sr_[k] / mr[k]:.2f}/{100 * sd[k] / md[k]:.2f}")
