"""March bench_truth's views at `final` with the solver's lowest altitude interval split into
SPLIT equal ones (skymodel.render.multiple_scattering.GROUND_SPLIT; 1 = the blended grid as it was
before 89c9d2a) and N altitude nodes; save $TRUTH_MISSES_OUT/var_<scene>_<tag>.npz for
notebooks/truth_misses/cmp.py.

usage: split_variant.py scenes tag SPLIT [N]      (N default: final's 24)
"""
import os
import sys
import time
from dataclasses import replace

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
import skymodel.render.multiple_scattering as ms  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
scenes, tag, split = sys.argv[1], sys.argv[2], int(sys.argv[3])
ms.GROUND_SPLIT = split
s = QUALITIES["final"].settings
if len(sys.argv) > 4:
    s = replace(s, table_altitudes=int(sys.argv[4]))
for name in scenes.split(","):
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm)
    idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
    t = time.perf_counter()
    m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s)
    r = m.radiance(sc.dirs).radiance
    secs = time.perf_counter() - t
    np.savez(f"{OUT}/var_{sc.name}_{tag}.npz", r=r[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :],
             views=sc.views, angle=sc.angle, secs=secs, solve=m.timings.get("multiple_scattering_s", 0.0))
    print(f"{sc.name} {tag}: lowest nodes {np.round(m.field.h_nodes[:5]).astype(int)} m, {secs:.1f} s "
          f"(solve {m.timings.get('multiple_scattering_s', 0):.1f} s)", flush=True)
