"""The peak's turns above a low sun, counted along chords: a cheaper model than strat2d's march.

usage: [DZ=50] chord.py scene wavelength_nm offsets_deg [x_max_km] [step_m]
  e.g. DZ=50 chord.py desert:0 650 2,3,4,5,6,8 300 1000

A chain of two or more peak turns (strat2d's population: only the cut peak scatters, everything else
is the scaled extinction) has a first turn at Q, where the direct beam arrives along the sun's straight
line (exact: the Earth's shadow, the air of that line), and a last turn at P on the view ray, after
which it reaches the eye through the true extinction. The chord model puts every turn between them on
the straight line from Q to P: light arrives at P from global elevation d_u with

    L(P, d_u) = int ds sigma_p(Q) T_beam(Q) T*(Q -> P) [k * K_tau](d_u - e),   Q = P + s (cos d_u, sin d_u),

tau the chord's peak depth from Q to P, K_tau = sum_m e^-tau tau^m / m! k^{*m} (the turns between Q and
P, any number) and k the peak projected on the elevation axis (the elevation marginal, as strat2d's
default); the view then gets int dl sigma_p(P) T(O <- P) int d(d_u) k(d_v - d_u) L(P, d_u). Unlike the
tilted line (strat2d TILTS), which read the whole chain along one raised line, the first turn sees the
real sun line; unlike strat2d's transport, the turns between do not bend the path.

Printed per view offset above the sun (elevation marginal, per unit solar irradiance, rad^-1): the 2D
transport (strat2d.march, the same numerics), the one-line count, the chord model and the ratios."""
import os
import sys
import time

import numpy as np

sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import strat2d as s2  # noqa: E402  (sets up the scene from sys.argv as strat2d's command line)


def kernel_table(taus):
    """[k * K_tau] on the offsets of strat2d's delta grid (periodic, index 0 = no turn): (n_tau, nfft),
    rad^-1; and k itself (nfft,)."""
    spec = s2.K[None, :] * np.exp(taus[:, None] * (s2.K[None, :] - 1.0))
    g = np.fft.irfft(spec, s2.nfft, axis=-1) / s2.d_rad
    k = np.fft.irfft(s2.K, s2.nfft) / s2.d_rad
    return np.maximum(g, 0.0), np.maximum(k, 0.0)


def chord_light(off, du_lo_deg=-6.0, du_hi_deg=14.0, ds=None):
    """The chord model's light of two or more turns at ``off`` above the sun (rad^-1)."""
    ds = s2.h if ds is None else ds
    d_v = s2.e_sun + off
    xp = np.arange(0.0, s2.x_max, s2.h) + 0.5 * s2.h
    zp = np.tan(d_v) * xp + xp**2 / (2 * s2.R)
    keep = zp < s2.TOP_M
    xp, zp = xp[keep], zp[keep]
    dl = s2.h / np.cos(d_v)
    sp_p = s2.coeff(zp, s2.sig_p_c)
    ext_v = sp_p + s2.coeff(zp, s2.sig_s_c)
    t_view = np.exp(-(np.cumsum(ext_v) - 0.5 * ext_v) * dl)
    j_lo = s2.i0 + int(round(np.radians(du_lo_deg) / s2.d_rad))
    j_hi = s2.i0 + int(round(np.radians(du_hi_deg) / s2.d_rad))
    ju = np.arange(max(j_lo, 0), min(j_hi, s2.nd - 1) + 1)
    d_u = s2.delta[ju]
    taus = np.geomspace(1e-4, 40.0, 160)  # below 1e-4 the first node's value
    g, k = kernel_table(taus)
    ltau = np.log(taus)
    g = g[:, (ju - s2.i0) % s2.nfft]  # (n_tau, U): the chord's first turn plus the turns between
    k_view = k[(s2.i0 + int(round(off / s2.d_rad)) - ju) % s2.nfft]  # the last turn into the view, (U,)
    total = 0.0
    for x0, z0, sp, tv in zip(xp, zp, sp_p, t_view):
        if sp * tv <= 0.0:
            continue
        s = np.arange(0.5 * ds, max(s2.x_max - x0, ds), ds)  # along the chord, horizontally
        xq = x0 + s[None, :]
        zq = z0 + np.tan(d_u)[:, None] * s[None, :] + (xq**2 - x0**2) / (2 * s2.R)  # (U, S)
        cp = s2.coeff(zq, s2.sig_p_c)
        cs = s2.coeff(zq, s2.sig_s_c)
        step = ds / np.cos(d_u)[:, None]
        tau_p = (np.cumsum(cp, axis=1) - 0.5 * cp) * step
        tau_s = (np.cumsum(cs, axis=1) - 0.5 * cs) * step
        beam = s2.beam(np.broadcast_to(xq, zq.shape), zq)
        src = cp * beam * np.exp(-tau_s) * step  # (U, S)
        # the angular factor at the chord's peak depth, linear in log(tau)
        lt = np.log(np.maximum(tau_p, taus[0]))
        f = np.clip((lt - ltau[0]) / (ltau[1] - ltau[0]), 0.0, ltau.size - 1.000001)
        i = f.astype(int)
        w = f - i
        col = np.arange(ju.size)[:, None]
        ang = g[i, col] * (1 - w) + g[i + 1, col] * w
        arrive = (src * ang).sum(axis=1)  # L(P, d_u) per unit E, (U,)
        total += sp * tv * dl * np.sum(k_view * arrive) * s2.d_rad
    return total


def main():
    t0 = time.perf_counter()
    obs = s2.march(s2.K)[0]
    t_march = time.perf_counter() - t0
    print(f"{s2.scene} {s2.wl_nm:.0f} nm, dz {s2.dz:g} m, step {s2.h:g} m, X_max {s2.x_max / 1e3:.0f} km; "
          f"2D march {t_march:.1f} s")
    print(" above sun    2D >=2   1line >=2   chord >=2  chord/2D  1line/2D   chord s")
    for off in s2.offsets:
        m1, s1 = s2.one_line_at(s2.K, *s2.view_ray(off), off)
        two = obs[s2.node(off)] - s1[0]
        t0 = time.perf_counter()
        ch = chord_light(off)
        print(f"{np.degrees(off):9.2f} {two:10.4g} {m1[0]:11.4g} {ch:11.4g} {ch / two:9.3f} {m1[0] / two:9.3f}"
              f" {time.perf_counter() - t0:9.1f}")


if __name__ == "__main__":
    main()
