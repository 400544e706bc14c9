"""March bench_truth's views at ``final`` with another share of the solver's sun-angle
nodes below the horizon (multiple_scattering.sun_elevation_nodes), and save them as
variant.py does, for cmp.py.

    TRUTH_CACHE=/work/cache/truth TRUTH_MISSES_OUT=/tmp/tm python notebooks/truth_misses/sun_nodes.py rural:-4,rural:5 neg45 0.45
    TRUTH_CACHE=... TRUTH_MISSES_OUT=/tmp/tm python notebooks/truth_misses/cmp.py rural:-4 fin,neg45

(the share was 10/32 = 0.31 before SUN_NODES_BELOW_SHARE; ``fin`` from
``variant.py <scene> fin "" final``)."""
import os
import sys
import time
from functools import partial

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
from skymodel.render import multiple_scattering as msm  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402

OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")
os.makedirs(OUT, exist_ok=True)
scenes, tag, share = sys.argv[1], sys.argv[2], float(sys.argv[3])
msm.sun_elevation_nodes = partial(msm.sun_elevation_nodes, below_share=share)
print("final's sun nodes:", np.round(msm.sun_elevation_nodes(QUALITIES["final"].settings.table_mus), 2).tolist())
for name in scenes.split(","):
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
    prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm)
    idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
    t = time.perf_counter()
    m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, QUALITIES["final"].settings)
    r = m.radiance(sc.dirs).radiance
    secs = time.perf_counter() - t
    out = r[:, idx] / np.asarray(prof.solar_irradiance)[idx][None, :]
    np.savez(f"{OUT}/var_{sc.name}_{tag}.npz", r=out, views=sc.views, angle=sc.angle, secs=secs,
             solve=m.timings.get("multiple_scattering_s", 0.0))
    print(f"{sc.name} {tag} (below-horizon share {share:g}): {secs:.1f} s", flush=True)
