"""Prototype: how much more halo light reaches a point near the ground when the
peak-scattered sunlight's bent paths are followed, against delta-M's straight sun path.
usage: ratio.py aerosol sun_elev_deg"""
import sys
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render.medium import factor_medium
from skymodel.render.peak_diffuse import peak_of, projected_kernel

R_E = 6_371_000.0
aer, es = sys.argv[1], float(sys.argv[2])
atm = bt.atmosphere(aer)
prof = atm.optical_profile([450.0, 550.0, 650.0])
med = factor_medium(prof, 12.0)
z = np.asarray(prof.altitudes_m, float)
top = float(prof.top_altitude_m)
hh = np.linspace(0, top, 4001)
ext = med.extinction.at(hh)  # (n, W)
exs = med.extinction_scaled.at(hh)
sig_p = sum(a.at(hh) - b.at(hh) for a, b in zip(med.aerosol, med.aerosol_scaled))
x, k = projected_kernel(prof.aerosol_phase_angles_deg, peak_of(prof, med)[0])
kn = k / k.sum(axis=0)  # weights over x per wavelength
print("f", med.forward_fraction[0], "kernel half width deg", np.degrees(x[-1]))


def coef(c, h):
    return np.stack([np.interp(h, hh, c[:, w]) for w in range(c.shape[1])], -1)


def depth_to_top(h0, elev_deg, c, n=3000):
    """optical depth from altitude h0 (array) along elevation elev (array, deg) to TOA; inf if ground."""
    r0 = R_E + h0
    mu = np.sin(np.radians(elev_deg))
    # distance to top
    d = -r0 * mu + np.sqrt((r0 * mu) ** 2 + (R_E + top) ** 2 - r0 ** 2)
    s = np.linspace(0, 1, n)[:, None] * d[None, :]
    h = np.sqrt(r0[None] ** 2 + s ** 2 + 2 * r0[None] * s * mu[None]) - R_E
    hit = (h.min(axis=0) < -1.0)
    cc = coef(c, np.clip(h, 0, top))  # (n, m, W)
    tau = np.trapz(cc, s[..., None], axis=0)
    tau[hit] = np.inf
    return tau


for h0 in [0.0, 200.0, 1000.0, 3000.0]:
    T = np.exp(-depth_to_top(np.array([h0]), np.array([es]), ext))[0]
    Ts = np.exp(-depth_to_top(np.array([h0]), np.array([es]), exs))[0]
    tp = depth_to_top(np.array([h0]), np.array([es]), sig_p)[0]
    # bent: from P along elevation es + x, distance s, Q; sun elevation at Q is es + angle subtended
    xs = x
    smax = 600e3
    s = np.concatenate([[0], np.geomspace(10, smax, 400)])
    out = np.zeros(3)
    straight = Ts - T  # the all-orders halo of the straight path (delta-M)
    for xi, xv in enumerate(xs):
        e = es + np.degrees(xv)
        mu = np.sin(np.radians(e))
        r0 = R_E + h0
        rq = np.sqrt(r0 ** 2 + s ** 2 + 2 * r0 * s * mu)
        hq = rq - R_E
        # local sun elevation at Q: the sun direction fixed; Q's vertical rotated by the angle at Earth's centre
        # angle between P's vertical and Q's vertical along the plane (toward sun if cos(e)>0)
        gamma = np.arctan2(s * np.cos(np.radians(e)), r0 + s * mu)
        esq = es + np.degrees(gamma)
        ok = (hq >= 0) & (hq <= top)
        # stop at the ground: first point below ground ends the line
        if np.any(hq < 0):
            ok &= np.arange(s.size) < np.argmax(hq < 0)
        if not ok.any():
            continue
        tq = depth_to_top(hq[ok], esq[ok], ext, n=800)  # (m, W): the direct beam to Q, true extinction
        # T*(Q->P): cumulative along the line
        cq = coef(exs, hq[ok])
        sk = s[ok]
        cum = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (cq[1:] + cq[:-1]) * np.diff(sk)[:, None], 0)])
        integrand = coef(sig_p, hq[ok]) * np.exp(-tq) * np.exp(-cum)
        out += kn[xi] * np.trapz(integrand, sk[:, None], axis=0)
    print(f"h {h0:6.0f} m sun {es:g}: T {T} T* {Ts} tau_p {tp}\n   halo straight {straight} bent {out} ratio {out / straight}"
          f"  (T*-T) {Ts - T}  direct+halo straight {Ts} bent {T + (Ts - T) * out / straight}")
