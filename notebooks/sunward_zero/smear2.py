"""Magnitude test: the cut peak's 2D smear minus its elevation-only (1D, peak_diffuse's)
smear, applied to the sky the observer sees, at view points (L(P, u) ~ L_obs(u))."""
import sys, os
import numpy as np
from dataclasses import replace
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.peak_diffuse import peak_of
from skymodel.render.marcher import SkyMarcher
from skymodel.render.quality import QUALITIES
scene, views = sys.argv[1], sys.argv[2].split(",")
KM = float(os.environ.get("KM", "1e9"))
a, e = scene.split(":")
sc = bt.Scene(a, float(e), os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
wl = np.asarray(prof.wavelengths_nm); idx = [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]
m = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, replace(QUALITIES["final"].settings, exact=True))
SE, SA = 0.25, 0.5
els = np.arange(-14.0, 20.0 + 1e-9, SE) + SE / 2; azs = np.arange(-20.0, 62.0 + 1e-9, SA)
EL, AZ = np.meshgrid(els, azs, indexing="ij")
sun = m.sun / np.linalg.norm(m.sun)
up = np.array([0.0, 0.0, 1.0]); hor = sun - sun[2] * up; hor /= np.linalg.norm(hor); side = np.cross(up, hor)
def vec(el, az):
    el, az = np.radians(el), np.radians(az)
    return (np.cos(el) * np.cos(az))[..., None] * hor + (np.cos(el) * np.sin(az))[..., None] * side + np.sin(el)[..., None] * up
D = vec(EL, AZ).reshape(-1, 3)
L = (m.radiance(D).radiance[:, idx] / prof.solar_irradiance[idx]).reshape(EL.shape + (3,))
med = m.medium
peaks = peak_of(prof, med)[:, :, idx]
ang = np.asarray(prof.aerosol_phase_angles_deg, float)
dOm = np.cos(np.radians(EL)) * np.radians(SE) * np.radians(SA)
prof_mc, mc = sc.load_mc()
truth = mc["mean"] / np.asarray(prof_mc.solar_irradiance)[None, :]
base = np.load(f"{os.environ.get('TRUTH_MISSES_OUT', '.cache/truth_misses')}/var_{sc.name}_base.npz")["r"]
for vname in views:
    i = [k for k, v in enumerate(sc.views) if f"{v[0]:g}/{v[1]:g}" == vname][0]
    d = sc.dirs[i] / np.linalg.norm(sc.dirs[i])
    v_el = np.degrees(np.arcsin(d[2])); v_az = abs(np.degrees(np.arctan2(d @ side, d @ hor)))
    rings = m._rings(np.array([d[2]]))
    h, dt, t = rings.h[0], rings.dt[0], rings.t[0]
    ext = med.extinction.at(h)[:, idx]
    tv = np.exp(-(np.cumsum(ext * dt[:, None], axis=0) - 0.5 * ext * dt[:, None]))
    near = (t < KM * 1e3)[:, None]
    psi = np.degrees(np.arccos(np.clip(D @ d, -1, 1))).reshape(EL.shape)
    col = (EL[:, 0] >= v_el - 13) & (EL[:, 0] <= v_el + 13)
    ja = int(np.argmin(np.abs(azs - v_az)))
    extra2, extra1 = np.zeros(3), np.zeros(3)
    for r in range(peaks.shape[0]):
        if not np.any(peaks[r] > 0):
            continue
        K = (med.aerosol[r].at(h)[:, idx] * tv * dt[:, None] * near).sum(axis=0)
        for p in range(3):
            pk = np.interp(psi, ang, peaks[r, :, p], right=0.0)
            f = (pk * dOm).sum()  # the cut share on this grid
            two = (pk * L[..., p] * dOm).sum() - f * L.reshape(-1, 3)[0, p] * 0  # in-scatter
            # 1D: the same peak projected on the elevation axis at the view's own azimuth column
            k1 = (pk * dOm).sum(axis=1)  # (n_el,) projected
            one = (k1 * L[:, ja, p]).sum()
            extra2[p] += K[p] * two; extra1[p] += K[p] * one
    b = base[i]
    diff = extra2 - extra1
    print(f"{vname} (el {v_el:.1f} az {v_az:.1f}): base " + "/".join(f"{100*x:+.2f}" for x in b / truth[i] - 1)
          + "  2D-1D smear % of base " + "/".join(f"{100*x:+.1f}" for x in diff / b)
          + "  new " + "/".join(f"{100*x:+.2f}" for x in (b + diff) / truth[i] - 1), flush=True)
