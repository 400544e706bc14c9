"""Fast evaluation of the medium along many rays.

Every coefficient of the atmosphere is a matrix A (altitude x wavelength) that is very
nearly of low rank: Rayleigh scattering is the air density times a cross section,
ozone absorption the ozone density times its cross section, each aerosol regime a
number-density profile times a cross section. We factor A = B W once with an SVD
(B: altitude basis functions, W: their spectra), keeping every singular value above
1e-12 of the largest, so the factorisation is exact to round-off. Along rays we then
interpolate k << n_wavelength basis functions and multiply by W at the end: the
optical depth of a path is (integral of B along the path) @ W.

The altitude dependence is interpolated as the profile itself is: linearly between
the nodes of an :class:`~skymodel.optics.profile.OpticalProfile`, piecewise-constant inside the
layers of a :class:`~skymodel.optics.profile.LayeredProfile`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymodel.optics.profile import LayeredProfile, OpticalProfile
from skymodel.render.threads import one_blas_thread


@dataclass(frozen=True)
class LowRank:
    """``A(h, lambda) = basis(h) @ weights`` with basis on altitude nodes."""

    nodes_m: np.ndarray  # (n_nodes,) altitudes (smooth) or layer edges (layered)
    basis: np.ndarray  # (n_nodes, k) smooth, or (n_layers, k) layered
    weights: np.ndarray  # (k, n_wl)
    layered: bool
    top_m: float

    @classmethod
    def from_matrix(cls, nodes_m, matrix, layered: bool, top_m: float, rtol: float = 1e-12) -> "LowRank":
        a = np.asarray(matrix, dtype=float)
        if not np.any(a):
            return cls(np.asarray(nodes_m, float), np.zeros((a.shape[0], 1)), np.zeros((1, a.shape[1])), layered, top_m)
        # on one BLAS thread: LAPACK's many small steps on BLAS's own threads wait for each
        # other on a machine busy with other work (a 401 x 81 matrix 1 s against 2 ms idle)
        with one_blas_thread():
            u, s, vt = np.linalg.svd(a, full_matrices=False)
        k = max(1, int(np.count_nonzero(s > rtol * s[0])))
        return cls(np.asarray(nodes_m, float), u[:, :k] * s[:k], vt[:k], layered, top_m)

    @property
    def rank(self) -> int:
        return int(self.basis.shape[1])

    def basis_at(self, altitudes_m) -> np.ndarray:
        """Basis functions at altitudes (any shape) -> shape + (k,); zero above the top."""
        h = np.asarray(altitudes_m, dtype=float)
        nodes = self.nodes_m
        if self.layered:
            idx = np.clip(np.searchsorted(nodes, h, side="right") - 1, 0, nodes.size - 2)
            out = self.basis[idx]
        else:
            hc = np.clip(h, nodes[0], nodes[-1])
            idx = np.clip(np.searchsorted(nodes, hc, side="right") - 1, 0, nodes.size - 2)
            t = ((hc - nodes[idx]) / (nodes[idx + 1] - nodes[idx]))[..., None]
            out = self.basis[idx] * (1.0 - t) + self.basis[idx + 1] * t
        return np.where((h <= self.top_m)[..., None], out, 0.0)

    def at(self, altitudes_m) -> np.ndarray:
        """The full coefficient at altitudes -> shape + (n_wl,)."""
        return self.basis_at(altitudes_m) @ self.weights


def evaluate_many(media, altitudes_m) -> list:
    """Evaluate several :class:`LowRank` coefficients sharing the same altitude nodes at
    once: one interpolation of the stacked basis, then one small product per medium."""
    first = media[0]
    stacked = LowRank(first.nodes_m, np.concatenate([m.basis for m in media], axis=1),
                      np.zeros((sum(m.rank for m in media), 1)), first.layered, first.top_m)
    values = stacked.basis_at(altitudes_m)
    out, k = [], 0
    for m in media:
        out.append(values[..., k:k + m.rank] @ m.weights)
        k += m.rank
    return out


@dataclass(frozen=True)
class FactoredMedium:
    """The medium of a profile in low-rank form, plus delta-M scaled quantities.

    ``extinction`` / ``rayleigh`` / ``aerosol[r]`` are true coefficients (m^-1);
    ``extinction_scaled`` and ``aerosol_scaled[r]`` remove the truncated forward peak
    fraction ``forward_fraction[r]`` (n_wl,) of aerosol scattering (delta-M, Wiscombe 1977),
    used only inside the multiple-scattering solution.
    """

    extinction: LowRank
    extinction_scaled: LowRank
    rayleigh: LowRank
    aerosol: tuple  # of LowRank, one per regime
    aerosol_scaled: tuple
    forward_fraction: np.ndarray  # (n_regime, n_wl)
    truncated_phase: np.ndarray  # (n_regime, n_angle, n_wl), normalised over 4 pi
    cutoff_deg: float  # half-angle of the cut cone (degrees)

    @property
    def capped_phase(self) -> np.ndarray:
        """(1 - f) p*: each regime's phase function with its forward peak clipped at the cut,
        min(p, p(cutoff)), not renormalised, on the profile's phase angles (n_regime, n_angle,
        n_wl) sr^-1."""
        return self.truncated_phase * (1.0 - self.forward_fraction)[:, None, :]


def truncate_forward_peak(angles_deg, phase, cutoff_deg: float):
    """Delta-M style truncation of tabulated phase functions.

    p*(theta) = min(p(theta), p(cutoff)) inside the cone theta < cutoff, then
    renormalised; the removed fraction f = 1 - integral(min(p, p(cutoff))) is returned.
    ``phase`` (R, A, W) -> (f (R, W), p* (R, A, W))."""
    from skymodel.numerics import trapezoid

    ang = np.asarray(angles_deg, dtype=float)
    p = np.asarray(phase, dtype=float)
    j = int(np.searchsorted(ang, cutoff_deg))
    j = min(max(j, 1), ang.size - 1)
    cap = p[:, j:j + 1, :]
    clipped = np.where(ang[None, :, None] < ang[j], np.minimum(p, cap), p)
    mu = np.cos(np.radians(ang))
    total = -2.0 * np.pi * trapezoid(clipped, mu, axis=1)  # mu decreasing with angle
    norm = -2.0 * np.pi * trapezoid(p, mu, axis=1)
    f = np.clip(1.0 - total / np.where(norm > 0, norm, 1.0), 0.0, 1.0)
    return f, clipped / np.where(total > 0, total, 1.0)[:, None, :]


#: A mild forward peak (:func:`delta_m_cone_deg`): the dominant aerosol's phase function falls
#: by at most this factor from the narrow cone's edge out to the wide one's (6 and 12 degrees),
#: at 550 nm. Every aerosol type of the paper's model lies at 1.6-2.4 (rural 2.25) but coarse
#: dust (4.4) and the stratospheric background (3.3); docs/accuracy.md, "The horizon toward a
#: setting sun in haze".
MILD_PEAK_FALL = 2.5
#: Wavelength (nm) at which :func:`delta_m_cone_deg` reads the phase function.
CONE_WAVELENGTH_NM = 550.0
#: Fewest solver azimuth nodes that resolve the field of the narrow cone: with 6 nodes (30
#: degrees apart) the source toward a sun at -4 degrees was 3-12 % off a 24-node field's, with 12
#: nodes within 0.2 % of a 48-node one's (rural AOD 0.2, 450 and 650 nm; tests/test_delta_m_cone.py).
MILD_CONE_MIN_TABLE_PHI = 12


def delta_m_cone_deg(profile, cutoff_deg: float, mild_cutoff_deg: float = 0.0,
                     mild_fall: float = MILD_PEAK_FALL, table_phi: int | None = None) -> float:
    """The delta-M cone (half-angle, degrees) for ``profile``: ``mild_cutoff_deg`` where the
    aerosol that scatters most over the column (at the profile's wavelength nearest
    :data:`CONE_WAVELENGTH_NM`) has a mild forward peak, its phase function falling by at
    most ``mild_fall`` from ``mild_cutoff_deg`` out to ``cutoff_deg``; else ``cutoff_deg``.

    Why: delta-M books light turned inside the cone as not scattered. Near a sun at the
    horizon a turn of a few degrees changes the air a path crosses by orders of magnitude,
    and that light, cut, is missing from the horizon toward the sun (rural AOD 0.2 against
    the Monte Carlo truth at sun 0 and -4 degrees: 3-5 % low at 650 nm with a 12-degree
    cone, 2-3 % with 6 degrees). A mild peak cut at the narrow cone leaves a phase function
    the solver's direction nodes resolve; a sharp one (coarse dust) leaves a shoulder at the
    cone's edge that the delta-M first scattering, unless spread by the peak's turns
    (``MarchSettings.peak_spread``), turns into a bright ring (desert AOD 0.5 at sun 5 degrees:
    worst 1.3 % with 12 degrees, 3.8 % with 6; with the spread, 1.0 % with 6, the cone of
    ``final`` and ``reference`` for every aerosol, notebooks/sunward_zero). Never
    wider than ``cutoff_deg``; ``mild_cutoff_deg`` 0 (or not narrower) keeps ``cutoff_deg``, and
    so does a solver with fewer than :data:`MILD_CONE_MIN_TABLE_PHI` azimuth nodes
    (``table_phi``, when given)."""
    cutoff_deg, mild_cutoff_deg = float(cutoff_deg), float(mild_cutoff_deg)
    if not 0.0 < mild_cutoff_deg < cutoff_deg:
        return cutoff_deg
    if table_phi is not None and int(table_phi) < MILD_CONE_MIN_TABLE_PHI:
        return cutoff_deg
    w = int(np.argmin(np.abs(np.asarray(profile.wavelengths_nm, dtype=float) - CONE_WAVELENGTH_NM)))
    # each regime's column scattering optical depth at w (the profile's own vertical integral)
    col = np.array([profile.vertical_optical_depth(a)[w] for a in profile.aerosol_scattering_by_regime])
    if col.size == 0 or not np.any(col > 0):
        return cutoff_deg
    r = int(np.argmax(col))
    ang = np.asarray(profile.aerosol_phase_angles_deg, dtype=float)
    p = np.asarray(profile.aerosol_phase, dtype=float)[r, :, w]
    inner, outer = np.interp([mild_cutoff_deg, cutoff_deg], ang, p)
    return mild_cutoff_deg if outer > 0 and inner <= mild_fall * outer else cutoff_deg


def factor_medium(profile, cutoff_deg: float = 12.0) -> FactoredMedium:
    """Factor every coefficient of ``profile`` (smooth or layered) for fast ray marching."""
    if isinstance(profile, LayeredProfile):
        nodes, layered = profile.edges_m, True
    elif isinstance(profile, OpticalProfile):
        nodes, layered = profile.altitudes_m, False
    else:
        raise TypeError("profile must be an OpticalProfile or a LayeredProfile")
    top = float(profile.top_altitude_m)
    f, p_star = truncate_forward_peak(profile.aerosol_phase_angles_deg, profile.aerosol_phase, cutoff_deg)
    aer = profile.aerosol_scattering_by_regime
    aer_scaled = aer * (1.0 - f[:, None, :])
    ext = profile.extinction
    ext_scaled = ext - (aer - aer_scaled).sum(axis=0)

    def lr(a):
        return LowRank.from_matrix(nodes, a, layered, top)

    return FactoredMedium(
        extinction=lr(ext), extinction_scaled=lr(ext_scaled), rayleigh=lr(profile.rayleigh_scattering),
        aerosol=tuple(lr(a) for a in aer), aerosol_scaled=tuple(lr(a) for a in aer_scaled),
        forward_fraction=f, truncated_phase=p_star, cutoff_deg=float(cutoff_deg),
    )


def march_samples(p, d, t0, t1, n: int, ground_radius: float):
    """Midpoint quadrature nodes along ray segments [t0, t1] of rays p + t d.

    Samples crowd quadratically toward the lowest point of the segment (the perigee when
    it lies inside the segment, else the lower end), where the air is densest. With
    f = (t_p - t0) / (t1 - t0) the fraction of the segment before the perigee t_p, a
    uniform u in [0, 1] maps to t_p - (t_p - t0)(1 - u/f)^2 for u < f and to
    t_p + (t1 - t_p)((u - f)/(1 - f))^2 beyond, so each side gets samples in proportion
    to its length. Returns (t, dt), each shaped (..., n).
    """
    p = np.asarray(p, dtype=float)
    d = np.asarray(d, dtype=float)
    t0 = np.asarray(t0, dtype=float)[..., None]
    t1 = np.asarray(t1, dtype=float)[..., None]
    tp = np.clip(-np.einsum("...i,...i->...", p, d)[..., None], t0, t1)
    length = np.maximum(t1 - t0, 1e-300)
    f = np.clip((tp - t0) / length, 0.0, 1.0)
    u = np.linspace(0.0, 1.0, n + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        before = tp - (tp - t0) * (1.0 - np.where(f > 0, u / f, 1.0)) ** 2
        after = tp + (t1 - tp) * np.where(f < 1, (u - f) / (1.0 - f), 0.0) ** 2
    edges = np.where(u < f, before, after)
    edges[..., 0] = t0[..., 0]
    edges[..., -1] = t1[..., 0]
    t = 0.5 * (edges[..., 1:] + edges[..., :-1])
    dt = np.diff(edges, axis=-1)
    return t, dt


def samples_by_depth(edges_fine, sigma_fine, n: int, depth_share: float):
    """Midpoint quadrature nodes (t, dt), each (G, n), along G rays, placed by optical depth.

    ``edges_fine`` (G, F + 1): a fine march's step edges along each ray (from
    :func:`march_samples`, whose coordinate u runs evenly over them); ``sigma_fine`` (G, F):
    an extinction coefficient at its midpoints (per metre). The n coarse steps are equal
    steps of c = depth_share * tau(t) / tau_total + (1 - depth_share) * u: a share of them
    follows the ray's optical depth, the rest the fine march's own spacing (so no step spans
    a long stretch of thin air). Edges are interpolated linearly in c between the fine ones.

    Why: a view ray grazing the horizon (85-89 degrees from the zenith) holds most of its
    optical depth in its first few tens of kilometres, where the quadratic map of
    :func:`march_samples` puts a third of its steps; with the sun low the sunlit source then
    changes fast over each step. With 64 steps so placed (half by depth, 256 fine steps) the
    sky at sun 5 degrees lands where 512 quadratically spaced steps land, and 0.2-0.5 % below
    64 of them on the 85-89 degree rings (rural AOD 0.2, desert AOD 0.5, against the Monte
    Carlo tracer; docs/accuracy.md)."""
    e = np.asarray(edges_fine, dtype=float)
    g, f1 = e.shape
    if not 0.0 <= depth_share < 1.0:
        raise ValueError(f"depth_share must be in [0, 1), got {depth_share}")
    tau = np.concatenate([np.zeros((g, 1)), np.cumsum(np.asarray(sigma_fine, float) * np.diff(e, axis=1), axis=1)],
                         axis=1)
    c = depth_share * tau / np.maximum(tau[:, -1:], 1e-300) + (1.0 - depth_share) * np.linspace(0.0, 1.0, f1)
    # one search for all rays: ray k's coordinate shifted by 2k keeps the rows apart
    shift = 2.0 * np.arange(g)[:, None]
    flat = (c + shift).ravel()
    q = np.linspace(0.0, 1.0, n + 1)[None, :] + shift
    i = np.searchsorted(flat, q.ravel(), side="right").reshape(g, n + 1) - 1
    i = np.clip(i, np.arange(g)[:, None] * f1, np.arange(g)[:, None] * f1 + f1 - 2)
    lo, hi = flat[i], flat[i + 1]
    frac = np.clip((q - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
    ef = e.ravel()
    edges = ef[i] + frac * (ef[i + 1] - ef[i])
    edges[:, 0], edges[:, -1] = e[:, 0], e[:, -1]
    return 0.5 * (edges[:, 1:] + edges[:, :-1]), np.diff(edges, axis=1)


def step_transmittance(step_tau: np.ndarray, axis: int = 1, dtype=np.float64) -> np.ndarray:
    """Mean transmittance over each quadrature step of a ray, from the start of the ray:
    with tau_k the optical depth of step k (``step_tau``, steps along ``axis``) and T_k
    the transmittance to the step's start, T_k (1 - exp(-tau_k)) / tau_k, so that
    ``sum(step_transmittance * dt * J)`` is exact for a source J constant over each step
    (and ``sum(step_transmittance * dt * extinction)`` is exactly 1 - T_end). The
    midpoint value T_k exp(-tau_k / 2) is low by tau_k^2 / 24 of the step's share: on
    long grazing rays through the boundary layer, where the first steps hold optical
    depths of 0.3-1, single scattering at 1 degree above the horizon came out 1 % low
    (rural AOD 0.2, sun 60 degrees, 64 steps; with the step mean +0.06..0.2 %, 1024 steps
    +0.05..0.1 %, against the Monte Carlo tracer; notebooks/truth_misses/orders.py).
    With the sun at 5 degrees the sunlit source grows fast along such a ray and 64 steps
    are +0.6 % above 1024 (the midpoint value -0.7 %).

    ``dtype`` float32 (the marcher's per-sun march): the depths are summed in float64 and
    the exponentials taken in float32 (8x cheaper; a few 1e-7 relative)."""
    tau = np.asarray(step_tau, dtype=float)
    before = np.cumsum(tau, axis=axis) - tau
    if dtype is not np.float64:
        tau, before = tau.astype(dtype), before.astype(dtype)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(tau > 1e-8, -np.expm1(-tau) / np.where(tau > 1e-8, tau, 1.0), 1.0 - 0.5 * tau)
    np.negative(before, out=before)
    np.exp(before, out=before)
    before *= mean
    return before
