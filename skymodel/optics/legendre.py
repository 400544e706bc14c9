"""Legendre moments of phase functions: the form discrete-ordinates solvers (DISORT and
its kin) take the angular scattering of a layer in.

A phase function p(theta) in sr^-1, normalised so that its integral over the full
sphere is 1, is expanded in Legendre polynomials of mu = cos(theta):

    4 pi p(mu) = sum_l (2 l + 1) chi_l P_l(mu),    chi_l = 2 pi * integral_{-1}^{1} p(mu) P_l(mu) dmu

so chi_0 = 1 and chi_1 = g, the asymmetry parameter (DISORT's ``PMOM`` convention).

Closed forms used to check the numerical moments:

* Rayleigh with depolarisation rho (Chandrasekhar's phase function with
  gamma = rho / (2 - rho), :meth:`skymodel.optics.profile.OpticalProfile.rayleigh_phase`):
  writing mu^2 = (1 + 2 P_2) / 3 gives 4 pi p = 1 + (1 - gamma) / (2 (1 + 2 gamma)) P_2, hence
  chi_0 = 1, chi_2 = (1 - gamma) / (10 (1 + 2 gamma)) = (1 - rho) / (5 (2 + rho)), every other
  chi_l = 0 (chi_2 = 0.1 without depolarisation).
* Henyey-Greenstein with asymmetry g: chi_l = g^l.

Tabulated phase functions (the aerosol tables, linear in scattering angle between their
nodes as :meth:`~skymodel.optics.profile.OpticalProfile.aerosol_phase_at` reads them) are
integrated in angle with Gauss-Legendre nodes on sub-intervals fine enough for the
highest polynomial asked for, so the moments are those of the same piecewise-linear
function the renderer uses.
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError

#: Highest moment count accepted (memory and time grow linearly with it).
MAX_MOMENTS = 20_000


def _check_count(n_moments) -> int:
    integer = isinstance(n_moments, (int, np.integer)) and not isinstance(n_moments, bool)
    if not integer or not 0 <= int(n_moments) <= MAX_MOMENTS:
        raise SkymodelInputError("n_moments", n_moments, f"an integer in [0, {MAX_MOMENTS}]")
    return int(n_moments)


def legendre_polynomials(n_max: int, mu) -> np.ndarray:
    """P_0 .. P_n_max at ``mu`` (any shape) by the three-term recurrence; shape
    ``(n_max + 1,) + mu.shape``."""
    n_max = _check_count(n_max)
    x = np.asarray(mu, dtype=float)
    out = np.empty((n_max + 1,) + x.shape)
    out[0] = 1.0
    if n_max >= 1:
        out[1] = x
    for ell in range(2, n_max + 1):
        out[ell] = ((2 * ell - 1) * x * out[ell - 1] - (ell - 1) * out[ell - 2]) / ell
    return out


def rayleigh_moments(depolarization, n_moments: int) -> np.ndarray:
    """Moments chi_0 .. chi_n of the depolarised Rayleigh phase function; shape
    ``(n_moments + 1,) + depolarization.shape``."""
    n = _check_count(n_moments)
    rho = np.asarray(depolarization, dtype=float)
    if np.any(~np.isfinite(rho)) or np.any((rho < 0.0) | (rho >= 1.0)):
        raise SkymodelInputError("depolarization", depolarization, "values in [0, 1)")
    out = np.zeros((n + 1,) + rho.shape)
    out[0] = 1.0
    if n >= 2:
        out[2] = (1.0 - rho) / (5.0 * (2.0 + rho))
    return out


def henyey_greenstein_moments(g, n_moments: int) -> np.ndarray:
    """Moments g^l (l = 0 .. n) of the Henyey-Greenstein phase function; shape
    ``(n_moments + 1,) + g.shape``."""
    n = _check_count(n_moments)
    g = np.asarray(g, dtype=float)
    if np.any(~np.isfinite(g)) or np.any(np.abs(g) >= 1.0):
        raise SkymodelInputError("g", g, "asymmetry values in (-1, 1)")
    ell = np.arange(n + 1).reshape((-1,) + (1,) * g.ndim)
    return g[None, ...] ** ell


def henyey_greenstein(cos_theta, g) -> np.ndarray:
    """Henyey-Greenstein phase function, sr^-1 (normalised over 4 pi); broadcasts."""
    mu = np.asarray(cos_theta, dtype=float)
    g = np.asarray(g, dtype=float)
    return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)


def _angle_quadrature(angles_deg: np.ndarray, n_moments: int, nodes_per_interval: int):
    """Gauss-Legendre nodes in theta (rad) on sub-intervals of the table's intervals, each
    no wider than a quarter of the shortest half-period of P_n; returns (theta, weight,
    table interval index, fraction of the way through it)."""
    ang = np.radians(angles_deg)
    widest = np.pi / (4.0 * max(n_moments, 1))
    n_sub = np.maximum(1, np.ceil(np.diff(ang) / widest).astype(int))
    interval = np.repeat(np.arange(ang.size - 1), n_sub)
    k = np.arange(n_sub.sum()) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)  # index inside its interval
    width = np.diff(ang)[interval] / n_sub[interval]
    lo = ang[interval] + k * width
    x, w = np.polynomial.legendre.leggauss(nodes_per_interval)
    theta = (lo[:, None] + 0.5 * width[:, None] * (x[None, :] + 1.0)).ravel()
    weight = (0.5 * width[:, None] * w[None, :]).ravel()
    idx = np.repeat(interval, nodes_per_interval)
    frac = (theta - ang[idx]) / (ang[idx + 1] - ang[idx])
    return theta, weight, idx, frac


def tabulated_moments(angles_deg, phase, n_moments: int, normalize: bool = True,
                      nodes_per_interval: int = 6) -> np.ndarray:
    """Legendre moments of a tabulated phase function.

    ``angles_deg`` (n_angle,) increasing from 0 to 180 degrees; ``phase`` (n_angle, ...)
    in sr^-1, read as linear in angle between the nodes. Returns chi_0 .. chi_n shaped
    ``(n_moments + 1,) + phase.shape[1:]``; with ``normalize`` every column is divided by
    its own chi_0 (so chi_0 = 1 exactly, as solvers require; chi_0 before that is the
    table's integral over the sphere)."""
    n = _check_count(n_moments)
    ang = np.asarray(angles_deg, dtype=float)
    p = np.asarray(phase, dtype=float)
    if ang.ndim != 1 or ang.size < 2 or np.any(np.diff(ang) <= 0) or abs(ang[0]) > 1e-9 or abs(ang[-1] - 180.0) > 1e-9:
        raise SkymodelInputError("angles_deg", "table", "increasing scattering angles from 0 to 180 degrees")
    if p.shape[0] != ang.size or np.any(~np.isfinite(p)) or np.any(p < 0):
        raise SkymodelInputError("phase", "table", f"finite non-negative values, first axis of length {ang.size}")
    theta, weight, idx, frac = _angle_quadrature(ang, n, int(nodes_per_interval))
    cols = p.reshape(ang.size, -1)
    values = cols[idx] * (1.0 - frac)[:, None] + cols[idx + 1] * frac[:, None]  # (nodes, cols)
    wv = values * (2.0 * np.pi * weight * np.sin(theta))[:, None]
    mu = np.cos(theta)
    out = np.empty((n + 1, cols.shape[1]))
    p_prev, p_cur = np.ones_like(mu), mu
    out[0] = p_prev @ wv
    if n >= 1:
        out[1] = p_cur @ wv
    for ell in range(2, n + 1):  # recurrence: one pass over the nodes per order
        p_prev, p_cur = p_cur, ((2 * ell - 1) * mu * p_cur - (ell - 1) * p_prev) / ell
        out[ell] = p_cur @ wv
    if normalize:
        out = out / np.where(out[0] > 0, out[0], 1.0)
    return out.reshape((n + 1,) + p.shape[1:])


def phase_from_moments(moments, cos_theta) -> np.ndarray:
    """The phase function (sr^-1) of a Legendre series: sum_l (2l+1) chi_l P_l(mu) / (4 pi).
    ``moments`` (n + 1, ...); result shaped ``cos_theta.shape + moments.shape[1:]``."""
    chi = np.asarray(moments, dtype=float)
    mu = np.asarray(cos_theta, dtype=float)
    n = chi.shape[0] - 1
    ell = np.arange(n + 1).reshape((-1,) + (1,) * (chi.ndim - 1))
    coef = (2 * ell + 1) * chi / (4.0 * np.pi)  # (n+1, ...)
    flat = coef.reshape(n + 1, -1)
    out = np.zeros((mu.size, flat.shape[1]))
    x = mu.ravel()
    p_prev, p_cur = np.ones_like(x), x
    out += p_prev[:, None] * flat[0]
    if n >= 1:
        out += p_cur[:, None] * flat[1]
    for k in range(2, n + 1):
        p_prev, p_cur = p_cur, ((2 * k - 1) * x * p_cur - (k - 1) * p_prev) / k
        out += p_cur[:, None] * flat[k]
    return out.reshape(mu.shape + chi.shape[1:])
