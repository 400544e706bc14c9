"""The peak's light above a low sun: the aureole's one-line (plane-wave) counting against a
small-angle transport in the sun's vertical plane, on the same medium and kernel.

usage: [DZ=25] [INTERP=cubic] [PLANE=1 [N_ALPHA=40]] [SPREAD=1] [TILTS=b1,b2,..] strat2d.py scene wavelength_nm offsets_deg [x_max_km] [step_m]
  e.g. strat2d.py desert:0 650 2,3,4,5,6,8 500 250   (offsets: degrees above the sun)

Both models keep only the aerosols' cut peak as scattering (projected on the elevation axis: the
peak_diffuse kernel, one mixture weighted by column peak depth as the aureole's q); everything
else is extinction (delta-M's scaled extinction), as in the marcher's aureole term. In the sun's
vertical plane, global frame (X toward the sun's azimuth, horizontal at the observer; light
travels toward -X; delta its global elevation, the sun's e; altitude z = Y + X^2 / 2R):

* 2D: the turned light I(X, z, delta) marched from X_max to the observer: each step moves it
  along its rays (z shifts by (delta + X/R) dX, log-linear interpolation in z: exact for the
  exponential fall of grazing light), attenuates it by the scaled extinction and applies the
  peak's turns exactly for the step (along delta in Fourier space: exp(h sigma_p (K - 1))). The
  direct beam is exact (line integrals, the Earth's shadow included) and feeds the turned light
  step by step. Light turned beyond X_max or above the grid's top (TOP_M) is left out.
* one line (the marcher's aureole, skymodel.render.aureole.PeakAureole.correction_table): along
  the view ray every point P gets sigma_p E T*_sun T*_view sum_n e^-tau tau^n/(n+1)! k^{*(n+1)},
  tau the peak depth of P's sun line plus its view path; n = 0 is the single turn, which the
  two models share (the same lines, the exact beam).

Printed per view: the single turn, the two models' light of two or more turns and their ratio,
per unit solar irradiance and per radian of elevation: the elevation marginal (the radiance
integrated over azimuth). PLANE=1: the radiance in the sun's vertical plane instead (sr^-1; the
march at N_ALPHA azimuthal frequencies, see below). SPREAD=1: the first non-peak scattering with
the peak's turns before and after it, one line (peak_spread_table's p_cap * K_tau) against the
transport (marginal)."""
import os
import sys

import numpy as np
from scipy.integrate import cumulative_trapezoid

sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
from skymodel.render.medium import delta_m_cone_deg, factor_medium  # noqa: E402
from skymodel.render.peak_diffuse import STEP_DEG, peak_of, projected_kernel  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402

scene = sys.argv[1]
wl_nm = float(sys.argv[2])
offsets = np.radians([float(v) for v in sys.argv[3].split(",")])
x_max = float(sys.argv[4]) * 1e3 if len(sys.argv) > 4 else 500e3
h = float(sys.argv[5]) if len(sys.argv) > 5 else 250.0

sc, _, _, _ = su.scene(scene)
prof = sc.atm.optical_profile([wl_nm])
s = QUALITIES["final"].settings
cone = delta_m_cone_deg(prof, s.delta_m_cutoff_deg, s.delta_m_mild_cutoff_deg, table_phi=s.table_phi)
med = factor_medium(prof, cone)
R = prof.planet_radius_m
e_sun = np.radians(sc.elev)
t_sun = np.tan(e_sun)

# coefficients (per metre) up to 80 km for the line integrals; the 2D grid is the first TOP_M
dz = float(os.environ.get("DZ", "25"))
TOP_M = 20e3
zc = np.arange(0.0, 80e3 + dz / 2, dz)
sig_a_c = np.stack([lr.at(zc)[:, 0] for lr in med.aerosol])  # (Rg, nzc) aerosol scattering per regime
sig_r_c = sig_a_c * med.forward_fraction[:, 0][:, None]  # its cut peak's part
sig_p_c = sig_r_c.sum(axis=0)
sig_s_c = med.extinction.at(zc)[:, 0] - sig_p_c  # scaled extinction
assert np.allclose(sig_s_c, med.extinction_scaled.at(zc)[:, 0], rtol=1e-6, atol=1e-12), "scaled extinction"
nz = int(round(TOP_M / dz)) + 1
z, sig_p, sig_s = zc[:nz], sig_p_c[:nz], sig_s_c[:nz]

# the mixture kernel on the elevation axis (rad^-1, integral 1), weighted by column peak depth
peaks = peak_of(prof, med)  # (Rg, A, 1)
col = sig_r_c[:, :nz].sum(axis=1)
d_rad = np.radians(STEP_DEG)
i0 = int(round(10.0 / STEP_DEG))  # the sun's node: delta from e - 10 to e + 20 degrees
nd = int(round(30.0 / STEP_DEG)) + 1
delta = e_sun + (np.arange(nd) - i0) * d_rad
nfft = 2 * nd
kpad = np.zeros(nfft)
for r in range(peaks.shape[0]):
    if col[r] <= 0:
        continue
    x, k = projected_kernel(prof.aerosol_phase_angles_deg, peaks[r])
    k = k[:, 0] / (k[:, 0].sum() * d_rad)
    np.add.at(kpad, np.rint(x / d_rad).astype(int) % nfft, k * col[r] / col.sum())
K = np.fft.rfft(kpad) * d_rad  # K(0) = 1


def coeff(zq, c):
    """c at altitudes zq; below the ground opaque (the Earth's shadow), 0 above 80 km."""
    return np.where(np.asarray(zq) < 0.0, 1.0, np.interp(zq, zc, c, right=0.0))


def line_depth(y0, x_from, c, x_to=1500e3, n=3000, slope=t_sun):
    """Integral of c along the sun's line z = y0 + tan(e) X + X^2/2R from X = x_from outward
    (``slope``: another line's tan of elevation instead of the sun's)."""
    xs = np.linspace(x_from, x_to, n)
    return np.trapz(coeff(y0 + slope * xs + xs**2 / (2 * R), c), xs)


def direct_table(c, x_to=1500e3):
    """exp(-tau) of the direct beam at (X, z): tau tabulated on the sun's lines (intercept y0,
    10 m) from X outward (1 km); x scalar or broadcasting with zq."""
    xs = np.arange(0.0, x_to + 1, 1000.0)
    y_lo = min(0.0, -t_sun * x_max) - x_max**2 / (2 * R) - 2e3
    y_hi = TOP_M + max(0.0, -t_sun * x_max) + 2e3
    ys = np.arange(y_lo, y_hi, 10.0)
    cc = coeff(ys[:, None] + t_sun * xs[None, :] + xs[None, :] ** 2 / (2 * R), c)
    seg = 0.5 * (cc[:, 1:] + cc[:, :-1]) * np.diff(xs)[None, :]
    tau = np.concatenate([np.cumsum(seg[:, ::-1], axis=1)[:, ::-1], np.zeros((ys.size, 1))], axis=1)

    def beam(x, zq):
        fy = (np.asarray(zq) - t_sun * x - x**2 / (2 * R) - ys[0]) / 10.0
        iy = np.clip(np.floor(fy).astype(int), 0, ys.size - 2)
        wy = np.clip(fy - iy, 0.0, 1.0)
        x = np.asarray(x, float)
        ix = np.minimum((x / 1000.0).astype(int), xs.size - 2)
        wx = x / 1000.0 - ix
        t = ((tau[iy, ix] * (1 - wy) + tau[iy + 1, ix] * wy) * (1 - wx)
             + (tau[iy, ix + 1] * (1 - wy) + tau[iy + 1, ix + 1] * wy) * wx)
        return np.exp(-t)

    return beam


# --------------------------------------------------------------------------- 2D march
beam = direct_table(sig_s_c + sig_p_c)
ph0 = np.exp(-2j * np.pi * np.arange(K.size) * i0 / nfft)  # a delta at the sun's node


#: INTERP=cubic: the rays' moves read a clamped cubic in log|F| (four nodes) instead of log-linear (two)
CUBIC = os.environ.get("INTERP", "linear") == "cubic"


def move_along_rays(F, X, step, signed=False):
    """F (..., nz, nd) at the plane X moved one step toward the observer along its rays: node z'
    reads z' + (delta + X_mid/R) step, log-linear between altitude nodes (exact for the
    exponential fall of grazing light); nothing from below the ground or above the grid's top.
    ``signed`` (the azimuthal slices, which take both signs): log-linear in |F| where both nodes
    have the same sign, linear where they differ."""
    sh = (delta + (X - 0.5 * step) / R) * step / dz  # in z nodes
    n_int = np.floor(sh).astype(int)
    f = (sh - n_int)[None, :]
    zi = np.arange(z.size)[:, None] + n_int[None, :]
    ok = (zi >= 0) & (zi + 1 < z.size)
    cols = np.arange(nd)[None, :]
    a_ = F[..., np.clip(zi, 0, z.size - 1), cols]
    b_ = F[..., np.clip(zi + 1, 0, z.size - 1), cols]
    la, lb = np.log(np.maximum(np.abs(a_), 1e-300)), np.log(np.maximum(np.abs(b_), 1e-300))
    if CUBIC:  # Catmull-Rom in log|F| through the two nodes either side, clamped to the middle pair's range
        l0 = np.log(np.maximum(np.abs(F[..., np.clip(zi - 1, 0, z.size - 1), cols]), 1e-300))
        l3 = np.log(np.maximum(np.abs(F[..., np.clip(zi + 2, 0, z.size - 1), cols]), 1e-300))
        t2, t3 = f * f, f * f * f
        lm = 0.5 * ((-t3 + 2 * t2 - f) * l0 + (3 * t3 - 5 * t2 + 2) * la + (-3 * t3 + 4 * t2 + f) * lb + (t3 - t2) * l3)
        mag = np.exp(np.clip(lm, np.minimum(la, lb), np.maximum(la, lb)))
    else:
        mag = np.exp(la * (1.0 - f) + lb * f)
    if not signed:
        out = np.where(ok, mag, 0.0)
        out[out < 1e-250] = 0.0
        return out
    same = np.sign(a_) == np.sign(b_)
    return np.where(ok, np.where(same, np.sign(a_) * mag, a_ * (1.0 - f) + b_ * f), 0.0)


def march(Ks, KC=None):
    """The turned light at the observer (S, nd) for kernel spectra Ks (S, nfft/2 + 1) along delta
    (S = 1, the projected kernel: the elevation marginal; else slices of the 2D kernel's
    transform at azimuthal frequencies, see PLANE below). ``KC`` (Rg, nfft/2 + 1), with S = 1:
    also a second population, the light scattered once by the regimes' capped phase functions
    (spectra KC, see SPREAD below) with any peak turns before and after; returns both (2, nd)."""
    Ks = np.atleast_2d(Ks)
    signed = Ks.shape[0] > 1
    I = np.zeros((Ks.shape[0], z.size, nd))
    B = None if KC is None else np.zeros((1, z.size, nd))
    # once scattered by p_cap in a step (per metre of path), summed over the regimes: (nz, .)
    src = None if KC is None else (sig_a_c[:, :nz].T[:, :, None] * KC[None, :, :]).sum(axis=1)
    X = x_max
    while X > 1e-6:
        step = min(h, X)
        xm = X - 0.5 * step
        I = move_along_rays(I, X, step, signed=signed)
        M = np.exp(sig_p[None, :, None] * step * (Ks[:, None, :] - 1.0))
        att = np.exp(-sig_s * step)[None, :, None]
        # the direct beam entering the step (at its source point), turned in it: M less the part never turned
        b0 = (beam(X, z + (e_sun + xm / R) * step) / d_rad)[None, :, None] * ph0
        spec_in = rfft_delta(I)
        if B is not None:  # the turned light and the direct beam, scattered once by p_cap
            B = move_along_rays(B, X, step)
            B = irfft_delta((rfft_delta(B) + (spec_in + b0) * src * step) * att * M)
        I = irfft_delta(spec_in * att * M + b0 * att * (M - np.exp(-sig_p * step)[None, :, None]))
        if not signed:
            I = np.maximum(I, 0.0)
            if B is not None:
                B = np.maximum(B, 0.0)
        X -= step
    return I[:, 0] if B is None else np.concatenate([I[:, 0], B[:, 0]])  # at the observer (z = 0)


def rfft_delta(F):
    """The spectrum along delta of F (..., nd), zero-padded to nfft."""
    pad = np.zeros(F.shape[:-1] + (nfft,))
    pad[..., :nd] = F
    return np.fft.rfft(pad, axis=-1)


def irfft_delta(spec):
    return np.fft.irfft(spec, nfft, axis=-1)[..., :nd]


# --------------------------------------------------------------------------- one line
def view_ray(off, tilt=0.0):
    """Points of the view ray ``off`` above the sun inside the 2D grid: X (m), altitude (m),
    T*_sun T*_view (the scaled transmittances) and the peak depth tau of sun line plus view path.
    ``tilt``: the 'sun line' of each point raised toward the view by tilt * off (TILTS below)."""
    dv = e_sun + off
    xs = np.linspace(0.0, 800e3, 8001)
    zr = np.tan(dv) * xs + xs**2 / (2 * R)
    keep = (zr < z[-1]) & (zr >= 0.0)  # the 2D grid's points only
    xs, zr = xs[keep], zr[keep]
    cp, cs = coeff(zr, sig_p_c), coeff(zr, sig_s_c)
    tv_p = cumulative_trapezoid(cp, xs, initial=0.0)
    tv_s = cumulative_trapezoid(cs, xs, initial=0.0)
    sl = np.tan(e_sun + tilt * off)
    y0 = zr - sl * xs - xs**2 / (2 * R)
    ts_p = np.array([line_depth(y, x0, sig_p_c, slope=sl) for y, x0 in zip(y0, xs)])
    ts_s = np.array([line_depth(y, x0, sig_s_c, slope=sl) for y, x0 in zip(y0, xs)])
    return xs, zr, np.exp(-ts_s - tv_s), ts_p + tv_p


def node(off):
    return i0 + int(round(off / d_rad))


def at_view(spec, off):
    """The inverse transform of spectra (..., nfft/2 + 1) at the node ``off`` above the sun only."""
    phase = np.exp(2j * np.pi * np.arange(K.size) * ((node(off) - i0) % nfft) / nfft) * wts
    return (spec * phase).real.sum(axis=-1) / nfft / d_rad


wts = np.full(K.size, 2.0)
wts[0] = 1.0
wts[-1] = 1.0  # nfft even


def one_line_at(Ks, xs, zr, trans, tau, off):
    """The one-line light of >= 2 turns and of one turn at ``off`` for kernel spectra Ks (S, .)."""
    w = coeff(zr, sig_p_c) * trans
    out_m, out_1 = [], []
    for Kk in np.atleast_2d(Ks):
        # e^-tau (e^(tau K) - 1) / tau, written so that a shadowed point's huge tau gives 0
        tt = np.where(tau > 0, tau, 1e-12)[:, None]
        F = at_view((np.exp(tt * (Kk[None, :] - 1.0)) - np.exp(-tt)) / tt, off)
        k_at = at_view(Kk, off)
        out_m.append(np.trapz(w * (F - np.exp(-tau) * k_at), xs))
        out_1.append(np.trapz(w * np.exp(-tau) * k_at, xs))
    return np.array(out_m), np.array(out_1)


def main():
    """The printout of the module docstring (importing the module sets up the scene only)."""
    print(f"{scene} (sun {sc.elev:g} deg) {wl_nm:.0f} nm, cone {cone:.0f} deg, X_max {x_max / 1e3:.0f} km, "
          f"step {h:.0f} m, dz {dz:g} m; column peak depth {np.trapz(sig_p, z):.3f}, scaled {np.trapz(sig_s, z):.3f}")
    rays = {off: view_ray(off) for off in offsets}
    if os.environ.get("SPREAD"):
        # SPREAD=1 (elevation marginal): the first non-peak scattering (the capped phase functions,
        # within SPREAD_DEG of the sun, projected on the elevation axis) with any number of peak turns
        # before and after it: the one-line count (what peak_spread_table adds to the delta-M first
        # scattering: p_cap * K_tau, tau of sun path plus view path) against the transport, where a
        # second population B (once scattered by p_cap) is marched with the turned light A.
        cut_deg = float(os.environ.get("SPREAD_DEG", "15"))
        ang = prof.aerosol_phase_angles_deg
        capped = med.capped_phase  # (Rg, A, 1) sr^-1
        kc = np.zeros((sig_a_c.shape[0], nfft))
        for r in range(sig_a_c.shape[0]):
            x, k = projected_kernel(ang, np.where(ang[:, None] <= cut_deg, capped[r], 0.0))  # rad^-1
            np.add.at(kc[r], np.rint(x / d_rad).astype(int) % nfft, k[:, 0])
        KC = np.fft.rfft(kc, axis=1) * d_rad  # (Rg, .)
        obsB = march(K, KC)[1]
        print(" above sun   unspread   1line(p_cap*K)  2D        2D/1line  (first non-peak scattering, marginal)")
        for off in offsets:
            xs, zr, trans, tau = rays[off]
            spread = np.exp(np.where(tau > 0, tau, 0.0)[:, None] * (K[None, :] - 1.0))  # K_tau, (points, .)
            ol = un = 0.0
            for r in range(sig_a_c.shape[0]):
                wr = coeff(zr, sig_a_c[r]) * trans
                ol += np.trapz(wr * at_view(KC[r][None, :] * spread, off), xs)
                un += np.trapz(wr * at_view(KC[r], off), xs)
            j = node(off)
            print(f"{np.degrees(off):9.2f} {un:10.4g} {ol:12.4g} {obsB[j]:10.4g} {obsB[j] / ol:9.3f}")
        return
    if not os.environ.get("PLANE"):
        obs = march(K)[0]
        print(" above sun   single    2D >=2  1line >=2  2D/1line   (elevation marginal, per unit E, rad^-1)")
        for off in offsets:
            m1, s1 = one_line_at(K, *rays[off], off)
            j = node(off)
            print(f"{np.degrees(off):9.2f} {s1[0]:9.4g} {obs[j] - s1[0]:10.4g} {m1[0]:10.4g} {(obs[j] - s1[0]) / m1[0]:9.3f}")
        tilts = [float(v) for v in os.environ.get("TILTS", "").split(",") if v]
        if tilts:
            # TILTS=b1,b2,..: the one-line count with every point's sun line (peak depth and scaled
            # transmittance) raised toward the view by b * offset, the mean bend of the turned light
            print(" above sun  " + "".join(f"  2D/tilt{b:<5g}" for b in tilts) + "  (>= 2 turns, marginal)")
            for off in offsets:
                j = node(off)
                row = []
                for b in tilts:
                    m1, s1 = one_line_at(K, *(rays[off] if b == 0 else view_ray(off, b)), off)
                    row.append((obs[j] - s1[0]) / m1[0])
                print(f"{np.degrees(off):9.2f}  " + "".join(f"{v:13.3f}" for v in row))
        return

    # PLANE=1: the radiance in the sun's vertical plane (azimuth 0): the 2D kernel q (the aureole's,
    # marcher.peak_shape) has the Hankel transform Q(|omega|); at azimuthal frequency w_a the march
    # along delta runs with Q(sqrt(w_d^2 + w_a^2)) (the projection-slice theorem: w_a = 0 is the
    # marginal), and the value at azimuth 0 is (1/pi) int_0^inf (slice) dw_a (even in w_a).
    from skymodel.render.marcher import peak_shape  # noqa: E402

    machine, q2, Qk = peak_shape(prof, med, cone, prof.top_altitude_m)
    # the peak's core (a tenth of a degree) is finer than the delta grid's Nyquist frequency: both
    # models take the kernel blurred by a Gaussian of BLUR_DEG (harmless degrees from the sun)
    blur = np.radians(float(os.environ.get("BLUR_DEG", "0.1")))
    Qk = Qk * np.exp(-0.5 * (machine.k * blur) ** 2)[:, None]
    w_d = 2.0 * np.pi * np.arange(K.size) / (nfft * d_rad)


    def Q_at(k):
        """Q at |omega| (rad^-1); below 1 rad^-1 the transform rings at its grid's low end (0.59 at
        1e-3), where Q is 1 to 1e-4: 1 there."""
        good = machine.k >= 1.0
        return np.interp(np.log(np.maximum(k, 1e-9)), np.log(machine.k[good]), Qk[good, 0], left=1.0)


    low = w_d < 0.2 / blur
    print(f"projection-slice check (w_d < {0.2 / blur:.0f} rad^-1): max |K_marginal - Q(w_d)| = "
          f"{np.max(np.abs(K.real - Q_at(w_d))[low]):.2e}")
    n_a = int(os.environ.get("N_ALPHA", "40"))
    w0, w_top = 20.0, float(os.environ.get("W_TOP", "2500"))
    u = np.linspace(0.0, np.arcsinh(w_top / w0), n_a)
    w_a = w0 * np.sinh(u)
    dw = w0 * np.cosh(u) * (u[1] - u[0])
    dw[[0, -1]] *= 0.5
    Ks = Q_at(np.sqrt(w_d[None, :] ** 2 + w_a[:, None] ** 2)).astype(complex)
    obs = march(Ks)  # (n_a, nd)
    plane = (obs * dw[:, None]).sum(axis=0) / np.pi  # sr^-1
    print(" above sun   single    2D >=2  1line >=2  2D/1line   1line(Hankel) slices/Hankel (sun's vertical plane, sr^-1)")
    tau_g = np.concatenate([[0.0], np.geomspace(1e-3, 60.0, 200)])
    for off in offsets:
        xs, zr, trans, tau = rays[off]
        m_sl, s_sl = one_line_at(Ks, xs, zr, trans, tau, off)
        m_pl, s_pl = (m_sl * dw).sum() / np.pi, (s_sl * dw).sum() / np.pi
        C = machine.correction_table(q2, tau_g, np.array([off]), qk=Qk)[0, :, 0]  # (n_tau,) sr^-1
        m_h = np.trapz(coeff(zr, sig_p_c) * trans * np.interp(tau, tau_g, C), xs)
        j = node(off)
        print(f"{np.degrees(off):9.2f} {s_pl:9.4g} {plane[j] - s_pl:10.4g} {m_pl:10.4g} {(plane[j] - s_pl) / m_pl:9.3f}"
              f" {m_h:12.4g} {m_pl / m_h:9.3f}")


if __name__ == "__main__":
    main()
