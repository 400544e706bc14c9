"""final at sun_exact_deg 8 vs 12 on bench_truth's views: one build per scene, saved to $OUT (final_exact_<scene>.npz)."""
import sys, time
from dataclasses import replace
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
import os
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
for name in sys.argv[1].split(","):
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
    t = time.perf_counter()
    s12 = replace(QUALITIES["final"].settings, sun_exact_deg=12.0)
    m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s12)
    tb = time.perf_counter() - t
    out = {}
    for deg in (8.0, 12.0):
        m.settings = replace(s12, sun_exact_deg=deg)
        t = time.perf_counter()
        r = m.radiance(sc.dirs).radiance
        out[deg] = r[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :]
        print(f"{sc.name}: build {tb:.1f} s, radiance at exact {deg:g}: {time.perf_counter()-t:.2f} s", flush=True)
    np.savez(f"{OUT}/final_exact_{sc.name}.npz", r8=out[8.0], r12=out[12.0], views=sc.views, angle=sc.angle)
    d = out[12.0] / out[8.0] - 1
    for i in np.flatnonzero(np.any(np.abs(d) > 1e-6, axis=1)):
        print(f"  {bt.view_label(sc.views[i])} ({sc.angle[i]:.1f} deg from sun): 12 vs 8: "
              + "/".join(f"{100*x:+.2f}" for x in d[i]) + " %", flush=True)
