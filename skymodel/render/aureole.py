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
from scipy.special import j0

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
    """Hankel-transform machinery on fixed angle grids (radians, small-angle plane).

    ``n_theta`` points up to ``theta_max`` carry the peak shape; ``n_k`` wavenumbers
    resolve it (spacing chosen so the inverse transform does not alias within
    ``theta_max``)."""

    def __init__(self, theta_max: float = THETA_MAX_RAD, n_theta: int = 1200, n_k: int = 1600):
        self.theta = np.linspace(0.0, theta_max, n_theta)
        dtheta = self.theta[1] - self.theta[0]
        w = 2.0 * np.pi * self.theta * dtheta  # ring areas (trapezoid-like; the origin has no area)
        w[-1] *= 0.5
        self.ring = w
        # wavenumbers crowded toward 0 (k = k_max u^2, u uniform): the transforms of the
        # broad many-times-convolved peaks live at small k, the narrow single peak needs
        # k_max; the largest spacing 2 k_max / n_k keeps aliasing beyond theta_max
        k_max = np.pi / dtheta
        self.k = k_max * np.linspace(0.0, 1.0, n_k) ** 2
        dk = np.gradient(self.k)
        dk[0] *= 0.5
        dk[-1] *= 0.5
        self.k_weight = self.k * dk / (2.0 * np.pi)
        self.forward = j0(np.outer(self.theta, self.k)) * w[:, None]  # (n_theta, n_k)

    def shape_on_grid(self, angles_deg, peak) -> np.ndarray:
        """Peak values (A, W) on the table's angles -> normalised shape q (n_theta, W)
        on this grid (integral over the small-angle plane = 1; zero where the peak is)."""
        th = np.radians(np.asarray(angles_deg, float))
        q = np.stack([np.interp(self.theta, th, peak[:, i], right=0.0) for i in range(peak.shape[1])], axis=1)
        norm = self.ring @ q
        return np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), 0.0)

    def multiple(self, q, tau_peak, theta_out) -> np.ndarray:
        """Radiance per unit irradiance (sr^-1) at angles ``theta_out`` (radians) from the
        sun of light scattered two or more times in a peak of shape ``q`` (n_theta, W)
        with peak optical depth ``tau_peak`` (W,): (len(theta_out), W)."""
        tau = np.asarray(tau_peak, float)[None, :]
        qk = self.forward.T @ q  # (n_k, W), Q(0) = 1
        ak = np.exp(-tau) * (np.expm1(tau * qk) - tau * qk)
        inverse = j0(np.outer(np.asarray(theta_out, float), self.k)) * self.k_weight  # (n_out, n_k)
        out = inverse @ ak
        out[np.asarray(theta_out) > self.theta[-1]] = 0.0
        return np.maximum(out, 0.0)

    def correction_table(self, q, tau_grid, theta_out) -> np.ndarray:
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
        rest is, in Hankel space, exp(-tau) (exp(tau Q) - 1 - tau Q) / tau."""
        tau = np.asarray(tau_grid, float)[None, :, None]
        qk = (self.forward.T @ q)[:, None, :]  # (n_k, 1, W)
        x = tau * qk
        safe = np.where(tau > 0, tau, 1.0)
        ck = np.where(tau > 0, np.exp(-tau) * (np.expm1(x) - x) / safe, 0.0)  # (n_k, n_tau, W)
        inverse = j0(np.outer(np.asarray(theta_out, float), self.k)) * self.k_weight  # (n_out, n_k)
        out = (inverse @ ck.reshape(self.k.size, -1)).reshape(len(theta_out), tau.shape[1], -1)
        out[np.asarray(theta_out) > self.theta[-1]] = 0.0
        return np.maximum(out, 0.0)
