"""Magnitude test: the cut peak at view points smearing the marcher-only light (single +
peak aureole) as the observer sees it around the sun (in-scatter only)."""
import sys, os
import numpy as np
from dataclasses import replace
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.peak_diffuse import peak_of
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
scene, views = sys.argv[1], sys.argv[2].split(",")
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
wl = np.asarray(prof.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
fin = replace(QUALITIES["final"].settings, exact=True)
m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, fin)
m0 = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, replace(fin, peak_aureole=False))
STEP = 0.25
els = np.arange(-0.125 + STEP, 16.0, STEP); azs = np.arange(-20.0, 30.0 + 1e-9, STEP)
EL, AZ = np.meshgrid(els, azs, indexing="ij")
sun = m.sun / np.linalg.norm(m.sun)
up = np.array([0.0, 0.0, 1.0]); hor = sun - sun[2] * up; hor /= np.linalg.norm(hor); side = np.cross(up, hor)
def vec(el, az):
    el, az = np.radians(el), np.radians(az)
    return (np.cos(el) * np.cos(az))[..., None] * hor + (np.cos(el) * np.sin(az))[..., None] * side + np.sin(el)[..., None] * up
D = vec(EL, AZ).reshape(-1, 3)
r1 = m.radiance(D); r0 = m0.radiance(D)
aur = (r1.multiple - r0.multiple)[:, idx]
single = r1.single[:, idx]
Lmo = (single + aur).reshape(EL.shape + (3,)) / prof.solar_irradiance[idx]
tot = r1.radiance[:, idx].reshape(EL.shape + (3,)) / prof.solar_irradiance[idx]
med = m.medium
peaks = peak_of(prof, med)[:, :, idx]
ang = np.asarray(prof.aerosol_phase_angles_deg, float)
dOm = np.cos(np.radians(EL)) * np.radians(STEP) ** 2
prof_mc, mc = sc.load_mc()
truth = mc["mean"] / np.asarray(prof_mc.solar_irradiance)[None, :]
base = np.load(f"{os.environ.get('TRUTH_MISSES_OUT', '.cache/truth_misses')}/var_{sc.name}_base.npz")["r"]
for vname in views:
    i = [k for k, v in enumerate(sc.views) if f"{v[0]:g}/{v[1]:g}" == vname][0]
    d = sc.dirs[i] / np.linalg.norm(sc.dirs[i])
    v_el = np.degrees(np.arcsin(d[2])); v_az = np.degrees(np.arctan2(d @ side, d @ hor))
    rings = m._rings(np.array([d[2]]))
    h, dt = rings.h[0], rings.dt[0]
    ext = med.extinction.at(h)[:, idx]
    tau = np.cumsum(ext * dt[:, None], axis=0) - 0.5 * ext * dt[:, None]
    tv = np.exp(-tau)
    # angle between v and each grid direction
    cosang = np.clip(D @ d, -1, 1).reshape(EL.shape)
    psi = np.degrees(np.arccos(cosang))
    extra = np.zeros(3)
    for r in range(peaks.shape[0]):
        if not np.any(peaks[r] > 0):
            continue
        sig = med.aerosol[r].at(h)[:, idx]  # true scattering of the regime, 1/m
        K = (sig * tv * dt[:, None]).sum(axis=0)
        for p in range(3):
            pk = np.interp(psi, ang, peaks[r, :, p], right=0.0)  # sr^-1, (p - p_cap)
            extra[p] += K[p] * (pk * Lmo[..., p] * dOm).sum()
    rel = base[i] / truth[i] - 1
    b = base[i]
    print(f"{vname}: base " + "/".join(f"{100*x:+.2f}" for x in rel) + "  extra/base " + "/".join(f"{100*x:.1f}" for x in extra / b)
          + "  new " + "/".join(f"{100*x:+.2f}" for x in (b + extra) / truth[i] - 1), flush=True)
