"""The light turned twice by desert dust's cut forward peak, 0.3-30 degrees from the sun, three
ways: the earlier transform (direct quadrature on a linear angle grid of 0.05 degrees to 60 degrees,
1600 wavenumbers crowded toward 0, as skymodel.render.aureole had it before 60acfad), today's
FFTLog transform on a log grid (skymodel.render.aureole.PeakAureole), and the same convolution
sampled (two deflections drawn from the peak, linear in angle as the medium reads it, added as
vectors in the plane, counted in rings of +-0.25 degrees; skymodel.validation.peak_sampling).

usage: twice_turned.py [location] [aod550] [cone_deg]      (default desert 0.5 12)
"""
import sys

import numpy as np
from scipy.special import j0

from skymodel import Atmosphere
from skymodel.render.aureole import PeakAureole, peak_part
from skymodel.validation.peak_sampling import sampled_twice_turned

loc = sys.argv[1] if len(sys.argv) > 1 else "desert"
aod = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
cone = float(sys.argv[3]) if len(sys.argv) > 3 else 12.0
prof = Atmosphere(location=loc, month=6, aod550=aod).optical_profile([450.0, 550.0, 650.0])
ang = prof.aerosol_phase_angles_deg
peak = peak_part(ang, prof.aerosol_phase, cone)[0]  # the first (dominant) regime, (A, W)
out_deg = np.array([0.3, 1, 2, 3, 5, 6, 8, 10, 12, 15, 20])
out = np.radians(out_deg)


def linear_grid(n_theta=1200, n_k=1600, theta_max=np.radians(60.0)):
    """q*q by the earlier machinery: rings on a linear grid, j0 quadrature both ways."""
    th = np.linspace(0.0, theta_max, n_theta)
    dth = th[1] - th[0]
    ring = 2 * np.pi * th * dth
    ring[-1] *= 0.5
    k = np.pi / dth * np.linspace(0.0, 1.0, n_k) ** 2
    dk = np.gradient(k)
    dk[[0, -1]] *= 0.5
    q = np.stack([np.interp(th, np.radians(ang), peak[:, w], right=0.0) for w in range(peak.shape[1])], 1)
    q /= ring @ q
    qk = (j0(np.outer(th, k)) * ring[:, None]).T @ q
    return (j0(np.outer(out, k)) * k * dk / (2 * np.pi)) @ qk**2


def log_grid(tau=1e-4):
    """q*q from today's machinery: its n >= 2 sum at a small peak optical depth is
    exp(-tau) tau^2 / 2 q*q (the n = 3 term adds tau / 3 of it)."""
    m = PeakAureole()
    q = m.shape_on_grid(ang, peak)
    taus = np.full(peak.shape[1], tau)
    return m.multiple(q, taus, out) / (np.exp(-tau) * tau * tau / 2)


def sampled(n=20_000_000, seed=1):
    rng = np.random.default_rng(seed)
    return np.stack([sampled_twice_turned(ang, peak[:, w], cone, out, n, rng, n_fine=400001)[0]
                     for w in range(peak.shape[1])], 1)


lin, log, mc = linear_grid(), log_grid(), sampled()
print(f"{loc} AOD {aod}, cone {cone:g} deg: q*q (sr^-1 per unit peak energy squared)")
print("angle (deg) | " + " | ".join(f"{w:g} nm: sampled, log grid, linear grid" for w in prof.wavelengths_nm))
for i, a in enumerate(out_deg):
    print(f"{a:g} | " + " | ".join(f"{mc[i, w]:.4g}, {log[i, w]:.4g} ({100 * (log[i, w] / mc[i, w] - 1):+.1f} %), "
                                   f"{lin[i, w]:.4g} ({100 * (lin[i, w] / mc[i, w] - 1):+.1f} %)"
                                   for w in range(peak.shape[1])))
