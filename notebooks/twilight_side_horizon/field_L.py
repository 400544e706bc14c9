"""The radiance field near the horizon at a point in the bottom layer (twilight): marcher vs MC on the
delta-M medium (the solver's own medium). usage: field_L.py scene alt_m az_from_sun elevs paths"""
import sys, time
from dataclasses import replace
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.marcher import SkyMarcher
from skymodel.render.medium import delta_m_cone_deg
from skymodel.render.quality import QUALITIES
from skymodel.validation.delta_m_medium import delta_m_profile
from skymodel.validation.montecarlo import trace_radiance
scene, alt, daz, elevs, paths = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), [float(x) for x in sys.argv[4].split(",")], int(sys.argv[5])
a, e = scene.split(":"); elev = float(e)
atm = bt.atmosphere(a)
fin = QUALITIES["final"].settings
def dm(p):
    return delta_m_profile(p, delta_m_cone_deg(p, fin.delta_m_cutoff_deg, fin.delta_m_mild_cutoff_deg))
az = np.radians(bt.SUN_AZIMUTH + daz)
el = np.radians(np.array(elevs))
dirs = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
pm = dm(atm.optical_profile(list(bt.MC_WAVELENGTHS_NM)))
t = time.time()
res = trace_radiance(pm, dirs, elev, bt.SUN_AZIMUTH, observer_altitude_m=alt, n_paths=paths, seed=11, estimator="proxy")
print(f"MC {time.time()-t:.0f} s")
e0 = np.asarray(pm.solar_irradiance)[None, :]
mc, se = res.radiance / e0, res.stderr / e0
p2 = dm(atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM)))
wl = np.asarray(p2.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
m = SkyMarcher(p2, elev, bt.SUN_AZIMUTH, alt, fin)
r = m.radiance(dirs)
tot = r.radiance[:, idx] / np.asarray(p2.solar_irradiance)[idx][None, :]
print("elev | MC (1e-6/sr) 450/550/650 | marcher/MC-1 % | se %")
for i, x in enumerate(elevs):
    print(f"{x:+6.2f} | " + "/".join(f"{1e6*v:.3f}" for v in mc[i]) + " | " + "/".join(f"{100*v:+.1f}" for v in tot[i] / mc[i] - 1)
          + " | " + "/".join(f"{100*v:.1f}" for v in se[i] / mc[i]))
