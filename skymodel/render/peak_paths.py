"""The delta-M sun beam near a low sun: the cut forward peak's light on its own, bent paths.

Delta-M (:mod:`skymodel.render.medium`) books the light that aerosols scatter into their cut
forward peak (a 6- or 12-degree cone, :func:`skymodel.render.medium.delta_m_cone_deg`) as not
scattered: it goes on along the sun's straight path, through the same air as the direct beam,
with the scaled extinction tau*. So every point's "sun" in the solver and in the marcher's
delta-M first scattering is exp(-tau*) along the straight line. Where the air along that line
changes little with the direction, that is right. Near a low sun it is not: the straight path to
a point low in the boundary layer is the densest there is (rural aerosol, sun on the horizon: a
direct beam of 2e-10 at 650 nm on the ground), while light turned by a few degrees reaches the
point along lines that cross far less air, or meet the ground (light from below the horizon does
not arrive at all). Against the Monte Carlo truth (rural AOD 0.2, ``final``) delta-M's straight
path left the horizon toward a sun at 0 degrees 5-9 % low at 650 nm out to 45 degrees of
azimuth, and the horizon of a sun at 5 degrees 1-2 % high (docs/accuracy.md).

This module replaces, at the nodes of the sun table (:class:`SunTransmittance`), delta-M's
beam by the direct beam plus the light turned once into the peak on its way:

    exp(-tau_eff) = exp(-tau) + sum_x k(x) integral ds sigma_peak(Q) T(Q -> sun) T*(Q -> P),

Q on the line that reaches the point P from elevation e_sun + x, k the cut peak projected on
the elevation axis (:func:`skymodel.render.peak_diffuse.projected_kernel`; offsets in
azimuth change a path's air little), sigma_peak the peak's share of aerosol scattering, T the
true extinction (the direct beam up to Q), T* the scaled one (further turns in the peak go
on forward). With x = 0 alone the integral is exp(-tau*) - exp(-tau) exactly: delta-M. The
difference tau_eff - tau* is added to the marcher's delta-M medium of the table as extra
columns, at probe wavelengths 50 nm apart at most, read linearly in wavelength
(:meth:`SunTransmittance.add_depth_columns`): the marcher's delta-M first scattering and
the directly lit ground see it. The solver keeps delta-M's beam: with the term in its first
order too (and so in every higher one) the truth's statistics moved by at most 0.15 % (mean)
and 0.35 % (worst; rural 0 and 5 degrees, desert 0 degrees), no closer to the Monte Carlo,
at 28 % more solve time (the spherical transport reads the table's columns at every sample). The peak
aureole (:mod:`skymodel.render.aureole`) keeps the straight path: it is its own small-angle
model of the same light seen near the sun.

Only nodes whose sun is within :data:`MAX_ELEVATION_DEG` of the local horizon and whose sun
line dips below :data:`MAX_LINE_FLOOR_M` get a term (elsewhere the lines differ little;
measured in ``tests/test_peak_paths.py``), at every altitude: in twilight a point 20 km up
sees a sun below its horizontal whose line grazes the boundary layer some 400 km away, and the
bent lines from it cross that air kilometres higher or lower (until 2026-11-28 only nodes
below 10 km had the term, and the sky of desert dust at sun -4 degrees came out 1-1.4 %
bright at 650 nm over its upper half against the Monte Carlo truth; docs/accuracy.md). Nodes
in the Earth's shadow get none (the bent light that reaches the shadow is left out).

The offsets x are spaced geometrically from 0.05 degrees out to the cone
(:func:`offset_nodes`, 37 lines for 12 degrees) and weighted by the kernel's integral against
each line's hat function (:func:`hat_weights`). The evenly spaced offsets a degree apart used
before, each weighted by the kernel's value there, put nearly all of a coarse dust's peak (half
its light within 0.2 degrees) on the straight line, and so nearly no bent light; the new nodes
give the same sky as evenly spaced ones 0.25, 0.1 and 0.05 degrees apart (97-481 lines) to
0.01 % at every view of the truth's set (desert -4 degrees).

The lines are evaluated in float32, only on their points up to the ground or the top and only
the lines the kernels weigh (against float64 on every point: tau_eff - tau* moved by at most
2e-5). With :meth:`SunTransmittance.basis_depths` gathering by flat index, the term's time per
solve (on - off, two threads) went from 0.70/0.60 to 0.40/0.38 s at ``final`` and from 0.57/0.51
to 0.35/0.32 s at ``preview`` (docs/benchmarks.md, "The peak paths").
"""

from __future__ import annotations

import numpy as np

from skymodel.numerics import linear_interp_matrix
from skymodel.render.medium import LowRank
from skymodel.render.peak_diffuse import peak_of, projected_kernel
from skymodel.render.sun_transmittance import horizon_mu
from skymodel.render.threads import SOLVER_THREADS, in_threads
from skymodel.wavelengths import spread_indices

#: Nodes whose sun stands higher than this above the local horizon (degrees) keep delta-M's beam.
MAX_ELEVATION_DEG = 20.0
#: ... and nodes whose straight sun line stays above this altitude (metres; the node's own
#: altitude, or its tangent point's where the sun is below the node's horizontal): their lines
#: cross thin air only. In desert dust (AOD 0.5) the term changes such nodes' optical depth by
#: at most 0.012 at a floor of 15-20 km, 0.006 at 20-30 km (0.42 at 10-15 km); leaving them
#: out moved the truth's views (docs/accuracy.md) by at most 0.05 % and saved ~0.1 s a solve.
MAX_LINE_FLOOR_M = 20_000.0
#: Lowest sun elevation above the local horizon (degrees) of a node that gets the term (the
#: solar disc's radius below it, the point is in the Earth's shadow).
MIN_ABOVE_HORIZON_DEG = -0.3
#: D is computed on every this-many-th altitude node of the sun table (linear in rho between).
ROW_STRIDE = 2
#: Sun elevations the bent beam is computed at (:func:`elevation_nodes`), then read linearly.
N_ELEVATIONS = 32
#: Elevation offsets x over the projected peak (:func:`offset_nodes`): the first beside 0 at
#: this many degrees, then each this factor further out, up to the cone.
OFFSET_FIRST_DEG = 0.05
OFFSET_RATIO = 1.4
#: Samples along each line (geometric in distance, from LINE_FIRST_M out to LINE_LENGTH_M).
LINE_STEPS = 64
LINE_FIRST_M = 20.0
#: Length of each line (metres): past it a low line has left the atmosphere; the lines of a
#: high node in twilight have not, but the straight and the bent ones are cut alike (2000 km:
#: the truth's statistics the same to 0.01 %).
LINE_LENGTH_M = 800e3
#: Probe wavelengths: evenly over the profile's range, at most this far apart (nm), read linearly
#: between. The term is not linear in wavelength where tau* is large (Rayleigh's lambda^-4): over
#: 380-780 nm (the default grid, rural AOD 0.2 and desert AOD 0.5 in June), against 41 probes, 5
#: probes (100 nm) left the beam up to 1.4e-3 off (127 % of a beam of 1e-3), 9 probes (50 nm)
#: 1.1e-4 (10 %), 13 probes 5e-5 (5 %).
PROBE_STEP_NM = 50.0
#: Nodes per batch (memory ~ batch x offsets x steps x ~80 bytes).
NODE_BATCH = 64


def offset_nodes(cutoff_deg: float) -> np.ndarray:
    """Elevation offsets x (radians, ascending, 0 among them) of the bent lines: 0, then
    +-OFFSET_FIRST_DEG growing by OFFSET_RATIO out to the cone's edge (the last one on it).
    A coarse dust's peak holds half its light within 0.2 degrees, and from a point 400 km
    from the sun line's tangent point a tenth of a degree moves that point 0.7 km in altitude:
    evenly spaced offsets a degree apart put nearly the whole peak on the straight line."""
    cut = float(cutoff_deg)
    n = int(np.ceil(np.log(cut / OFFSET_FIRST_DEG) / np.log(OFFSET_RATIO))) if cut > OFFSET_FIRST_DEG else 0
    side = np.minimum(OFFSET_FIRST_DEG * OFFSET_RATIO ** np.arange(n + 1), cut)
    side = np.unique(side)
    return np.radians(np.concatenate([-side[::-1], [0.0], side]))


def hat_weights(offsets_rad, x, k) -> np.ndarray:
    """Weights (n_offsets, W) of the lines at ``offsets_rad`` for the kernel k (n, W) sampled
    at x (n,) (evenly spaced): the integral of k times each offset's hat function (the
    piecewise-linear interpolation between the lines), normalised to sum 1. Exact for a line
    integral that is linear in x between neighbouring offsets, whatever the kernel's width."""
    xs = np.asarray(offsets_rad, float)
    x = np.asarray(x, float)
    # each line's hat function at x (n_off, n); zero beyond the outermost lines, not clamped
    hats = linear_interp_matrix(xs, x) * ((x >= xs[0]) & (x <= xs[-1]))
    w = hats @ np.asarray(k, float)
    total = w.sum(axis=0)
    return w / np.where(total > 0, total, 1.0)


def _kernels(profile, medium, probe_idx, offsets_rad):
    """Per aerosol regime with a cut peak: (regime, weights (n_offsets, P) summing to 1, from
    :func:`hat_weights`) at the wavelengths ``probe_idx`` of the profile."""
    peaks = peak_of(profile, medium)
    out = []
    for r in range(len(medium.aerosol)):
        if not np.any(medium.forward_fraction[r, probe_idx] > 0):
            continue
        x, k = projected_kernel(profile.aerosol_phase_angles_deg, peaks[r][:, probe_idx])
        out.append((r, hat_weights(offsets_rad, x, k)))
    return out


def elevation_nodes(n: int | None = None) -> np.ndarray:
    """Sun elevations above the local horizon (degrees) of the nodes the bent beam is
    computed on, from :data:`MIN_ABOVE_HORIZON_DEG` to :data:`MAX_ELEVATION_DEG`, crowded
    toward the horizon (the beam changes fastest there): evenly in asinh(e / 1 degree)."""
    lo, hi = np.arcsinh(MIN_ABOVE_HORIZON_DEG), np.arcsinh(MAX_ELEVATION_DEG)
    return np.sinh(np.linspace(lo, hi, N_ELEVATIONS if n is None else int(n)))


def horizon_elevation_deg(st, altitudes_m) -> np.ndarray:
    """Elevation (degrees) of the local horizon seen from ``altitudes_m`` (<= 0)."""
    return np.degrees(np.arcsin(horizon_mu(st.R, st.R + np.maximum(np.asarray(altitudes_m, float), 0.0))))


def line_floor_m(radius_m, altitudes_m, elevations_deg):
    """The lowest altitude (metres) of the straight line from a point toward a sun at
    ``elevations_deg`` above its horizontal: the point's own, or its tangent point's."""
    r = radius_m + np.asarray(altitudes_m, float)
    e = np.radians(np.asarray(elevations_deg, float))
    return np.where(e < 0.0, r * np.cos(e) - radius_m, r - radius_m)


def bent_minus_straight(sun_table, profile, medium, cutoff_deg: float, altitudes_m, elevations_deg, *,
                        true_medium: int = 0, scaled_medium: int = 2):
    """D = B_bent - B_straight at points of ``altitudes_m`` (n_h,) and ``elevations_deg``
    (n_h, n_e; local sun elevation, degrees): (probe wavelengths (P,) nm, D (n_h, n_e, P)),
    per unit solar irradiance. B is the peak light of the module docstring's integral, B_straight its x = 0
    line alone (exactly exp(-tau*) - exp(-tau), delta-M's share), both from the same
    quadrature so that its error cancels where the two differ little."""
    st = sun_table
    wl = np.asarray(profile.wavelengths_nm, float)
    pi = spread_indices(wl, PROBE_STEP_NM)
    probes = wl[pi]
    hh = np.broadcast_to(np.asarray(altitudes_m, float)[:, None], np.shape(elevations_deg))
    ee = np.asarray(elevations_deg, float)
    out = np.zeros(hh.shape + (pi.size,))
    offsets = offset_nodes(cutoff_deg)
    n_half = offsets.size // 2  # the x = 0 line
    kernels = _kernels(profile, medium, pi, offsets)
    mu = np.sin(np.radians(ee))
    vis = st.visible_fraction(hh, mu)
    todo = np.nonzero((vis > 1e-6) & (line_floor_m(st.R, hh, ee) < MAX_LINE_FLOOR_M))
    if not kernels or todo[0].size == 0:
        return probes, out
    # only the lines some kernel weighs, and the x = 0 line (the kernels end inside the cone)
    used = np.flatnonzero((sum(k.sum(axis=1) for _, k in kernels) > 0) | (np.arange(offsets.size) == n_half))
    offsets = offsets[used]
    kernels = [(r, k[used].astype(np.float32)) for r, k in kernels]
    i0 = int(np.flatnonzero(used == n_half)[0])  # the x = 0 line
    w_true = st.weights[true_medium][:, pi].astype(np.float32)
    ext_s = (medium.extinction_scaled, medium.extinction_scaled.weights[:, pi])
    # the peak's scattering coefficient f sigma_aerosol (each LowRank has its own basis)
    sig_peak = [(medium.aerosol[r], medium.aerosol[r].weights[:, pi] * medium.forward_fraction[r, pi][None, :], k)
                for r, k in kernels]
    # the scaled extinction and each peak's coefficient from one stacked basis (shared altitude nodes)
    lrs = [ext_s[0]] + [lr for lr, _, _ in sig_peak]
    stacked = LowRank(lrs[0].nodes_m, np.concatenate([m.basis for m in lrs], axis=1), np.zeros((1, 1)),
                      lrs[0].layered, lrs[0].top_m)
    ends = np.cumsum([m.rank for m in lrs])
    spans = list(zip(np.concatenate([[0], ends[:-1]]), ends))
    coef_weights = [w.astype(np.float32) for w in [ext_s[1]] + [w for _, w, _ in sig_peak]]
    s = np.concatenate([[0.0], np.geomspace(LINE_FIRST_M, LINE_LENGTH_M, LINE_STEPS - 1)])
    half_ds = (0.5 * np.diff(s)).astype(np.float32)[None, None, :, None]
    R, top = st.R, st.top

    def batch(a):  # each batch writes its own nodes of ``out``
        i, j = todo[0][a:a + NODE_BATCH], todo[1][a:a + NODE_BATCH]
        r0, e0 = R + hh[i, j], np.radians(ee[i, j])
        e = e0[:, None, None] + offsets[None, :, None]  # (n, X, 1) elevation of each line at P
        qx = s[None, None, :] * np.cos(e)  # toward the sun, in P's vertical plane
        qz = r0[:, None, None] + s[None, None, :] * np.sin(e)
        rq = np.hypot(qx, qz)
        hq = rq - R
        muq = (qx * np.cos(e0)[:, None, None] + qz * np.sin(e0)[:, None, None]) / rq  # Q's sun cosine
        # each line's points up to the ground or the top (a prefix of the line); only those are
        # computed, the rest stay 0 (the trapezoids and the running depth read them as such)
        ia = np.nonzero((np.cumsum(hq < 0.0, axis=-1) == 0) & (hq <= top))
        h_a, mu_a = hq[ia], muq[ia]
        full = hq.shape + (pi.size,)
        t_a = st.basis_depths(h_a, mu_a, (true_medium,))[0].astype(np.float32) @ w_true
        np.negative(t_a, out=t_a)
        np.exp(t_a, out=t_a)
        t_a *= st.visible_fraction(h_a, mu_a).astype(np.float32)[:, None]  # the direct beam at Q
        basis = stacked.basis_at(h_a).astype(np.float32)  # (points, ranks of all)
        coef = []
        for (a0, a1), w in zip(spans, coef_weights):
            c = np.zeros(full, np.float32)
            c[ia] = basis[:, a0:a1] @ w
            coef.append(c)
        ext_q = coef[0]
        depth = np.zeros(full, np.float32)  # scaled depth from Q back to P
        np.cumsum((ext_q[:, :, 1:] + ext_q[:, :, :-1]) * half_ds, axis=2, out=depth[:, :, 1:])
        np.negative(depth, out=depth)
        np.exp(depth, out=depth)
        reach_q = np.zeros(full, np.float32)
        reach_q[ia] = t_a * depth[ia]
        d = np.zeros((i.size, pi.size))
        for sig_q, (_, _, k) in zip(coef[1:], sig_peak):
            sig_q *= reach_q
            line = np.einsum("nxsp,xsp->nxp", sig_q[:, :, 1:] + sig_q[:, :, :-1],
                             np.broadcast_to(half_ds[0], (sig_q.shape[1],) + half_ds.shape[2:]))
            d += np.einsum("nxp,xp->np", line, k) - line[:, i0]
        out[i, j] = d / vis[i, j][:, None]

    in_threads(batch, range(0, todo[0].size, NODE_BATCH), SOLVER_THREADS)
    return probes, out


def bent_beam_depth(sun_table, profile, medium, cutoff_deg: float, *, true_medium: int = 0,
                    scaled_medium: int = 2):
    """The optical-depth change tau_eff - tau* at the sun table's nodes: (probe wavelengths
    (P,) in nm, (n_h, n_x, P)), 0 where no term applies. D (:func:`bent_minus_straight`) is
    computed on the table's altitude nodes and on :func:`elevation_nodes`, read linearly in
    elevation at each table node, and added to delta-M's beam: exp(-tau_eff) = exp(-tau*) + D,
    never below the direct beam exp(-tau).
    ``medium`` is the profile's :class:`FactoredMedium` (cut at ``cutoff_deg``);
    ``true_medium`` and ``scaled_medium`` the table's media holding its true and scaled
    extinction on the profile's wavelengths."""
    st = sun_table
    n_h, n_x = st.h_nodes.size, st.x_nodes.size
    rows = np.arange(n_h)
    e_nodes = elevation_nodes()
    # D on every ROW_STRIDE-th altitude node (and the last), linear in rho between them
    coarse = np.unique(np.append(rows[::ROW_STRIDE], n_h - 1))
    # computed at elevations above each altitude's own horizon, so that rows interpolate
    # along the shadow's edge, where D changes by orders of magnitude
    e_coarse = horizon_elevation_deg(st, st.h_nodes[coarse])[:, None] + e_nodes[None, :]
    probes, d_coarse = bent_minus_straight(st, profile, medium, cutoff_deg, st.h_nodes[coarse], e_coarse,
                                           true_medium=true_medium, scaled_medium=scaled_medium)
    rho = st.rho_nodes
    kc = np.clip(np.searchsorted(coarse, rows) - 1, 0, coarse.size - 2)
    fc = ((rho - rho[coarse[kc]]) / (rho[coarse[kc + 1]] - rho[coarse[kc]]))[:, None, None]
    d = d_coarse[kc] * (1.0 - fc) + d_coarse[kc + 1] * fc
    if not np.any(d):
        return probes, np.zeros((n_h, n_x, probes.size))
    pi = spread_indices(profile.wavelengths_nm, PROBE_STEP_NM)
    hh, xx = np.meshgrid(st.h_nodes, st.x_nodes, indexing="ij")
    mu = st._mu_from_x(hh, xx)
    elev = np.degrees(np.arcsin(mu)) - horizon_elevation_deg(st, hh)  # above the local horizon
    inside = (elev >= e_nodes[0]) & (elev <= e_nodes[-1])
    k = np.clip(np.searchsorted(e_nodes, elev) - 1, 0, e_nodes.size - 2)
    f = np.clip((elev - e_nodes[k]) / (e_nodes[k + 1] - e_nodes[k]), 0.0, 1.0)[..., None]
    r = rows[:, None]
    d_at = (d[r, k] * (1.0 - f) + d[r, k + 1] * f) * inside[..., None]  # (n_h, n_x, P)
    depth_true, depth_s = st.basis_depths(hh, mu, (true_medium, scaled_medium))  # one lookup for both
    tau_true = depth_true @ st.weights[true_medium][:, pi]
    k_s = st.base_ranks[scaled_medium]
    tau_s = depth_s[..., :k_s] @ st.weights[scaled_medium][:k_s, pi]
    t_eff = np.maximum(np.exp(-tau_s) + d_at, np.exp(-tau_true))
    return probes, np.where(inside[..., None], -np.log(np.clip(t_eff, 1e-300, None)) - tau_s, 0.0)


def add_peak_paths(sun_table, profile, medium, cutoff_deg: float, which: int = 2) -> None:
    """Put the bent paths into the sun table's delta-M medium ``which`` (the marcher's: the
    profile's wavelengths), as :meth:`SunTransmittance.add_depth_columns`."""
    probes, corr = bent_beam_depth(sun_table, profile, medium, cutoff_deg, scaled_medium=which)
    if np.any(corr):
        sun_table.add_depth_columns(which, corr, linear_interp_matrix(probes, profile.wavelengths_nm))
