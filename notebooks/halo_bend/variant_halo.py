"""march bench_truth's views at final + a variant; save $OUT/var_<scene>_<tag>.npz.
usage: variant.py scenes tag 'field=value,...'"""
import sys, time
from dataclasses import replace
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
import os
sys.path.insert(0, "notebooks/halo_bend")
import halo_patch
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
scenes, tag, var = sys.argv[1], sys.argv[2], (sys.argv[3] if len(sys.argv) > 3 else "")
base = sys.argv[4] if len(sys.argv) > 4 else "final"
for name in scenes.split(","):
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
    s = replace(QUALITIES[base].settings, **bt._parse_variant(var))
    halo_patch.install(prof, s)
    t = time.perf_counter()
    m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s)
    r = m.radiance(sc.dirs).radiance
    secs = time.perf_counter() - t
    out = r[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :]
    np.savez(f"{OUT}/var_{sc.name}_{tag}.npz", r=out, views=sc.views, angle=sc.angle, secs=secs,
             solve=m.timings.get("multiple_scattering_s", 0.0))
    print(f"{sc.name} {tag} ({var or base}): {secs:.1f} s, solve {m.timings.get('multiple_scattering_s', 0):.1f} s", flush=True)
