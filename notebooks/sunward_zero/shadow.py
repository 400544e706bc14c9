"""Magnitude test: sunlight turned into the aerosols' cut peak above the Earth's shadow and
reaching view points in the shadow (left out by peak_paths), first scattering at P."""
import inspect, os, sys
import numpy as np
from dataclasses import replace
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
import skymodel.render.peak_paths as pp
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
src = inspect.getsource(pp.bent_minus_straight)
src = src.replace("todo = np.nonzero(vis > 1e-6)", "todo = np.nonzero((vis <= 1e-6) & (ee > -14.0))")
src = src.replace("out[i, j] = d / vis[i, j][:, None]", "out[i, j] = d")
assert "ee > -14.0" in src and "out[i, j] = d\n" in src
ns = dict(pp.__dict__); exec(src, ns); bms = ns["bent_minus_straight"]
scene, views = sys.argv[1], sys.argv[2].split(",")
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
wl = np.asarray(prof.wavelengths_nm)
pi = pp.probe_indices(wl); probes = wl[pi]
m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, replace(QUALITIES["final"].settings, exact=True))
med = m.medium
prof_mc, mc = sc.load_mc()
truth = mc["mean"] / np.asarray(prof_mc.solar_irradiance)[None, :]
base = np.load(f"{os.environ.get('TRUTH_MISSES_OUT', '.cache/truth_misses')}/var_{sc.name}_base.npz")["r"]
for vname in views:
    i = [k for k, v in enumerate(sc.views) if f"{v[0]:g}/{v[1]:g}" == vname][0]
    d = sc.dirs[i] / np.linalg.norm(sc.dirs[i])
    rings = m._rings(np.array([d[2]]))
    mus = m._sun_cosines(rings, d[None, None, :])[0, 0]
    h, dt = rings.h[0], rings.dt[0]
    e_sun = np.degrees(np.arcsin(np.clip(mus, -1, 1)))
    ext = med.extinction.at(h)[:, pi]
    tv = np.exp(-(np.cumsum(ext * dt[:, None], axis=0) - 0.5 * ext * dt[:, None]))
    _, B = bms(m.sun_table, prof, med, m.medium.cutoff_deg, h, e_sun[:, None])
    B = B[:, 0, :]  # (S, P) bent beam in the shadow, per unit irradiance
    cos_t = float(d @ m.sun)
    p_cap = m._capped_aerosol_phase(np.array([[cos_t]]))[:, 0, 0][:, pi]  # (R, P) (1-f) p*
    pa = prof.aerosol_phase_at(np.array([[cos_t]]))[:, 0, 0][:, pi]
    ray = med.rayleigh.at(h)[:, pi] * prof.rayleigh_phase(np.array([[cos_t]]))[0, 0][pi]
    cap = ray.copy(); full = ray.copy()
    for r in range(len(med.aerosol)):
        sig = med.aerosol[r].at(h)[:, pi]
        cap += sig * p_cap[r]; full += sig * pa[r]
    w = (tv * dt[:, None] * B)
    add_cap = (w * cap).sum(axis=0); add_full = (w * full).sum(axis=0)
    b = base[i] * 1.0
    bi = np.interp(probes, bt.MC_WAVELENGTHS_NM, b)
    print(f"{vname}: base " + "/".join(f"{100*x:+.2f}" for x in base[i] / truth[i] - 1)
          + "  bent-into-shadow first scattering, % of base at " + ",".join(f"{p:.0f}" for p in probes) + " nm: capped "
          + "/".join(f"{100*x:.2f}" for x in add_cap / bi) + "  full phase " + "/".join(f"{100*x:.2f}" for x in add_full / bi), flush=True)
