"""The bent beam alone against the Monte Carlo tracer: the scene's medium with its dust scattering
only into its cut peak (the phase function the peak alone, renormalised, scattering x f), the
background aerosol removed, Rayleigh and ozone kept. The marcher's delta-M then cuts all of the
dust's scattering, and what the dust does to the sky is the bent beam's (and the peak aureole's)
alone; the tracer scatters exactly. One wavelength, `final`, every direction exact.

usage: peak_only.py PATHS TAG [NAME=VALUE ...]   (env SCENE=desert:-4, WL=650, VIEWS=0/0,30/0,...,
                                                 SOLVER=1 as variant_pp.py; NAME=VALUE as there;
                                                 VARIANT="peak_diffuse=0": MarchSettings changed from final)
The tracer's run (seed 11, bench_truth's estimator and sun_guide 0.2) is cached in $TRUTH_MISSES_OUT.
"""
import hashlib
import os
import sys
import time
from dataclasses import replace

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
import skymodel.render.marcher as mm  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402
from skymodel.validation.montecarlo import trace_radiance  # noqa: E402
from _beam import beam_in_solver_if_asked, dust_peak_only, set_constants  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
paths, tag = int(sys.argv[1]), sys.argv[2]
set_constants(sys.argv[3:])
beam_in_solver_if_asked()
a, e = os.environ.get("SCENE", "desert:-4").split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
V = os.environ.get("VIEWS", "0/0,30/0,60/0,75/0,60/90,30/180,70/45,85/90").split(",")
keep = sc.view_rows(V)
dirs, names = sc.dirs[keep], [bt.view_label(sc.views[i]) for i in keep]
WL = float(os.environ.get("WL", 650))


pm = dust_peak_only(sc.atm.optical_profile([WL]))
key = hashlib.sha1(",".join(names).encode()).hexdigest()[:6]
mc_f = f"{OUT}/peakonly_{sc.name}_{WL:g}_{paths}_{key}.npz"
if os.path.exists(mc_f):
    z = np.load(mc_f)
    mc, se = z["mean"], z["se"]
else:
    t = time.time()
    res = trace_radiance(pm, dirs, sc.elev, bt.SUN_AZIMUTH, n_paths=paths, seed=11,
                         estimator=bt.estimator_for(sc.elev), sun_guide=0.2)
    mc, se = res.radiance, res.stderr
    np.savez(mc_f, mean=mc, se=se)
    print(f"MC {time.time() - t:.0f} s")
e0 = float(np.asarray(pm.solar_irradiance)[0])
mc, se = mc[:, 0] / e0, se[:, 0] / e0
p = dust_peak_only(sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM)))
s = replace(QUALITIES["final"].settings, exact=True, **bt._parse_variant(os.environ.get("VARIANT", "")))
m = mm.SkyMarcher(p, sc.elev, bt.SUN_AZIMUTH, 0.0, s)
sr = m.radiance(dirs)
k = int(np.argmin(np.abs(np.asarray(p.wavelengths_nm) - WL)))
r = sr.radiance[:, k] / p.solar_irradiance[k]
rel = r / mc - 1
print(f"{sc.name} peak-only dust, {WL:g} nm, {tag}: mean {100 * rel.mean():+.2f} % (+- {100 * np.sqrt((se ** 2 / mc ** 2).sum()) / rel.size:.2f})")
for i, n in enumerate(names):
    print(f"{n} | marcher/MC-1 {100 * rel[i]:+.2f} % | se {100 * se[i] / mc[i]:.2f} % | single share {100 * sr.single[i, k] / sr.radiance[i, k]:.0f} %")
