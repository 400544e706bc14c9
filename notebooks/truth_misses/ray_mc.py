"""Rayleigh + ozone (no aerosol) at a sun elevation: MC vs marcher (final, + variants) at a few
views; the MC is cached in $OUT/ray_mc_<sun>.npz (grows with each run).
usage: ray_mc.py sun n_paths [variants ';'-separated]"""
import sys, time, os
from dataclasses import replace
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel import Atmosphere
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
from skymodel.validation.montecarlo import trace_radiance
from skymodel.validation.truth import view_directions
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
sun = float(sys.argv[1]); n = int(sys.argv[2]); variants = sys.argv[3] if len(sys.argv) > 3 else ""
views = np.array([(0, 0), (60, 90), (85, 0), (85, 90), (85, 180), (89, 0), (89, 90), (89, 180), (88, 45), (70, 135)], float)
dirs = view_directions(views, 180.0)
atm = Atmosphere(location="rural", month=6, aerosol="none", stratospheric="none")
prof = atm.optical_profile(list(bt.MC_WAVELENGTHS_NM))
f = f"{OUT}/ray_mc_{sun:g}.npz"
if n > 0:
    t = time.perf_counter()
    old = dict(np.load(f)) if os.path.exists(f) else None
    seed = int(old["seed"]) + 1 if old else 1
    res = trace_radiance(prof, dirs, sun, 180.0, n_paths=n, seed=seed)
    if old:
        no = float(old["n"]); tot = no + n
        mean = (old["mean"] * no + res.radiance * n) / tot
        se = np.sqrt((old["se"] * no) ** 2 + (res.stderr * n) ** 2) / tot
    else:
        tot, mean, se = n, res.radiance, res.stderr
    np.savez(f, mean=mean, se=se, n=tot, seed=seed)
    print(f"MC sun {sun:g}: +{n} paths ({time.perf_counter() - t:.0f} s), total {tot}", flush=True)
z = np.load(f)
e0 = np.asarray(prof.solar_irradiance)
truth, se = z["mean"] / e0, z["se"] / e0
mprof = atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
wl = np.asarray(mprof.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
rows = {}
for v in [""] + [x for x in variants.split(";") if x]:
    s = replace(QUALITIES["final"].settings, **bt._parse_variant(v))
    t = time.perf_counter()
    r = SkyMarcher(mprof, sun, 180.0, 0.0, s).radiance(dirs).radiance
    rows[v or "final"] = r[:, idx] / np.asarray(mprof.solar_irradiance)[idx][None, :]
    print(f"  marcher {v or 'final'}: {time.perf_counter() - t:.0f} s", flush=True)
print(f"Rayleigh+ozone, sun {sun:g}, MC {int(z['n'])} paths: view | " + " | ".join(rows) + " (%, 450/550/650) | MC se")
for i, v in enumerate(views):
    print(f"{bt.view_label(v)} | " + " | ".join("/".join(f"{100*x:+.2f}" for x in r[i] / truth[i] - 1) for r in rows.values())
          + " | " + "/".join(f"{100*x:.2f}" for x in se[i] / truth[i]))
for k, r in rows.items():
    rel = r / truth - 1
    print(f"{k}: mean " + "/".join(f"{100*x:+.2f}" for x in rel.mean(0)) + " median abs " + "/".join(f"{100*x:.2f}" for x in np.median(np.abs(rel), 0)))
