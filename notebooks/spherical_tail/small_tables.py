"""spherical_orders 2, 3, 4 with and without spherical_tail against every order spherical (20), on
the small tables of tests/test_spherical_transport.py: synthetic AOD 0.2, sun -4 degrees, six views
(the zenith, the sunward horizon at 85-89 degrees, 85 degrees away from the sun); the multiple
scattering's relative difference in % at 450 / 650 nm.
usage: python notebooks/spherical_tail/small_tables.py"""
import time, numpy as np
from dataclasses import replace
from skymodel.validation.synthetic import synthetic_profile
from skymodel.render.marcher import MarchSettings, SkyMarcher
from skymodel.render.rays import direction_from_angles
WL = (450.0, 650.0)
prof = synthetic_profile(WL, aod550=0.2)
d = direction_from_angles(np.array([0.0, 85.0, 88.0, 89.0, 89.0, 85.0]), np.array([0.0, 180.0, 180.0, 180.0, 160.0, 0.0]))
base = MarchSettings(exact=True, table_altitudes=16, table_mu=16, table_phi=8, table_mus=24, ms_wavelength_step_nm=100, peak_aureole=False)
def run(n, tail):
    t = time.perf_counter()
    r = SkyMarcher(prof, -4.0, 180.0, 0.0, replace(base, spherical_orders=n, spherical_tail=tail)).radiance(d).multiple
    return r, time.perf_counter() - t
ref, t20 = run(20, False)
for n, tail in ((2, False), (2, True), (3, False), (3, True), (4, False)):
    r, t = run(n, tail)
    print(n, tail, f"{t:.1f}s (20: {t20:.1f}s)", np.round(100 * (r / ref - 1), 2).tolist())
