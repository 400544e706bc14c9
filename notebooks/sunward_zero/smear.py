"""Magnitude test: the cut peak at view points smearing the marcher-only light (single +
peak aureole) as the observer sees it around the sun (in-scatter only)."""
import os
import sys
import numpy as np
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
from skymodel.render.peak_diffuse import peak_of  # noqa: E402
scene, views = sys.argv[1], sys.argv[2].split(",")
sc, prof, wl, idx = su.scene(scene)
m = su.marcher(sc, prof)
m0 = su.marcher(sc, prof, peak_aureole=False)
STEP = 0.25
els = np.arange(-0.125 + STEP, 16.0, STEP); azs = np.arange(-20.0, 30.0 + 1e-9, STEP)
EL, AZ = np.meshgrid(els, azs, indexing="ij")
hor, side, up, vec = su.sun_frame(m)
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
truth, _, base = su.truth_and_base(sc)
for vname in views:
    i, d = su.view(sc, vname)
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
