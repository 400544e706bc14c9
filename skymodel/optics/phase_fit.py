"""Analytic stand-ins for tabulated aerosol phase functions: Henyey-Greenstein (HG) and
double Henyey-Greenstein (DHG) fits, used where a renderer cannot take a table (Cycles'
Volume Scatter lobes, the accuracy study of what the full Mie table buys).

HG (Henyey & Greenstein 1941): p(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^1.5), normalised
over 4 pi, with asymmetry parameter g.
* HG (``fit_phase``: ``g``) takes g equal to the table's asymmetry parameter <mu> (moment matching: the
  choice that keeps the diffusion of light, and so multiple scattering, right).
* DHG (``fit_phase``: ``dhg_w``, ``dhg_g1``, ``dhg_g2``) fits p = w HG(g1) + (1 - w) HG(g2) with g2 < g < g1 (a sharper forward
  lobe and a broader or backward one) by least squares on log p over the angle grid, with
  the first moment constrained to the table's (w = (g - g2) / (g1 - g2), in (0, 1) by
  construction), so the asymmetry is kept exactly and the shape (forward peak,
  back-scatter) is matched as well as two lobes allow.
The fit error reported is the RMS of log(p_fit / p_table) over the sphere (solid-angle
weighted), i.e. roughly the typical relative error of the phase function.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from skymodel.numerics import trapezoid


def hg(mu, g):
    """Henyey-Greenstein phase function, sr^-1 (broadcasts mu against g)."""
    mu = np.asarray(mu, dtype=float)
    g = np.asarray(g, dtype=float)
    return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)


def asymmetry(angles_deg, phase) -> np.ndarray:
    """<cos theta> of phase tables (n_angle, ...) on an angle grid (degrees)."""
    mu = np.cos(np.radians(np.asarray(angles_deg, float)))
    p = np.asarray(phase, float)
    shape = (-1,) + (1,) * (p.ndim - 1)
    return -2.0 * np.pi * trapezoid(p * mu.reshape(shape), mu, axis=0)


def _rms_log_error(angles_deg, table, model):
    mu = np.cos(np.radians(np.asarray(angles_deg, float)))
    w = np.abs(np.gradient(mu))  # solid-angle weights on the grid (per 2 pi)
    ratio = np.log(np.maximum(model, 1e-300) / np.maximum(table, 1e-300))
    return float(np.sqrt((w * ratio**2).sum() / w.sum()))


@dataclass(frozen=True)
class PhaseFit:
    """Per-wavelength fit parameters: HG g; DHG weight w of the forward lobe, g1, g2;
    and the RMS log error of each fit."""

    g: np.ndarray
    dhg_w: np.ndarray
    dhg_g1: np.ndarray
    dhg_g2: np.ndarray
    hg_error: np.ndarray
    dhg_error: np.ndarray

    def hg_table(self, angles_deg) -> np.ndarray:
        mu = np.cos(np.radians(np.asarray(angles_deg, float)))[:, None]
        return hg(mu, self.g[None, :])

    def dhg_table(self, angles_deg) -> np.ndarray:
        mu = np.cos(np.radians(np.asarray(angles_deg, float)))[:, None]
        return self.dhg_w * hg(mu, self.dhg_g1) + (1 - self.dhg_w) * hg(mu, self.dhg_g2)


#: largest |g| of a fitted lobe
G_MAX = 0.999


def fit_phase(angles_deg, phase) -> PhaseFit:
    """Fit HG and DHG to every column of ``phase`` (n_angle, n_wl) on ``angles_deg``."""
    ang = np.asarray(angles_deg, float)
    tab = np.asarray(phase, float)
    mu = np.cos(np.radians(ang))
    gs = np.clip(asymmetry(ang, tab), -0.99, 0.99)
    out = {k: np.zeros(tab.shape[1]) for k in ("w", "g1", "g2", "e_hg", "e_dhg")}
    for j in range(tab.shape[1]):
        g = gs[j]
        p = tab[:, j]
        out["e_hg"][j] = _rms_log_error(ang, p, hg(mu, g))

        # g1 in (g, G_MAX) and g2 in (-G_MAX, g), so the weight that keeps the first
        # moment, w = (g - g2) / (g1 - g2), always lies in (0, 1): the asymmetry is kept
        # exactly (a free (g1, g2) pair could need w outside [0, 1], and clipping it there
        # silently changed the asymmetry)
        lo, hi = g, G_MAX

        def lobes(x):
            s1, s2 = 0.5 * (1.0 + np.tanh(x[0])), 0.5 * (1.0 + np.tanh(x[1]))
            return lo + (hi - lo) * s1, -G_MAX + (lo + G_MAX) * s2

        def model(x):
            g1, g2 = lobes(x)
            w = (g - g2) / (g1 - g2) if g1 - g2 > 1e-12 else 1.0
            return w, g1, g2, w * hg(mu, g1) + (1 - w) * hg(mu, g2)

        def resid(x):
            return np.log(np.maximum(model(x)[3], 1e-300)) - np.log(np.maximum(p, 1e-300))

        def start(g1_0, g2_0):
            s1 = np.clip((g1_0 - lo) / (hi - lo), 1e-3, 1 - 1e-3)
            s2 = np.clip((g2_0 + G_MAX) / (lo + G_MAX), 1e-3, 1 - 1e-3)
            return [np.arctanh(2 * s1 - 1), np.arctanh(2 * s2 - 1)]

        best = None
        for g1_0, g2_0 in ((g + 0.1, -0.3), (g + 0.2, -0.1), (g + 0.02, -0.6), (0.5 * (g + G_MAX), g - 0.3)):
            sol = least_squares(resid, x0=start(min(g1_0, 0.995), g2_0), method="lm", max_nfev=400)
            if best is None or sol.cost < best.cost:
                best = sol
        w, g1, g2, pm = model(best.x)
        out["w"][j], out["g1"][j], out["g2"][j] = w, g1, g2
        out["e_dhg"][j] = _rms_log_error(ang, p, pm)
    return PhaseFit(gs, out["w"], out["g1"], out["g2"], out["e_hg"], out["e_dhg"])
