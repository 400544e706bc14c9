"""The marcher against the Monte Carlo tracer for the paper's desert (issue 20's known limit).

    .venv/bin/python notebooks/aerosol_models_vs_aeronet/marcher_vs_mc_desert.py     # ~1 min

Sun 20 deg, the six views of tests/test_marcher.py, 450 and 650 nm: the paper's desert at AOD
0.27 (4000 paths) and at its table AOD 2.33 (40000 paths). Prints marcher / MC - 1 and the MC
standard error, in percent.
"""
import sys, time
import numpy as np
from skymodel import Atmosphere
from skymodel.render.marcher import SkyMarcher, MarchSettings
from skymodel.validation.montecarlo import trace_radiance
from skymodel.render.rays import direction_from_angles
REAL_VIEWS = ((0.0, 0.0), (45.0, 0.0), (45.0, 180.0), (80.0, 0.0), (80.0, 180.0), (88.0, 180.0))
d = direction_from_angles(np.array([v[0] for v in REAL_VIEWS]), np.array([180.0 + v[1] for v in REAL_VIEWS]))
for aod, n in ((0.27, 4000), (None, 40000)):
    t = time.time()
    prof = Atmosphere(location="desert", month=6, aod550=aod).optical_profile((450.0, 650.0))
    mc = trace_radiance(prof, d, 20.0, 180.0, n_paths=n, seed=31)
    r = SkyMarcher(prof, 20.0, 180.0, 0.0, MarchSettings(exact=True)).radiance(d).radiance
    rel = r / mc.radiance - 1.0; se = mc.stderr / mc.radiance
    print("aod", aod, "paths", n, f"{time.time()-t:.0f}s")
    print(" rel %", np.round(100 * rel, 1).tolist()); print(" se %", np.round(100 * se, 1).tolist())
    print(" within 4se+1%:", bool(np.all(np.abs(rel) <= 4 * se + 0.01)), " mean rel", round(100*rel.mean(),1))
