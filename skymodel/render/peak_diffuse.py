"""The cut forward peak for the diffuse light near the horizon: the small-angle
scattering of the solver's radiance field across the sky/ground edge.

Delta-M (:mod:`skymodel.render.medium`) cuts the aerosols' forward peaks (a fraction f of
aerosol scattering inside a cone of 6 or 12 degrees,
:func:`~skymodel.render.medium.delta_m_cone_deg`; f = 0.85-0.88 for the desert's coarse dust)
and treats the cut light as not scattered: a point scatters sigma f integral(q L) into a
direction d, with q the peak's normalised shape around d, and delta-M books it as sigma f L(d),
light that goes on along d (the scaled extinction). The two agree where the radiance L is smooth
across the peak. Near the horizon it is not: a direction a degree above the local horizon has
the bright ground a degree or two below it, so the true source there holds ground light turned
by a few degrees, which delta-M leaves out (measured, desert AOD 0.5, sun 60 degrees, view
zenith 89 degrees: the marcher 2-8 % below the Monte Carlo tracer at every preset, all of it
ground light; docs/accuracy.md, "Where the presets miss the truth").

This module gives the missing term to the solver's source, order by order:

    dJ(h, d) = sum over regimes r of sigma_r(h) (integral q_r(d, d') L(d') dOmega' f_r - f_r L(d)),

with the true (not scaled) scattering coefficient sigma_r. It is evaluated on the
solver's grid in one dimension, the elevation: the peak (a few degrees wide) is
projected onto the elevation axis (the small-angle plane: k(x) = integral of the
peak along the other axis), L is read linearly in elevation between the zenith nodes at
the direction's own azimuth and sun angle, and only directions within
:data:`BAND_DEG` of the horizon get the term (elsewhere L is smooth on the peak's scale
and the term is second order). It redistributes light (a constant L gives dJ = 0), so
it conserves energy up to the grid's quadrature.

``MarchSettings.peak_diffuse``: on in ``final`` and ``reference``. Against the Monte Carlo
tracer (``final``, view zenith 88-89 degrees, marcher / MC - 1 at 450/550/650 nm, MC se
0.2-0.5 %; commands in notebooks/truth_misses): desert AOD 0.5 sun 60, 89/180
-2.37/-5.21/-8.24 -> +0.36/+0.50/+0.16 %, 89/90 -3.40/-4.75/-7.60 -> -0.52/+0.95/+0.31 %;
desert sun 20, 89/90 -1.57/-2.50/-4.54 -> -0.10/+0.43/-0.42 %. Over the rural ground it
once looked wrong (rural AOD 0.2 sun 60, 89/0 -0.45/-0.28/+0.05 -> -1.43/-1.48/-1.33 %),
but the term is right there (a 3-degree cone on 64 x 48 direction nodes, no term, gives
-1.30/-1.36/-1.25 %): the second error was the view rays' quadrature, 1 % low at 89 degrees
(:func:`~skymodel.render.medium.step_transmittance`); with it fixed, rural 60 89/0 is
-0.08/-0.45/-0.50 % with the term.
"""

from __future__ import annotations

import copy

import numpy as np

from skymodel.numerics import linear_interp_matrix, trapezoid
from skymodel.render.threads import SOLVER_THREADS, chunks_in_threads

#: Zenith nodes within this elevation of the horizon (degrees) get the peak term.
BAND_DEG = 24.0
#: Step (degrees) of the small-angle plane on which the peak is projected.
STEP_DEG = 0.05


def peak_of(profile, medium) -> np.ndarray:
    """The cut peak of every aerosol regime, p - min(p, p(cutoff)) inside the cone (R, A, W)
    in sr^-1, on the profile's tabulated angles, from the medium's truncated phase
    functions (p* = min(p, p(cutoff)) / (norm (1 - f)), norm the tabulated p's integral)."""
    ang = np.asarray(profile.aerosol_phase_angles_deg, float)
    p = np.asarray(profile.aerosol_phase, float)
    f = np.asarray(medium.forward_fraction, float)
    norm = -2.0 * np.pi * trapezoid(p, np.cos(np.radians(ang)), axis=1)  # (R, W)
    clipped = np.asarray(medium.truncated_phase, float) * (norm * (1.0 - f))[:, None, :]
    cut = p - clipped
    return np.where(cut > 1e-9 * p, cut, 0.0)  # outside the cone only rounding is left


def projected_kernel(angles_deg, peak, step_deg: float = STEP_DEG):
    """The peak (A, W) projected on one axis of the small-angle plane: offsets x (n,) in
    radians and k (n, W) in rad^-1 with k(x) = integral of peak(sqrt(x^2 + y^2)) dy,
    normalised so that sum(k) dx equals the peak's integral over the sphere."""
    ang = np.asarray(angles_deg, float)
    peak = np.asarray(peak, float)
    nz = np.flatnonzero(np.any(peak > 0, axis=1))
    reach = float(ang[min(nz[-1] + 1, ang.size - 1)]) if nz.size else step_deg
    n = int(np.ceil(reach / step_deg))
    dx = np.radians(step_deg)
    x = np.arange(-n, n + 1) * dx
    y = np.arange(-n, n + 1) * dx
    theta = np.degrees(np.hypot(x[:, None], y[None, :]))  # (n_x, n_y)
    k = np.stack([np.interp(theta, ang, peak[:, w], right=0.0).sum(axis=1) * dx for w in range(peak.shape[1])],
                 axis=1)  # (n_x, W)
    mu = np.cos(np.radians(ang))
    total = -2.0 * np.pi * trapezoid(peak, mu, axis=0)  # (W,): the integral over the sphere
    s = k.sum(axis=0) * dx
    return x, k * np.where(s > 0, total / np.where(s > 0, s, 1.0), 0.0)[None, :]


def _fast_length(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n: an FFT length numpy's pocketfft does fast (a length with a
    large prime factor, such as 3841 = 23 x 167 for the 6-degree cone's kernel, took it 2x longer).
    scipy.fft's own rule for real transforms; imported here, not with the module (60 ms)."""
    from scipy.fft import next_fast_len

    return int(next_fast_len(int(n), real=True))


def _convolve_same(a, kernel):
    """The linear convolution of ``a`` (n, ...) with ``kernel`` (m, ...) along axis 0, by FFT,
    its central n samples (scipy.signal.fftconvolve's mode "same"; numpy's FFT instead, whose
    import costs nothing where scipy.signal's took a cold render about 1 s). The transforms are
    zero-padded to a fast length (:func:`_fast_length`); the product is the same."""
    n, m = a.shape[0], kernel.shape[0]
    size = n + m - 1
    fast = _fast_length(size)
    full = np.fft.irfft(np.fft.rfft(a, fast, axis=0) * np.fft.rfft(kernel, fast, axis=0), fast, axis=0)
    start = (size - n) // 2
    return full[start:start + n]


def elevation_operator(mu_nodes, x, k, band_deg: float = BAND_DEG):
    """D (W, n_band, n_mu) and the band's node indices: D applied to L on the zenith nodes
    (ascending cosines) gives, per band node i, the term c(e) = integral k(x) L(e + x) dx -
    f L(e) averaged over the node's hat (the piecewise-linear basis function of node i in
    the elevation e = arcsin(mu)), L linear in e between nodes. The average (a lumped L2
    projection) instead of c at the node itself: the marcher reads the table linearly
    between nodes, and c falls steeply away from the horizon (the peak's tail), so point
    values would put about twice the light at 1 degree that belongs there (a sky/ground
    step at the horizon, desert dust: 0.074 against 0.034; averaged: 0.036)."""
    e = np.arcsin(np.asarray(mu_nodes, float))
    band = np.flatnonzero(np.abs(e) <= np.radians(band_deg))
    dx = x[1] - x[0]
    f = k.sum(axis=0) * dx  # (W,)
    fine = np.arange(-np.pi / 2, np.pi / 2 + 0.5 * dx, dx)  # the elevation, on the kernel's step
    hat = linear_interp_matrix(e, fine)  # (n_mu, n_fine): hat[j] is node j's basis function
    # c for each basis function: conv(k, hat_j)(e) - f hat_j(e); k is even, so the
    # convolution is the correlation integral k(x) L(e + x) dx
    basis = np.repeat(hat.T[:, :, None], k.shape[1], axis=2)  # (n_fine, n_mu, W): "same" keeps in1's shape
    c = _convolve_same(basis, k[:, None, :] * dx) - basis * f
    w = hat[band] / hat[band].sum(axis=1, keepdims=True)  # (n_band, n_fine)
    return np.einsum("bf,fjw->wbj", w, c), band


class PeakDiffuse:
    """The peak term dJ on a solver grid (module doc): ``source(L)`` for a radiance field
    L in the solver's dir layout (n_wl, n_dir, n_h, n_mus) -> dJ, the same shape, float32."""

    def __init__(self, profile, medium, grid, band_deg: float = BAND_DEG):
        peaks = peak_of(profile, medium)
        self.terms = []
        for reg in range(peaks.shape[0]):
            sig = medium.aerosol[reg].at(grid.h_nodes)  # (n_h, n_wl) true scattering, m^-1
            if not (np.any(sig > 0) and np.any(peaks[reg] > 0)):
                continue
            x, k = projected_kernel(profile.aerosol_phase_angles_deg, peaks[reg])
            d, band = elevation_operator(grid.mu_nodes, x, k, band_deg)
            rows = slice(int(band[0]), int(band[-1]) + 1)  # the band is contiguous (ascending nodes)
            # contiguous: einsum's output is a transposed view, on which matmul leaves BLAS
            # for a slow loop (0.55 s a call at final, 0.02 s contiguous)
            self.terms.append((np.ascontiguousarray(d, dtype=np.float32), rows, sig.T.astype(np.float32)))
        self.grid = grid

    def __bool__(self):
        return bool(self.terms)

    def on_grid(self, grid) -> "PeakDiffuse":
        """The same term on ``grid``, a grid with the same zenith and altitude nodes and other
        azimuths (the solver's coarse orders): the operators are the elevation's and the
        altitudes' alone, so they are shared, not made again (about 0.7 s a grid at ``final``)."""
        same = (np.array_equal(grid.mu_nodes, self.grid.mu_nodes) and np.array_equal(grid.h_nodes, self.grid.h_nodes)
                and np.array_equal(grid.wavelengths_nm, self.grid.wavelengths_nm))
        if not same:
            raise ValueError("PeakDiffuse.on_grid: the grid must have the same zenith, altitude and wavelength nodes")
        other = copy.copy(self)
        other.grid = grid
        return other

    def source(self, radiance: np.ndarray) -> np.ndarray:
        """dJ for the radiance field, a new array of its shape (float32)."""
        out = np.zeros(radiance.shape, dtype=np.float32)
        self.add_source(radiance, out)
        return out

    def add_source(self, radiance: np.ndarray, target: np.ndarray) -> None:
        """target += dJ for the radiance field (both in the solver's dir layout, target
        contiguous): only the horizon band's rows are touched. The wavelengths on
        :data:`~skymodel.render.threads.SOLVER_THREADS` threads, each product on one BLAS
        thread (as :func:`skymodel.render.multiple_scattering.gathered_radiance`: BLAS's own
        threads took 4.7x their idle time here on a machine busy with other work)."""
        g = self.grid
        if not target.flags.c_contiguous:  # reshape would copy, and the sum would be lost
            raise ValueError("PeakDiffuse.add_source: target must be C-contiguous")
        # one contiguous copy (the solver's radiance is a strided view; reshape would copy anyway)
        flat = np.ascontiguousarray(radiance).reshape(g.n_wl, g.n_mu, -1)
        tgt = target.reshape(g.n_wl, g.n_mu, g.n_phi, g.n_h, g.n_mus)  # a view: target is contiguous

        def wavelengths(ws):
            for w in ws:
                for d, rows, sig in self.terms:  # sig (n_wl, n_h)
                    part = np.matmul(d[w], flat[w]).reshape(d.shape[1], g.n_phi, g.n_h, g.n_mus)
                    part *= sig[w, None, None, :, None]
                    tgt[w, rows] += part

        chunks_in_threads(wavelengths, range(g.n_wl), SOLVER_THREADS)
