"""From the multiple-scattering solver's wavelengths to the render's.

The solver runs at fewer wavelengths than the render (``MarchSettings.ms_wavelength_step_nm``:
40 nm at ``preview``, 10 nm at ``reference``, 10 nm over 440-660 nm and 20 nm beyond at
``final``, :func:`skymodel.render.marcher.solver_wavelengths`), and what it gives (the diffuse
light gathered along a view ray, the diffuse irradiance of the ground, both per unit solar
irradiance) is carried to the render's wavelengths by :class:`SolverSpectrumMap`.

A straight line between solver wavelengths misses the ozone Chappuis band: its cross-section
has bumps a few nanometres wide, and the long slant paths of a low sun print them on the
diffuse light as exp(-tau_O3(lambda) N). Against a solve at every 5-nm render wavelength,
linear interpolation from 10 nm was wrong by up to 6.5 % at 505 nm (rural AOD 0.2, sun -4
degrees; 0.37 % in CIE Z) and from 40 nm by up to 25 % (docs/accuracy.md, "The solver's
wavelengths"). So each spectrum S is interpolated in its logarithm with a local model of that
physics,

    ln S(lambda) ~ a + b ln lambda + c ln^2 lambda + d tau_O3(lambda),

a smooth spectrum (a power law and its bend) times the ozone transmittance of some column,
fitted by least squares over the ``stencil`` solver wavelengths around each interval; the
fit's residuals at the interval's two ends are added back, read linearly, so the map is exact
at the solver wavelengths. tau_O3 is the profile's vertical ozone optical depth at the render
wavelengths, so the bumps between solver wavelengths come from the ozone table itself. The
map is linear in ln S: one (n_solver, n_render) weight matrix, built once per solution.

Spectra with a value <= 0 at any solver wavelength (no logarithm) are interpolated linearly.

The solver itself uses the same map one step earlier: its spherical correction is computed at
probe wavelengths about 100 nm apart and carried to the other solver wavelengths by it
(:class:`skymodel.render.multiple_scattering._SphericalTransport`; there with the wavelength on
the first axis and in float32).
"""

from __future__ import annotations

import numpy as np

from skymodel.numerics import linear_interp_matrix

#: Solver wavelengths in each interval's least-squares fit, and the model's terms (1, ln lambda,
#: ln^2 lambda, tau_O3). Chosen by measurement (docs/accuracy.md, "The solver's wavelengths"):
#: at 10 nm, 8 wavelengths and the four terms were the best of the variants tried.
STENCIL = 8


def _log_weights(src_nm: np.ndarray, dst_nm: np.ndarray, ozone_depth: np.ndarray | None,
                 stencil: int) -> np.ndarray:
    """(n_src, n_dst) weights on ln S at ``src_nm`` giving ln S at ``dst_nm`` (inside
    [src[0], src[-1]]; outside: the end value)."""
    n = src_nm.size
    w = np.zeros((n, dst_nm.size))
    tau = np.zeros(dst_nm.size) if ozone_depth is None else np.asarray(ozone_depth, float)
    tau_scale = float(np.ptp(tau)) or 1.0
    tau_src = np.interp(src_nm, dst_nm, tau) / tau_scale  # at the solver wavelengths
    tau_dst = tau / tau_scale
    lnl_src, lnl_dst = np.log(src_nm), np.log(dst_nm)
    for j, lam in enumerate(dst_nm):
        if lam <= src_nm[0] or lam >= src_nm[-1]:
            w[0 if lam <= src_nm[0] else n - 1, j] = 1.0
            continue
        i = int(np.clip(np.searchsorted(src_nm, lam, side="right") - 1, 0, n - 2))
        f = (lam - src_nm[i]) / (src_nm[i + 1] - src_nm[i])
        lo = min(max(0, i - (stencil // 2 - 1)), max(0, n - stencil))
        s = np.arange(lo, min(n, lo + stencil))
        # the model's terms, ln lambda centred on the interval (conditioning)
        c0 = 0.5 * (lnl_src[i] + lnl_src[i + 1])
        h = lnl_src[i + 1] - lnl_src[i]

        def terms(lnl, t):
            x = (lnl - c0) / h
            return np.stack([np.ones_like(x), x, x * x, t], axis=-1)

        phi = terms(lnl_src[s], tau_src[s])
        p = np.linalg.pinv(phi, rcond=1e-9)  # (terms, stencil): the least-squares fit
        model = terms(np.array([lnl_dst[j]]), np.array([tau_dst[j]]))[0] @ p
        ends = np.zeros(s.size)
        ends[i - lo], ends[i + 1 - lo] = 1.0 - f, f
        w[s, j] = model + ends @ (np.eye(s.size) - phi @ p)  # + the residuals at i, i+1, linearly
    return w


def ozone_column(profile) -> np.ndarray:
    """The model's tau_O3: ``profile``'s vertical ozone optical depth at its wavelengths."""
    return profile.vertical_optical_depth(profile.ozone_absorption)


class SolverSpectrumMap:
    """Spectra at the solver's wavelengths ``solver_nm`` -> the render's ``render_nm`` (both
    ascending, nm), interpolated in the logarithm with the ozone model of the module's
    docstring; ``ozone_depth`` (n_render,) is the vertical ozone optical depth at the render
    wavelengths (None or zeros: no ozone term). ``map(values (..., n_solver)) -> (..., n_render)``.
    Where the two grids are the same the map is the identity."""

    def __init__(self, solver_nm, render_nm, ozone_depth=None, stencil: int = STENCIL):
        self.solver_nm = np.asarray(solver_nm, dtype=float)
        self.render_nm = np.asarray(render_nm, dtype=float)
        self.identity = (self.solver_nm.shape == self.render_nm.shape
                         and np.array_equal(self.solver_nm, self.render_nm))
        #: the linear map (spectra with a value <= 0, and one solver wavelength)
        self.linear = linear_interp_matrix(self.solver_nm, self.render_nm)
        self.log = None
        if not self.identity and self.solver_nm.size >= 4:
            self.log = _log_weights(self.solver_nm, self.render_nm, ozone_depth, int(stencil))

    @classmethod
    def for_profile(cls, solver_nm, profile, stencil: int = STENCIL) -> "SolverSpectrumMap":
        """The map to ``profile``'s wavelengths, with its ozone column."""
        return cls(solver_nm, profile.wavelengths_nm, ozone_column(profile), stencil)

    def __call__(self, values, axis: int = -1, dtype=np.float64) -> np.ndarray:
        """``values`` with its wavelength axis ``axis`` (the last, or 0) carried to the render's
        wavelengths; the logarithms and weights in ``dtype`` (float64; float32 where the spectra are
        float32 and large: the spherical correction's factor)."""
        v = np.asarray(values)
        if self.identity:
            return v
        if axis not in (0, -1, v.ndim - 1):
            raise ValueError(f"axis must be 0 or the last, got {axis}")
        first = axis == 0 and v.ndim > 1

        def apply(x, w):  # x (..., n_solver) or (n_solver, ...) with w (n_solver, n_render)
            w = w.astype(x.dtype, copy=False)
            return np.einsum("p...,pw->w...", x, w) if first else x @ w

        if self.log is None:
            return apply(v, self.linear)
        positive = np.all(v > 0, axis=0 if first else -1, keepdims=True)
        out = apply(np.log(np.where(v > 0, v, 1), dtype=dtype), self.log)
        np.exp(out, out=out)  # in place: the factor's arrays are tens of MB
        if not np.all(positive):
            np.copyto(out, apply(v.astype(dtype, copy=False), self.linear), where=~positive)
        return out.astype(np.result_type(v.dtype, np.float32), copy=False)
