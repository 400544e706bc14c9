"""The part of the solar aureole that delta-M leaves out: sunlight scattered two or more
times inside the aerosols' forward peaks, in the small-angle approximation.

The multiple-scattering solver truncates every aerosol phase function inside a cone
around the forward direction (delta-M, :mod:`skymodel.render.medium`): light scattered
into the cut peak, a fraction f of aerosol scattering, is treated as not scattered at
all. The marcher puts back the light scattered into the peak exactly once (its single
scattering uses the full phase function and the true extinction). Light scattered two or
more times inside the peak is then missing from the picture: it is neither in the sun
disc (seen through the true extinction) nor in the diffuse sky. Along a long, low sun
path it is a large share of the aureole: desert dust (f ~ 0.25) at AOD 0.27 with the
sun at 5 degrees has a peak optical depth of about 0.7 along the path.

Within the peak every scattering turns the light by a few degrees at most, so its
angular spread around the sun is a sum of small random deflections (the small-angle
approximation; e.g. Zege, Ivanov & Katsev 1991, ch. 4). If the sun path holds a peak
optical depth tau_p and q(theta) is the peak's shape (normalised to 1 over the plane
of small angles), the radiance that arrives after exactly n peak scatterings, per unit
solar irradiance and broad-band transmittance, is the Poisson weight
exp(-tau_p) tau_p^n / n! times the n-fold convolution q^{*n}. Under the Hankel transform
(radially symmetric Fourier transform) the convolutions become powers, and the sum over
n >= 2 has a closed form:

    A^(k) = exp(-tau_p) (exp(tau_p Q(k)) - 1 - tau_p Q(k)),   Q = Hankel transform of q,

whose integral over all angles is 1 - exp(-tau_p)(1 + tau_p): the energy delta-M kept in
the "direct" beam beyond what the true extinction and the single peak scattering
account for. The marcher adds E_sun T*_sun A(theta) to the sky (T*: the delta-M scaled
transmittance of the sun path, i.e. the broad, non-peak extinction), so that sun disc +
single peak scattering + this term carry the sun's energy as delta-M assumes.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import fht, fhtoffset, ifht

#: Largest angle from the sun (radians) the aureole is computed for; beyond it the
#: twice-scattered peak light is negligible for cones up to ~20 degrees.
THETA_MAX_RAD = np.radians(60.0)


def peak_part(angles_deg, phase, cutoff_deg: float) -> np.ndarray:
    """The forward peak that delta-M truncation removes: p - min(p, p(cutoff)) inside the
    cone (0 outside), as :func:`skymodel.render.medium.truncate_forward_peak` cuts it.
    ``phase`` (R, A, W) in sr^-1 -> (R, A, W)."""
    ang = np.asarray(angles_deg, dtype=float)
    p = np.asarray(phase, dtype=float)
    j = min(max(int(np.searchsorted(ang, cutoff_deg)), 1), ang.size - 1)
    cap = p[:, j:j + 1, :]
    return np.where(ang[None, :, None] < ang[j], np.maximum(p - cap, 0.0), 0.0)


class PeakAureole:
    """Hankel-transform machinery (radians, small-angle plane) on one logarithmic angle grid.

    The transforms are FFTLog's (:func:`scipy.fft.fht`): on ``n`` angles spaced evenly in
    log(theta) from ``theta_min`` to ``theta_max`` (and as many wavenumbers, spaced alike)
    each transform is one FFT. A log grid resolves what a linear one cannot: coarse dust's
    peak holds half its energy within 0.17 degrees of the forward direction at 450 nm, and
    its wings count out to the cone, 12 degrees. On a linear grid of 0.05 degrees (1200
    points to 60 degrees, the earlier machinery) the unresolved core left the twice-turned
    light 10 degrees from the sun 25 % low: on a medium of that peak alone the aureole 10
    degrees from a sun at 20 degrees was 8 % below the Monte Carlo tracer, the desert sky
    there 1.4 % (notebooks/aureole_transform). 4096 angles from 1e-8 to 1e3 rad give the
    correction table within 2e-3 of the phase function of one on 16384 angles.

    The grid runs from far inside the narrowest tabulated peak to far beyond any spread
    the table keeps, so that the periodic continuation the FFT assumes sees next to
    nothing at either end; the transforms ring within about four decades of its small
    end, so angles below ``theta_floor`` (1e-4 rad, 0.006 degrees, far inside the finest
    tabulated angle step) read the value there.

    ``theta`` (n,) are the angles and ``ring`` their areas in the small-angle plane
    (2 pi theta^2 dln: sums over the grid are integrals over the plane)."""

    def __init__(self, n: int = 4096, theta_min: float = 1e-8, theta_max: float = 1e3):
        ln = np.linspace(np.log(theta_min), np.log(theta_max), n)
        self.dln = float(ln[1] - ln[0])
        self.offset = float(fhtoffset(self.dln, mu=0.0))  # the low-ringing pairing of the grids
        self.theta = np.exp(ln)
        # FFTLog's wavenumbers: k_j theta_c = exp(offset) exp((j - j_c) dln), theta_c the centre
        self.k = np.exp(self.offset + ln - (ln[0] + ln[-1]))
        self.ring = 2.0 * np.pi * self.theta**2 * self.dln
        self.theta_floor = theta_min * 1e4

    def on_grid(self, angles_deg, values) -> np.ndarray:
        """Values (A, W) tabulated at ``angles_deg`` -> (n, W) on this grid, linear in angle as
        the medium reads them, 0 beyond the last tabulated angle."""
        th = np.radians(np.asarray(angles_deg, float))
        return np.stack([np.interp(self.theta, th, values[:, i], right=0.0) for i in range(values.shape[1])], axis=1)

    def shape_on_grid(self, angles_deg, peak) -> np.ndarray:
        """Peak values (A, W) on the table's angles, linear in angle as the medium reads
        them -> normalised shape q (n, W) on this grid (integral over the small-angle plane
        = 1; zero where the peak is)."""
        q = self.on_grid(angles_deg, peak)
        norm = self.ring @ q
        return np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), 0.0)

    def transform(self, q) -> np.ndarray:
        """Hankel transform of a normalised shape q (n, W): Q(k) = 2 pi int q J0(k theta)
        theta dtheta on ``self.k``, (n, W), Q(0) = 1. |Q| <= 1 for a density; what the
        FFT's ringing puts beyond that is clipped."""
        a = fht(np.ascontiguousarray((q * self.theta[:, None]).T), self.dln, mu=0.0, offset=self.offset)
        return np.clip(2.0 * np.pi * a.T / self.k[:, None], -1.0, 1.0)

    def _inverse(self, ak, theta_out) -> np.ndarray:
        """Inverse transform of ak (n, M) (radiance per unit irradiance in k space) at
        ``theta_out`` (radians): (len(theta_out), M), 0 beyond ``THETA_MAX_RAD``; what the
        FFT's ringing puts below 0 is clipped."""
        return np.maximum(self._inverse_signed(ak, theta_out), 0.0)

    def _inverse_signed(self, ak, theta_out) -> np.ndarray:
        """:meth:`_inverse` without the clipping at 0 (for differences)."""
        b = ifht(np.ascontiguousarray((ak * (self.k / (2.0 * np.pi))[:, None]).T), self.dln, mu=0.0,
                 offset=self.offset)
        c = b.T / self.theta[:, None]
        t = np.clip(np.asarray(theta_out, float), self.theta_floor, self.theta[-1])
        i = np.clip(np.searchsorted(self.theta, t) - 1, 0, self.theta.size - 2)
        w = ((t - self.theta[i]) / (self.theta[i + 1] - self.theta[i]))[:, None]
        out = c[i] * (1.0 - w) + c[i + 1] * w
        out[np.asarray(theta_out) > THETA_MAX_RAD] = 0.0
        return out

    def multiple(self, q, tau_peak, theta_out) -> np.ndarray:
        """Radiance per unit irradiance (sr^-1) at angles ``theta_out`` (radians) from the
        sun of light scattered two or more times in a peak of shape ``q`` (n, W)
        with peak optical depth ``tau_peak`` (W,): (len(theta_out), W)."""
        tau = np.asarray(tau_peak, float)[None, :]
        qk = self.transform(q)
        return self._inverse(np.exp(-tau) * (np.expm1(tau * qk) - tau * qk), theta_out)

    def correction_table(self, q, tau_grid, theta_out, qk=None) -> np.ndarray:
        """Peak light that the marcher's single scattering leaves out, per unit peak
        scattering at a point on a view ray, as a table (len(theta_out), len(tau_grid), W)
        in sr^-1; tau is the peak optical depth of the sun path to the point plus the
        view path from it.

        A path that the peak turns n + 1 times reaches the observer with the angular
        spread q^{*(n+1)} and the Poisson weight of n further peak scatterings; counting
        it at each of its n + 1 turning points would count it n + 1 times, so each
        point carries 1 / (n + 1) of it: sum over n of exp(-tau) tau^n / (n + 1)!
        q^{*(n+1)}. Along a view ray toward the sun (the sun path and the view path on
        one line) the integral of this over the ray is the Poisson sum over m >= 1
        scatterings of the whole line. The n = 0 term, exp(-tau) q, is the direct beam
        scattered once into the peak, which the marcher's single scattering holds; the
        rest is, in Hankel space, exp(-tau) (exp(tau Q) - 1 - tau Q) / tau. One tau node
        at a time (memory ~ n * W * 8 B * 4). ``qk``: q's :meth:`transform`, when the
        caller has it."""
        taus = np.asarray(tau_grid, float)
        qk = self.transform(q) if qk is None else qk  # (n, W)
        out = np.zeros((len(theta_out), taus.size, qk.shape[1]))
        for j, tau in enumerate(taus):
            if tau > 0:
                x = tau * qk
                out[:, j] = self._inverse(np.exp(-tau) * (np.expm1(x) - x) / tau, theta_out)
        return out

    def spread_table(self, q, g, tau_grid, theta_out, qk=None) -> np.ndarray:
        """The part of a smooth angular pattern ``g`` that the peak's small turns carry away
        from where it was: (g * K_tau) - exp(-tau) g, the light turned at least once, at
        ``theta_out`` (radians) for every peak optical depth of ``tau_grid``,
        (len(theta_out), len(tau_grid), W) in g's units, where

            K_tau = sum over n >= 0 of exp(-tau) tau^n / n! q^{*n}

        is the angular spread of light that has crossed a peak optical depth tau (n = 0, the
        part never turned, a delta; q the normalised peak shape, (n, W) on this grid). The
        whole change the turns make is this minus (1 - exp(-tau)) g; the caller adds that
        term with ``g`` read at its own angle, so that ``g``'s fine structure (Mie ripples,
        which this grid's transforms and the caller's table of angles do not carry alike)
        cancels exactly where the turns take it away: in Hankel space the table is
        G exp(-tau) (exp(tau Q) - 1), smooth on the scale of the peak's width. ``g`` (n, W) on
        this grid: a radially symmetric, non-negative pattern that vanishes beyond some angle.
        Used for the first scattering's non-peak part
        (:func:`skymodel.render.marcher.peak_spread_table`). ``qk``: q's :meth:`transform`,
        when the caller has it."""
        taus = np.asarray(tau_grid, float)
        g = np.asarray(g, float)
        norm = self.ring @ g  # (W,)
        shape = np.where(norm > 0, g / np.where(norm > 0, norm, 1.0), 0.0)
        gk = self.transform(shape) * norm[None, :]
        qk = self.transform(q) if qk is None else qk
        out = np.zeros((len(theta_out), taus.size, g.shape[1]))
        for j, tau in enumerate(taus):
            if tau > 0:
                out[:, j] = self._inverse_signed(gk * (np.exp(-tau) * np.expm1(tau * qk)), theta_out)
        return out
