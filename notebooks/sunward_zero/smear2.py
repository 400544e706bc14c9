"""Magnitude test: the cut peak's 2D smear minus its elevation-only (1D, peak_diffuse's)
smear, applied to the sky the observer sees, at view points (L(P, u) ~ L_obs(u))."""
import os
import sys
import numpy as np
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
from skymodel.render.peak_diffuse import peak_of  # noqa: E402
scene, views = sys.argv[1], sys.argv[2].split(",")
KM = float(os.environ.get("KM", "1e9"))
sc, prof, wl, idx = su.scene(scene)
m = su.marcher(sc, prof)
SE, SA = 0.25, 0.5
els = np.arange(-14.0, 20.0 + 1e-9, SE) + SE / 2; azs = np.arange(-20.0, 62.0 + 1e-9, SA)
EL, AZ = np.meshgrid(els, azs, indexing="ij")
hor, side, up, vec = su.sun_frame(m)
D = vec(EL, AZ).reshape(-1, 3)
L = (m.radiance(D).radiance[:, idx] / prof.solar_irradiance[idx]).reshape(EL.shape + (3,))
med = m.medium
peaks = peak_of(prof, med)[:, :, idx]
ang = np.asarray(prof.aerosol_phase_angles_deg, float)
dOm = np.cos(np.radians(EL)) * np.radians(SE) * np.radians(SA)
truth, _, base = su.truth_and_base(sc)
for vname in views:
    i, d = su.view(sc, vname)
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
