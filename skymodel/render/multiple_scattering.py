"""Multiple scattering, order by order, on a grid of (altitude, direction, sun angle).

The radiance field of a spherically symmetric atmosphere lit by a parallel beam depends
on the altitude h of a point, the cosine mu_s of the sun's zenith angle there, and the
viewing direction (cosine mu of its zenith angle, azimuth phi from the sun's vertical
plane, phi in [0, pi] by symmetry). We solve for the light scattered twice or more on
that 4-D grid, at a reduced set of wavelengths (the multiple-scattering spectrum is
smooth). Its transport, the integral of a source along the ray through each grid node,
is done in two ways:

* the *independent column* approximation (the matrix M below): along a ray the source is
  read at the mu_s and phi of the point the ray starts from (as in a plane-parallel
  atmosphere), while path, altitude and local zenith angle follow the true spherical
  geometry, so horizontal rays stay finite and rays that meet the ground stop there;
* the *spherical* transport, where every point of the ray has its own sun angle,
  mu_s(t) = (r0 mu_s0 + t d.s) / r(t): the sun rises by about one degree for every 111
  km travelled toward it, so from a point in the Earth's shadow the air toward the sun
  is sunlit. The light scattered once is transported this way exactly
  (:func:`_first_order_spherical`); the column transport of the next orders (up to
  ``spherical_orders``) is corrected by the ratio of the two at a few probe wavelengths
  (:class:`_SphericalTransport`), and the later orders keep the columns or take the last
  correction (``spherical_tail``). Measured against the Monte Carlo tracer at sun
  elevation -4 degrees (notebooks/twilight_accuracy, "Fixed: the independent
  columns"): the median difference over the sky fell from
  15 % (columns) to about 1 %.

The azimuth nodes are what the first order's forward lobe toward a low sun needs (24 at
``final``: with 12 the sunward horizon in rural haze was 2 % low, notebooks/azimuth_count);
the smoother parts can run on every other node and be read back linearly: the spherical
correction (``coarse_phi`` of :class:`_SphericalTransport`) and the orders after the
corrected ones (:class:`CoarseOrders`).

The sun light that feeds the first order is attenuated along the true spherical path,
so the Earth's shadow is in the source. The final image integrates the resulting source
J_ms along each view ray with every point's own mu_s (:mod:`skymodel.render.marcher`).

Each order is two matrix products per wavelength:

* gather: L_n = M J_n + G Lg_n, where M (rays x nodes) holds the quadrature weights of
  the integral of the source along each grid ray, times the transmittance, spread onto
  the grid nodes by linear interpolation, and G the transmittance to the ground for rays
  that meet it (Lg: light leaving the Lambertian ground);
* scatter: J_{n+1} = sum over species of sigma_s(h) P L_n, where P holds the phase
  function between every pair of grid directions times the quadrature weight of the
  incoming direction (Gauss-Legendre in mu, per hemisphere or composite with nodes
  crowded at the horizon: :func:`zenith_nodes`; midpoint in phi), applied by azimuth
  mode (P is a circulant in the azimuth: :func:`phase_modes`).

Two safeguards keep thick media right: no grid ray gathers more than the physical
bound (its transport row is scaled down where interpolation between altitude nodes
would gather more, which once made the series diverge in dense layers), and in
to-tolerance mode the orders left out are added as a geometric series.

Aerosol phase functions have forward peaks far narrower than any practical direction
grid; we truncate the peak inside a cone (delta-M, Wiscombe 1977) and treat the cut
fraction f as unscattered (sigma_s* = (1 - f) sigma_s) inside the solver. The single
scattering seen in the image is computed exactly with the full phase function and the
true extinction (the TMS correction of Nakajima & Tanaka 1988), so the truncation only
touches the multiple-scattering part; the light it still leaves out, scattered two or
more times inside the peaks (the bright aureole around a low sun in dust), is added by
the marcher in the small-angle approximation (:mod:`skymodel.render.aureole`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from skymodel.geometry import altitude_grid
from skymodel.render.medium import FactoredMedium, LowRank, march_samples, step_transmittance
from skymodel.render.peak_diffuse import PeakDiffuse
from skymodel.render.rays import altitude_along, atmosphere_segment
from skymodel.render.solver_spectrum import SolverSpectrumMap, ozone_column
from skymodel.render.sun_transmittance import SUN_ANGULAR_RADIUS_RAD, SunTransmittance, horizon_mu
from skymodel.render.threads import SOLVER_THREADS, chunks_in_threads
from skymodel.wavelengths import spread_indices


#: Share of the sun-angle nodes below the horizon (:func:`sun_elevation_nodes`). Measured against the
#: Monte Carlo truth (issue 23, rural AOD 0.2, ``final``'s 32 nodes; notebooks/truth_misses/sun_nodes.py):
#: 10 of 32 below the horizon (the earlier u^2 spacing over -20..90), sun -4 degrees, median 0.89/1.06/1.91 %
#: at 450/550/650 nm, worst -7.7 %; 14 below, 0.76/0.57/0.63 %, -5.9 %; 18 below, 0.81/0.55/0.45 %, -5.3 %;
#: with the sun at 60, 20 and 5 degrees (rural) and 60, 20, 5 (desert) no median moved beyond its noise.
SUN_NODES_BELOW_SHARE = 0.55
#: Tables with fewer sun-angle nodes than this (tests, the accuracy bench's quick run) keep the earlier
#: spread (u^2 over -20..90, about a third below the horizon): with 12 nodes the share would leave 5 for
#: the day, 28 degrees apart at a 60-degree sun, which then outweighs every other knob of such a table.
SUN_NODES_SHARE_MIN = 24


def sun_elevation_nodes(n: int, lowest_deg: float = -20.0, below_share: float | None = None) -> np.ndarray:
    """Sun elevation nodes (degrees) from ``lowest_deg`` to 90, crowded near 0 where
    twilight changes fastest: ``round(n * below_share)`` nodes below the horizon at
    elevation = lowest_deg u^2 (u from 1 down to 0, evenly spaced, 0 excluded), the rest at
    90 u^2 (u from 0 to 1). ``below_share`` None: :data:`SUN_NODES_BELOW_SHARE` (fewer than
    :data:`SUN_NODES_SHARE_MIN` nodes: 90 sign(u) u^2 for u evenly spaced from
    -sqrt(-lowest_deg / 90) to 1, the earlier spread). A sun below
    the horizon lights the sky through the air above the Earth's shadow, whose height goes
    as the square of the sun's depth: the field changes there much faster with the sun's
    angle than by day, where a few nodes suffice (the cubic in log J between them)."""
    if below_share is None and n < SUN_NODES_SHARE_MIN:
        u = np.linspace(-np.sqrt(-lowest_deg / 90.0), 1.0, n)
        return 90.0 * np.sign(u) * u * u
    share = SUN_NODES_BELOW_SHARE if below_share is None else float(below_share)
    n_below = min(max(int(round(n * share)), 1), n - 2)
    u_below = np.linspace(1.0, 0.0, n_below + 1)[:-1]
    u_above = np.linspace(0.0, 1.0, n - n_below)
    return np.concatenate([lowest_deg * u_below * u_below, 90.0 * u_above * u_above])


#: The blended grid's lowest interval is split into this many equal ones (the nodes taken
#: from the rest of the grid, the count unchanged; :func:`table_altitudes`).
GROUND_SPLIT = 3


def table_altitudes(medium: FactoredMedium, n: int, top: float, weight_tau: float = 0.6,
                    ground_split: int | None = None) -> np.ndarray:
    """Altitude nodes for the solver's grid, adapted to the medium: equally spaced in a
    blend of the fraction of the column's extinction optical depth below h (weight
    ``weight_tau``, at the middle solver wavelength) and of the fixed stretched grid
    (which keeps nodes in the thin upper atmosphere). A thin aerosol layer near the
    ground then gets nodes inside it; linear interpolation across a layer that a node
    spacing cannot resolve overestimates the source there (measured: +1.5 % at the zenith
    for a 1.2 km aerosol layer with the plain grid).

    The lowest interval is then split into ``ground_split`` (default :data:`GROUND_SPLIT`)
    equal ones (for n >= 8; the count stays n). Near the ground the source of grazing
    directions changes within tens of metres: from a point h above the ground the ground a
    degree below the horizon lies 57 h away, one optical depth off at h ~ 60-70 m in the
    desert's and the rural site's haze (550 nm), and the cut forward peaks turn that bright
    ground light into the sky just above the horizon (:mod:`skymodel.render.peak_diffuse`).
    Read linearly between the nodes at 0 and 120 m (desert AOD 0.5, 24 nodes), that source
    put the horizon 90-180 degrees in azimuth from a sun at 60 degrees 1-1.5 % above the
    Monte Carlo truth; split in three it lands within 0.15 % of 64 nodes
    (notebooks/ground_nodes)."""
    split = (GROUND_SPLIT if ground_split is None else int(ground_split)) if n >= 8 else 1
    fine = altitude_grid(2001, top, stretch=3.0)
    ext = medium.extinction.at(fine)
    e = ext[:, ext.shape[1] // 2]
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(fine))])
    frac_tau = cum / cum[-1] if cum[-1] > 0 else np.linspace(0.0, 1.0, fine.size)
    frac_grid = np.linspace(0.0, 1.0, fine.size)  # position in the stretched grid
    c = weight_tau * frac_tau + (1.0 - weight_tau) * frac_grid
    nodes = np.interp(np.linspace(0.0, 1.0, n - (split - 1)), c, fine)
    nodes[0], nodes[-1] = 0.0, top
    if split > 1:
        nodes = np.concatenate([[0.0], nodes[1] * np.arange(1, split) / split, nodes[1:]])
    return nodes


@dataclass
class MultipleScatteringField:
    """The solved field: source J_ms (scattered >= 2 times, per metre) and the diffuse
    irradiance on the ground, on the grid, at ``wavelengths_nm``."""

    wavelengths_nm: np.ndarray
    h_nodes: np.ndarray
    mu_nodes: np.ndarray
    phi_nodes: np.ndarray
    mus_nodes: np.ndarray
    source: np.ndarray  # (n_wl, n_mu, n_phi, n_h, n_mus) float32, W m^-2 sr^-1 nm^-1 per metre
    ground_diffuse_irradiance: np.ndarray  # (n_mus, n_wl) W m^-2 nm^-1
    orders: int
    order_contributions: list  # relative size of each order's source (diagnostic)
    #: the scattering coefficient (a LowRank, :func:`scattering_reference`) when J is interpolated in
    #: altitude as sigma_s(h) times J / sigma_s read linearly; None: J itself read linearly (fields
    #: solved before, or ``source_by_scattering=False``)
    scattering: object = None

    @property
    def h_scale(self) -> np.ndarray | None:
        """sigma_s at the altitude nodes (n_h, n_wl) [m^-1] (``scattering``), or None."""
        return None if self.scattering is None else self.scattering.at(self.h_nodes)

    def source_at(self, h, mu, phi, mu_s, scale=None) -> np.ndarray:
        """Interpolated J_ms at points (any common shape) -> shape + (n_wl,).

        Linear in altitude, mu and phi; with ``scattering`` (the solver's
        ``source_by_scattering``) J / sigma_s is read linearly in altitude and multiplied by
        sigma_s(h) at the point: ``scale``, sigma_s at the points (broadcast to shape +
        (n_wl,); None: evaluated here from ``scattering``). J falls with the air's density,
        a convex function of altitude, which a straight line between nodes overestimates
        (``final``'s 32 nodes: the rural column of sigma_s by +0.6 %, the multiple
        scattering by about as much); J / sigma_s is smooth. Along the sun cosine mu_s, a cubic in log J
        (:func:`_sun_interp_cubic`): with the sun below the horizon the source falls
        steeply and not quite exponentially with the depth of the sun (the sunlit air
        recedes upward as the square of the depth, so log J bends down), and neither a
        straight line in J nor one in log J follows it between nodes 2-3 degrees
        apart. Measured on a Rayleigh sky at sun -4 degrees, 24 sun nodes against 192:
        mean |error| 2.9 % (log-linear) -> 1.0 % between -6 and -2 degrees, 0.36 % ->
        0.03 % with the sun up; the horizon toward the sun at 450 nm went from -2.9 %
        to -1.2 % against the Monte Carlo tracer (notebooks/twilight_accuracy).

        In float32 (the table of :meth:`_interp_table` and the arithmetic): the solver's
        source is float32 already; the interpolation in float32 instead of float64
        changed the marcher's total radiance by at most 2.7e-6 (median 5e-8) over its
        direction grid (``final``, rural and desert, sun 60/20/5/0/-4 degrees) and made
        the gather, the largest part of a sun's march, about 1.4x faster.
        """
        pts = np.broadcast_arrays(*(np.asarray(a, float) for a in (h, mu, phi, mu_s)))
        shape, n = pts[0].shape, pts[0].size
        flat = [a.reshape(-1) for a in pts]
        out = np.empty((n, self.wavelengths_nm.size), dtype=self._interp_table().dtype)
        # in blocks: the gather and the cubic hold several (points, 2, n_wl) arrays, which
        # for a whole chunk of view rays (2048 x 64 points) set the `final` preset's peak
        # memory (noon, 512x256: 2143 MiB read whole, 1813 MiB in blocks with the table
        # of _interp_table built node by node)
        for a in range(0, n, _SOURCE_BLOCK):
            out[a:a + _SOURCE_BLOCK] = self._source_block(*(x[a:a + _SOURCE_BLOCK] for x in flat))
        out = out.reshape(shape + (out.shape[-1],))
        if self.scattering is not None:
            out *= (self.scattering.at(pts[0]) if scale is None else scale).astype(out.dtype)
        return out

    def _source_block(self, h, mu, phi, mu_s) -> np.ndarray:
        """:meth:`source_at` for 1-D arrays of points -> (points, n_wl)."""
        tab = self._interp_table()  # (n_mu + 2, n_phi + 2, n_h, n_mus, 2, n_wl): log-slope beside J
        ih, fh = _axis(self.h_nodes, h)
        im, fm = _axis(self._mu_poles, mu)
        ip, fp = _axis(self._phi_edges, phi)
        isn, fs = _axis(self.mus_nodes, mu_s)
        fm, fp, fh, fs = (f.astype(tab.dtype) for f in (fm, fp, fh, fs))
        n_phi, n_h, n_mus = self._phi_edges.size, self.h_nodes.size, self.mus_nodes.size
        # the 8 corners of the (mu, phi, h) cell at sun nodes isn and isn + 1: one gather of
        # 16 table rows per point, then the weighted sum over the corners
        base = ((im * n_phi + ip) * n_h + ih) * n_mus + isn
        rows = np.take(tab.reshape(-1, tab.shape[-2] * tab.shape[-1]), (base[:, None] + _corner_offsets(
            n_phi, n_h, n_mus)).reshape(-1), axis=0).reshape(base.size, 8, 2, 2, tab.shape[-1])
        w = np.stack([wm * wp * wh for wm in (1 - fm, fm) for wp in (1 - fp, fp) for wh in (1 - fh, fh)], axis=1)
        at = np.einsum("nc,ncdkw->ndkw", w, rows)  # (points, sun node, J | slope, n_wl)
        dx = (self.mus_nodes[isn + 1] - self.mus_nodes[isn]).astype(tab.dtype)[..., None]
        return _sun_interp_cubic(at[:, 0, 0], at[:, 1, 0], at[:, 0, 1], at[:, 1, 1], dx, fs[..., None],
                                 (self.mus_nodes[isn + 1] <= 0.0)[..., None])

    def _interp_table(self):
        """J and d(log J)/d(mu_s) at the nodes, laid out (n_mu + 2, n_phi, n_h, n_mus, 2,
        n_wl) so that each gather of :meth:`source_at` reads one contiguous block
        (computed once), in float32 (the solver's precision; :meth:`source_at`), with a
        *pole* row at mu = -1 and at mu = +1 (``_mu_poles``, the zenith-cosine nodes with
        -1 and 1 added): the azimuthal mean of the nearest ring
        of nodes (J; the log-slope J-weighted), the same at every azimuth. The double
        Gauss-Legendre nodes never reach the poles (``final``'s top ring is 5.9 degrees
        from the zenith); clamped to that ring, the zenith read J at the ring's azimuth
        nearest its own, 5.9 degrees toward or away from the sun, instead of the
        azimuthal mean that a direction at the pole has. Linear interpolation between
        the ring and the pole removes that bias (issue 23: rural AOD 0.2, sun 20
        degrees, the zenith was +2.2 % above the Monte Carlo tracer at ``final``).

        Likewise an *edge* column at phi = 0 and at phi = pi (``_phi_edges``): the azimuth
        nodes are midpoints, (k + 1/2) pi / n_phi, so the principal plane itself lies outside
        them and was read at the nearest node, flat in phi. J is even in phi about both
        edges; the edge holds the even quadratic in log J through the two nearest nodes,
        J_1 (J_1 / J_2)^(1/8) (the log-slope extrapolated the same way), and phi is read
        linearly between it and the first node. (Measured against the Monte Carlo truth:
        docs/accuracy.md, "The principal plane".)"""
        tab = getattr(self, "_table_edges", None)
        if tab is not None:
            return tab
        with _TABLE_LOCK:  # the marcher's threads ask at once: one builds, the others wait for it
            if getattr(self, "_table_edges", None) is None:
                self._build_interp_table()
        return self._table_edges

    def _build_interp_table(self) -> None:
        """Fill ``_mu_poles``, ``_phi_edges`` and then ``_table_edges`` (:meth:`_interp_table`);
        the table is published last, so a reader that sees it also sees its nodes."""
        src = np.moveaxis(self.source, 0, -1)  # (n_mu, n_phi, n_h, n_mus, n_wl)
        if self.scattering is not None:  # J / sigma_s, read linearly in altitude (:meth:`source_at`)
            src = src / _safe(self.h_scale).astype(np.float32)[None, None, :, None, :]
        n_mu, n_phi = src.shape[:2]
        tab = np.empty((n_mu + 2, n_phi + 2) + src.shape[2:-1] + (2, src.shape[-1]), dtype=np.float32)
        # one zenith node at a time, so the slopes' temporaries stay small; the table
        # then holds the only copy of J (``source`` becomes a view of it)
        for i in range(n_mu):
            tab[i + 1, 1:-1, ..., 0, :] = src[i]
            tab[i + 1, 1:-1, ..., 1, :] = _log_slopes(self.mus_nodes, np.asarray(src[i], dtype=np.float64), axis=2)
        for edge, a, b in ((0, 1, 2), (n_phi + 1, n_phi, n_phi - 1)):
            ring_j, ring_s = tab[1:-1, a, ..., 0, :], tab[1:-1, a, ..., 1, :]
            if n_phi < 2:
                tab[1:-1, edge] = tab[1:-1, a]
                continue
            j2 = tab[1:-1, b, ..., 0, :]
            with np.errstate(invalid="ignore", divide="ignore"):
                ratio = np.where((ring_j > 0) & (j2 > 0), ring_j / np.where(j2 > 0, j2, 1.0), 1.0)
            tab[1:-1, edge, ..., 0, :] = ring_j * ratio ** np.float32(0.125)
            tab[1:-1, edge, ..., 1, :] = ring_s + (ring_s - tab[1:-1, b, ..., 1, :]) * np.float32(0.125)
        for pole, ring in ((0, 1), (n_mu + 1, n_mu)):
            j = tab[ring, 1:-1, ..., 0, :]  # (n_phi, n_h, n_mus, n_wl); the phi nodes are equally spaced
            jm = j.mean(axis=0)
            with np.errstate(invalid="ignore", divide="ignore"):
                sl = np.where(jm > 0, (j * tab[ring, 1:-1, ..., 1, :]).mean(axis=0) / np.where(jm > 0, jm, 1.0),
                              tab[ring, 1:-1, ..., 1, :].mean(axis=0))
            tab[pole, ..., 0, :] = jm[None]
            tab[pole, ..., 1, :] = sl[None]
        self._mu_poles = np.concatenate([[-1.0], np.asarray(self.mu_nodes, dtype=float), [1.0]])
        self._phi_edges = np.concatenate([[0.0], np.asarray(self.phi_nodes, dtype=float), [np.pi]])
        self._table = self._table_poles = None  # tables of older versions (pickled solutions) are not used
        if self.scattering is None:
            self.source = np.moveaxis(tab[1:-1, 1:-1, ..., 0, :], -1, 0)  # the same values, a view: one copy kept
        self._table_edges = tab

    def ground_irradiance_at(self, mu_s) -> np.ndarray:
        """Diffuse (sky) irradiance on the ground where the sun's zenith cosine is mu_s
        (interpolated in mu_s as in :meth:`source_at`)."""
        i, f = _axis(self.mus_nodes, np.asarray(mu_s, float))
        e = self.ground_diffuse_irradiance
        s = _log_slopes(self.mus_nodes, e, axis=0)
        dx = (self.mus_nodes[i + 1] - self.mus_nodes[i])[..., None]
        return _sun_interp_cubic(e[i], e[i + 1], s[i], s[i + 1], dx, f[..., None],
                                 (self.mus_nodes[i + 1] <= 0.0)[..., None])


#: points per block in :meth:`MultipleScatteringField.source_at` (bounds its temporaries:
#: the gathered rows are 16 x 2 x n_wl float32 a point, 21 MB at 41 wavelengths)
_SOURCE_BLOCK = 4096

#: serialises the first build of a field's interpolation table (the marcher's threads read
#: the field at once; a test on the CI machine caught one reading ``_mu_poles`` between the
#: table's publication and its nodes')
_TABLE_LOCK = threading.Lock()


def _corner_offsets(n_phi: int, n_h: int, n_mus: int) -> np.ndarray:
    """Row offsets in the flattened table of :meth:`MultipleScatteringField._interp_table`
    of the 8 corners (mu, phi, h; in that order, lower node first) x 2 sun nodes of a cell."""
    return np.array([((dm * n_phi + dp) * n_h + dh) * n_mus + ds
                     for dm in (0, 1) for dp in (0, 1) for dh in (0, 1) for ds in (0, 1)])


def _axis(nodes, x):
    """Lower node index and fraction for linear interpolation (clamped to the nodes)."""
    x = np.clip(x, nodes[0], nodes[-1])
    i = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    return i, (x - nodes[i]) / (nodes[i + 1] - nodes[i])


def _safe(sigma):
    """sigma [m^-1] with zeros (no scatterer: above the top) replaced by 1, to divide by."""
    sigma = np.asarray(sigma, dtype=float)
    return np.where(sigma > 0.0, sigma, 1.0)


def scattering_reference(medium: FactoredMedium):
    """The scattering coefficient of the solver's medium, air plus the delta-M scaled
    aerosol regimes, as one LowRank (``.at(h) -> (..., n_wl)`` m^-1): the altitude shape
    of the multiple-scattering source J = sum_s sigma_s(h) P_s L, by which J is
    interpolated between the altitude nodes (:meth:`MultipleScatteringField.source_at`,
    :func:`column_transport_matrix`)."""
    parts = [medium.rayleigh] + [a for a in medium.aerosol_scaled if np.any(a.weights)]
    if len(parts) == 1:
        return parts[0]
    nodes = parts[0].nodes_m
    if any(p.layered != parts[0].layered or not np.array_equal(p.nodes_m, nodes) for p in parts):
        raise ValueError("the medium's coefficients are on different altitude nodes")
    # on the nodes (smooth) or per layer (layered) the basis values are the coefficients themselves
    total = sum(p.basis @ p.weights for p in parts)
    return LowRank.from_matrix(nodes, total, parts[0].layered, parts[0].top_m)


def _log_slopes(nodes, values, axis: int = -1):
    """d(log v)/dx at the nodes along ``axis`` of ``values``, from the cubic spline
    (not-a-knot) through log v; NaN along every line of nodes that holds a value <= 0
    (where :func:`_sun_interp_cubic` falls back to :func:`_sun_interp`). A spline's
    slopes at its nodes are linear in its values, so they are one matrix product."""
    v = np.moveaxis(np.asarray(values), axis, -1)
    d = _spline_slope_matrix(tuple(np.asarray(nodes, dtype=float))).astype(v.dtype, copy=False)
    ok = np.all(v > 0.0, axis=-1, keepdims=True)
    lg = np.log(np.where(ok, v, 1.0))
    slopes = np.where(ok, lg @ d.T, np.nan)
    return np.moveaxis(slopes, -1, axis)


_SLOPE_MATRICES: dict = {}


def _spline_slope_matrix(nodes: tuple) -> np.ndarray:
    """(n, n) matrix D with D @ y = slopes at the nodes of the not-a-knot cubic spline
    through y (for n < 4 the polynomial through the n points, as scipy): the tridiagonal
    system of scipy's ``CubicSpline`` (continuity of the second derivative inside,
    not-a-knot at both ends) solved for the unit vectors, here
    in numpy (importing scipy.interpolate cost a render 0.5-2 s; equal to
    ``CubicSpline(x, np.eye(n), axis=0)(x, 1)`` to 1e-15 of its largest element,
    tests/test_sun_interpolation.py)."""
    if nodes not in _SLOPE_MATRICES:
        x = np.asarray(nodes, dtype=float)
        n = x.size
        if n < 4:  # the line or the parabola through the points
            k = np.arange(n)
            v = x[:, None] ** k  # Vandermonde
            dv = np.where(k > 0, k * x[:, None] ** np.maximum(k - 1, 0), 0.0)
            _SLOPE_MATRICES[nodes] = dv @ np.linalg.inv(v)
            return _SLOPE_MATRICES[nodes]
        dx = np.diff(x)
        a = np.zeros((n, n))  # a @ slopes = b @ y
        b = np.zeros((n, n))
        dy = np.zeros((n - 1, n))  # dy @ y = slope of each interval
        dy[np.arange(n - 1), np.arange(n - 1)] = -1.0 / dx
        dy[np.arange(n - 1), np.arange(1, n)] = 1.0 / dx
        i = np.arange(1, n - 1)
        a[i, i] = 2.0 * (dx[:-1] + dx[1:])
        a[i, i + 1] = dx[:-1]
        a[i, i - 1] = dx[1:]
        b[1:-1] = 3.0 * (dx[1:, None] * dy[:-1] + dx[:-1, None] * dy[1:])
        d0, d1 = x[2] - x[0], x[-1] - x[-3]
        a[0, 0], a[0, 1] = dx[1], d0
        b[0] = ((dx[0] + 2.0 * d0) * dx[1] * dy[0] + dx[0] ** 2 * dy[1]) / d0
        a[-1, -1], a[-1, -2] = dx[-2], d1
        b[-1] = (dx[-1] ** 2 * dy[-2] + (2.0 * d1 + dx[-1]) * dx[-2] * dy[-1]) / d1
        _SLOPE_MATRICES[nodes] = np.linalg.solve(a, b)
    return _SLOPE_MATRICES[nodes]


def _sun_interp_cubic(a, b, sa, sb, dx, f, below):
    """Interpolate between node values ``a`` (f = 0) and ``b`` (f = 1) that lie ``dx``
    apart, with slopes ``sa``, ``sb`` of log v there: the cubic Hermite polynomial in
    log v where both values are positive and both slopes known (a cubic spline through
    log v, when the slopes are the spline's), else :func:`_sun_interp`. The result
    matches a and b at the nodes, so it stays continuous across them."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = f
        t2 = t * t
        t3 = t2 * t
        c0, c1 = 2.0 * t3 - 3.0 * t2 + 1.0, (t3 - 2.0 * t2 + t) * dx
        c2, c3 = 3.0 * t2 - 2.0 * t3, (t3 - t2) * dx
        shape = np.broadcast_shapes(*(np.shape(v) for v in (a, b, sa, sb, c1, c3)))
        if not shape:
            out = np.array(np.exp(c0 * np.log(a) + c1 * sa + c2 * np.log(b) + c3 * sb))
        else:  # the same sums in the same order, in two work arrays instead of ten temporaries
            dtype = np.result_type(c0, c1, c2, c3, a, b, sa, sb)
            out, term = np.empty(shape, dtype), np.empty(shape, dtype)
            np.multiply(c0, np.log(a), out=out)
            out += np.multiply(c1, sa, out=term)
            out += np.multiply(c2, np.log(b), out=term)
            out += np.multiply(c3, sb, out=term)
            np.exp(out, out=out)
    bad = ~np.isfinite(out)  # a or b <= 0, or a slope unknown
    if np.any(bad):
        shape = out.shape
        out[bad] = _sun_interp(np.broadcast_to(a, shape)[bad], np.broadcast_to(b, shape)[bad],
                               np.broadcast_to(f, shape)[bad], np.broadcast_to(below, shape)[bad])
    return out


def _sun_interp(a, b, f, below):
    """Interpolate between values ``a`` (f = 0) and ``b`` (f = 1): geometrically
    (linear in log) where ``below`` and both are positive, else linearly. Measured at
    sun elevation -4 degrees (synthetic AOD 0.2 sky, 24 sun nodes): linear interpolation
    put the multiple-scattering radiance of the anti-sun horizon 25 % above its
    value with 192 nodes; geometric interpolation is within about 3 % of it at 24 nodes.
    Now the fallback of :func:`_sun_interp_cubic` where a value is <= 0 (the cubic in
    log, :meth:`MultipleScatteringField.source_at`, is closer still). (The logarithms
    are taken only where needed.)"""
    out = a * (1.0 - f) + b * f
    pos = np.broadcast_to(below, out.shape) & (a > 0.0) & (b > 0.0)
    if np.any(pos):
        fb = np.broadcast_to(f, out.shape)[pos]
        out[pos] = np.exp(np.log(np.broadcast_to(a, out.shape)[pos]) * (1.0 - fb)
                          + np.log(np.broadcast_to(b, out.shape)[pos]) * fb)
    return out


@dataclass(frozen=True)
class TableGrid:
    """The solver's grid: altitude x view direction x sun angle, at the solver wavelengths.

    Directions are (mu, phi) pairs, direction index = i_mu * n_phi + i_phi: mu the cosine
    of the view zenith angle (double or composite Gauss-Legendre, ascending:
    :func:`zenith_nodes`), phi the azimuth from the
    sun's vertical plane in radians (midpoints of [0, pi]; the field is symmetric in phi,
    so the integral over [0, 2 pi) of g is the sum over [0, pi) of g(phi) + g(-phi)).
    """

    wavelengths_nm: np.ndarray  # (n_wl,) nm
    h_nodes: np.ndarray  # (n_h,) altitude, m, ascending from 0 to just below the top
    mu_nodes: np.ndarray  # (n_mu,) cosine of the view zenith angle, ascending (zenith_nodes)
    mu_weights: np.ndarray  # (n_mu,) their quadrature weights on [-1, 1] (sum 2)
    phi_nodes: np.ndarray  # (n_phi,) rad, in (0, pi)
    phi_weight: float  # rad, weight of every phi node (pi / n_phi)
    mus_nodes: np.ndarray  # (n_mus,) cosine of the sun's zenith angle, ascending

    @property
    def n_wl(self) -> int:
        return self.wavelengths_nm.size

    @property
    def n_h(self) -> int:
        return self.h_nodes.size

    @property
    def n_mu(self) -> int:
        return self.mu_nodes.size

    @property
    def n_phi(self) -> int:
        return self.phi_nodes.size

    @property
    def n_mus(self) -> int:
        return self.mus_nodes.size

    @property
    def n_dir(self) -> int:
        return self.n_mu * self.n_phi

    @property
    def dir_mu(self) -> np.ndarray:
        """(n_dir,) zenith cosine of every direction."""
        return np.repeat(self.mu_nodes, self.n_phi)

    @property
    def dir_phi(self) -> np.ndarray:
        """(n_dir,) azimuth of every direction, rad."""
        return np.tile(self.phi_nodes, self.n_mu)

    @property
    def dir_sin(self) -> np.ndarray:
        """(n_dir,) sine of the zenith angle of every direction."""
        return np.sqrt(1.0 - self.dir_mu**2)

    def empty_field(self) -> MultipleScatteringField:
        """A field with no light scattered twice or more (single scattering only)."""
        return MultipleScatteringField(self.wavelengths_nm, self.h_nodes, self.mu_nodes, self.phi_nodes,
                                       self.mus_nodes, np.zeros((self.n_wl, self.n_mu, self.n_phi, self.n_h,
                                                                 self.n_mus)), np.zeros((self.n_mus, self.n_wl)),
                                       1, [])


def zenith_nodes(n_mu: int, horizon_deg: float = 0.0, horizon_nodes: int = 0):
    """Zenith cosines (ascending) and their weights on [-1, 1] (sum 2): in each hemisphere
    ``n_mu / 2`` Gauss-Legendre nodes on mu in [0, 1] (double Gauss-Legendre, so the horizon is
    never a node), or, with ``horizon_nodes`` > 0, a composite rule: that many Gauss-Legendre
    nodes on [0, sin(horizon_deg)] and the rest on [sin(horizon_deg), 1].

    The composite rule puts the nodes where the field changes fastest: near a sun at or below
    the horizon the diffuse light toward the sun is a glow a few degrees high, which the plain
    rule's 32 nodes (0.3, 1.6, 3.9, 7.0 degrees from the horizon) integrate and interpolate
    coarsely (desert AOD 0.5, sun -4 degrees, ``final``: 88/0 at 650 nm -8.2 % against the Monte
    Carlo truth; 6 of 20 nodes per hemisphere within 4 degrees: -3.2 %; docs/accuracy.md)."""
    if n_mu % 2:
        raise ValueError("n_mu must be even (double Gauss-Legendre)")
    half = n_mu // 2
    horizon_nodes = int(horizon_nodes)
    if horizon_nodes > 0:
        if not (horizon_nodes < half and 0.0 < float(horizon_deg) < 90.0):
            raise ValueError(f"horizon_nodes must be in [1, {half - 1}] and horizon_deg in (0, 90)")
        a = np.sin(np.radians(float(horizon_deg)))
        x1, w1 = np.polynomial.legendre.leggauss(horizon_nodes)
        x2, w2 = np.polynomial.legendre.leggauss(half - horizon_nodes)
        up = np.concatenate([0.5 * a * (x1 + 1.0), a + 0.5 * (1.0 - a) * (x2 + 1.0)])
        w_up = np.concatenate([0.5 * a * w1, 0.5 * (1.0 - a) * w2])
    else:
        x, w = np.polynomial.legendre.leggauss(half)
        up, w_up = 0.5 * (x + 1.0), 0.5 * w
    return np.concatenate([-up[::-1], up]), np.concatenate([w_up[::-1], w_up])


def build_table_grid(profile, medium: FactoredMedium, *, n_altitudes: int, n_mu: int, n_phi: int,
                     n_mus: int, horizon_deg: float = 0.0, horizon_nodes: int = 0) -> TableGrid:
    """The solver's grid for ``profile``: ``n_altitudes`` altitude nodes adapted to the
    medium (:func:`table_altitudes`), ``n_mu`` zenith cosines (:func:`zenith_nodes`: ``n_mu``
    even, half of them in each hemisphere, so the horizon is never a node; ``horizon_nodes`` of
    each half within ``horizon_deg`` of the horizon), ``n_phi`` azimuths (midpoint rule on
    [0, pi]) and ``n_mus`` sun cosines (:func:`sun_elevation_nodes`)."""
    mu_nodes, mu_w = zenith_nodes(n_mu, horizon_deg, horizon_nodes)
    assert n_altitudes >= 2 and n_phi >= 1 and n_mus >= 2, (n_altitudes, n_phi, n_mus)
    h_nodes = table_altitudes(medium, n_altitudes, profile.top_altitude_m * (1 - 1e-9))
    phi_nodes = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    mus_nodes = np.sin(np.radians(sun_elevation_nodes(n_mus)))
    return TableGrid(profile.wavelengths_nm, h_nodes, mu_nodes, mu_w, phi_nodes, np.pi / n_phi, mus_nodes)


# ------------------------------------------------------------------ rays and transport


@dataclass(frozen=True)
class GridRays:
    """One ray from every (altitude, zenith) node of a :class:`TableGrid` (ray index =
    i_h * n_mu + i_mu, pointing at azimuth 0) to the top of the atmosphere or the
    ground, sampled at ``n_steps`` midpoints (:func:`~skymodel.render.medium.march_samples`)."""

    r0: np.ndarray  # (rays,) m, distance of the start from the planet's centre
    mu0: np.ndarray  # (rays,) zenith cosine at the start
    t: np.ndarray  # (rays, steps) m, distance of each sample from the start
    dt: np.ndarray  # (rays, steps) m, length of each sample's step
    h: np.ndarray  # (rays, steps) m, altitude of each sample (>= 0)
    hits: np.ndarray  # (rays,) bool, the ray ends on the ground
    trans: np.ndarray  # (rays, steps, n_wl) delta-M scaled transmittance from the start, mean over each step
    ground_t: np.ndarray  # (rays, n_wl) scaled transmittance to the ground (0 for rays that miss it)
    ih: np.ndarray  # (rays, steps) altitude node below each sample
    fh: np.ndarray  # (rays, steps) its fraction toward the next node
    im: np.ndarray  # (rays, steps) zenith-cosine node below each sample's local zenith cosine
    fm: np.ndarray  # (rays, steps) its fraction toward the next node


def trace_grid_rays(grid: TableGrid, medium: FactoredMedium, planet_radius_m: float, top_altitude_m: float,
                    n_steps: int) -> GridRays:
    """March the grid's rays through the delta-M scaled medium: sample positions,
    altitudes, local zenith cosines (interpolation between grid nodes) and the scaled
    transmittance from each ray's start (each step's mean, :func:`~skymodel.render.medium.step_transmittance`,
    and to the ground)."""
    assert planet_radius_m > 0 and top_altitude_m > 0 and n_steps >= 1, (planet_radius_m, top_altitude_m, n_steps)
    R = planet_radius_m
    hh, mm = np.meshgrid(grid.h_nodes, grid.mu_nodes, indexing="ij")  # ray (i, j) -> index i * n_mu + j
    r0 = R + hh.ravel()
    mu0 = mm.ravel()
    p = np.stack([np.zeros_like(r0), np.zeros_like(r0), r0], axis=-1)
    d = np.stack([np.sqrt(1.0 - mu0**2), np.zeros_like(r0), mu0], axis=-1)
    t0, t1, hits = atmosphere_segment(p, d, R, R + top_altitude_m)
    t, dt = march_samples(p, d, t0, t1, n_steps, R)
    h = np.clip(altitude_along(p, d, t, R), 0.0, None)
    r = R + h
    mu_t = np.clip((r0[:, None] * mu0[:, None] + t) / r, -1.0, 1.0)  # local zenith cosine of the ray
    ext = medium.extinction_scaled.at(h)  # (rays, steps, n_wl)
    trans = step_transmittance(ext * dt[..., None])  # each step's mean transmittance
    ground_t = np.where(hits[:, None], np.exp(-(ext * dt[..., None]).sum(axis=1)), 0.0)  # (rays, n_wl)
    ih, fh = _axis(grid.h_nodes, h)
    im, fm = _axis(grid.mu_nodes, mu_t)
    return GridRays(r0, mu0, t, dt, h, hits, trans, ground_t, ih, fh, im, fm)


def transport_row_scale(grid: TableGrid, rays: GridRays, medium: FactoredMedium, sigma_nodes=None,
                        sigma_samples=None) -> np.ndarray:
    """Factor (rays, n_wl), at most 1, that keeps each grid ray's transport within the
    physical bound.

    For a source proportional to the extinction, a ray gathers sum dt T sigma(h
    interpolated between altitude nodes), whose exact value sum dt T sigma(h) is at most
    1 - T_end < 1. Linear interpolation between nodes overestimates it grossly where a
    node sits in a dense layer and the ray runs through thin air beside it: measured up
    to 15-35 (30-85x the exact value) on some rays for the 'background' aerosol at AOD 5
    with 16-48 altitude nodes, which made each order larger than the last (the series
    diverged to 8x the solar irradiance). Rows above the physical bound 1 are scaled down
    to it; rows below it are left as they were (an ordinary sky changes by < 0.1 %: only
    grazing rays through the whole atmosphere come near the bound). ``sigma_nodes`` (n_h, n_wl)
    and ``sigma_samples`` (rays, steps, n_wl): the scattering coefficient by which the transport
    reads the source between altitude nodes (:func:`column_transport_matrix`), None: linearly."""
    ih, fh = rays.ih, rays.fh
    ext_nodes = medium.extinction_scaled.at(grid.h_nodes)  # (n_h, n_wl)
    if sigma_nodes is not None:
        ext_nodes = ext_nodes / _safe(sigma_nodes)
    ext_interp = ext_nodes[ih] * (1.0 - fh)[..., None] + ext_nodes[np.minimum(ih + 1, grid.n_h - 1)] * fh[..., None]
    if sigma_samples is not None:
        ext_interp = ext_interp * sigma_samples
    gathered = ((rays.dt[..., None] * rays.trans) * ext_interp).sum(axis=1)  # (rays, n_wl)
    return 1.0 / np.maximum(gathered, 1.0)


def column_transport_matrix(grid: TableGrid, rays: GridRays, row_scale: np.ndarray, sigma_nodes=None,
                            sigma_samples=None) -> np.ndarray:
    """The independent-column transport M, (n_wl, rays, nodes) float32, nodes = i_h *
    n_mu + i_mu as the rays: (M J)[ray] is the integral of a source J along the ray,
    int T(t) J(h(t), mu(t)) dt by the midpoint rule (J at the middle of each step, T its
    mean over the step: :func:`~skymodel.render.medium.step_transmittance`), J read between the four (altitude,
    zenith) nodes around each sample (at the ray's start's sun angle and azimuth: the
    columns). Rows scaled by ``row_scale`` (:func:`transport_row_scale`). Dimensionless
    per metre of source: M [m] times J [W m^-2 sr^-1 nm^-1 m^-1]. ``sigma_nodes`` (n_h, n_wl)
    and ``sigma_samples`` (rays, steps, n_wl), the scattering coefficient
    (:func:`scattering_reference`) at the nodes and the samples: J is read as sigma_s(h) times
    J / sigma_s between the altitude nodes (M's sample weights times sigma_s there, each node's
    column divided by sigma_s at the node); None: J linearly."""
    n_rays, n_wl = rays.r0.size, grid.n_wl
    assert row_scale.shape == (n_rays, n_wl) and np.all(row_scale <= 1.0), row_scale.shape
    ih, fh, im, fm = rays.ih, rays.fh, rays.im, rays.fm
    ray_idx = np.broadcast_to(np.arange(n_rays)[:, None], rays.h.shape).ravel()
    # every sample's four (altitude, zenith) corners: the flat index ray * nodes + node and
    # the interpolation weight, corner after corner (the order of the sums)
    cells, corner_w = [], []
    for dh_, wh in ((0, 1 - fh), (1, fh)):
        for dm_, wm in ((0, 1 - fm), (1, fm)):
            cells.append(ray_idx * n_rays + ((ih + dh_) * grid.n_mu + (im + dm_)).ravel())
            corner_w.append((wh * wm).ravel())
    cells, corner_w = np.concatenate(cells), np.concatenate(corner_w)
    base = rays.dt[..., None] * rays.trans
    node_scale = None
    if sigma_nodes is not None:
        base = base * sigma_samples
        node_scale = np.repeat(1.0 / _safe(sigma_nodes), grid.n_mu, axis=0)  # (nodes, n_wl)
    M = np.empty((n_wl, n_rays, n_rays), dtype=np.float32)
    # one wavelength at a time, summed in float64 by bincount (the same sums in the same order
    # as np.add.at into a (rays, nodes, n_wl) float64 array, without its 0.34 GB at final)
    for w in range(n_wl):
        m_w = np.bincount(cells, np.tile(base[..., w].ravel(), 4) * corner_w, minlength=n_rays * n_rays)
        m_w = m_w.reshape(n_rays, n_rays) * row_scale[:, w, None]
        M[w] = m_w if node_scale is None else m_w * node_scale[None, :, w]
    return M  # (n_wl, rays, nodes)


def ground_transmittance_vector(rays: GridRays) -> np.ndarray:
    """G, (n_wl, rays) float32: the scaled transmittance from each grid ray's start to
    the ground (0 for rays that miss it), which carries the light leaving the ground."""
    return rays.ground_t.T.astype(np.float32)


# ------------------------------------------------------------------ layouts
# "dir" layout (n_wl, n_dir, n_h, n_mus) with dir = i_mu * n_phi + i_phi: what scattering reads;
# "ray" layout (n_wl, n_h * n_mu, n_phi * n_mus) with ray = i_h * n_mu + i_mu: what transport reads.


def dir_in_ray_order(a: np.ndarray, n_mu: int, n_phi: int) -> np.ndarray:
    """An array in the dir layout, (..., n_mu * n_phi, n_h, k) with direction
    i_mu * n_phi + i_phi (k: sun nodes, or any trailing axis), viewed with its axes in the ray
    layout's order: (..., n_h, n_mu, n_phi, k), a strided view of the same memory (writes
    through it land in ``a``)."""
    *lead, n_dir, n_h, k = a.shape
    assert n_dir == n_mu * n_phi, (a.shape, n_mu, n_phi)
    j = len(lead)
    return a.reshape(*lead, n_mu, n_phi, n_h, k).transpose(*range(j), j + 2, j, j + 1, j + 3)


def to_ray_layout(a: np.ndarray, grid: TableGrid) -> np.ndarray:
    """A field in the dir layout, laid out by grid ray: (n_wl, n_h * n_mu, n_phi * n_mus), a copy."""
    return dir_in_ray_order(a, grid.n_mu, grid.n_phi).reshape(grid.n_wl, grid.n_h * grid.n_mu, grid.n_phi * grid.n_mus)


def to_dir_layout(a: np.ndarray, grid: TableGrid) -> np.ndarray:
    """A field in the ray layout, laid out by direction: (n_wl, n_dir, n_h, n_mus), a copy."""
    out = np.empty((grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus), dtype=a.dtype)
    np.copyto(dir_in_ray_order(out, grid.n_mu, grid.n_phi),
              a.reshape(grid.n_wl, grid.n_h, grid.n_mu, grid.n_phi, grid.n_mus))
    return out


def coarse_azimuth_grid(grid: TableGrid) -> TableGrid:
    """The same grid with half the azimuth nodes (an even n_phi): the midpoints of n_phi / 2
    cells on [0, pi], each the mean of two neighbouring nodes of ``grid``."""
    return replace(grid, phi_nodes=coarse_azimuths(grid.phi_nodes), phi_weight=2.0 * grid.phi_weight)


def coarse_azimuths(phi_nodes: np.ndarray) -> np.ndarray:
    """The midpoints of half as many cells on [0, pi] as ``phi_nodes`` (rad, an even count of
    midpoints): each the mean of nodes 2k and 2k + 1."""
    if phi_nodes.size % 2:
        raise ValueError(f"half the azimuth nodes needs an even count, not {phi_nodes.size}")
    return 0.5 * (phi_nodes[0::2] + phi_nodes[1::2])


def azimuth_pair_mean(a: np.ndarray, n_mu: int, n_phi: int) -> np.ndarray:
    """(P, n_mu * n_phi, ...) -> (P, n_mu * n_phi / 2, ...): the mean of azimuth nodes 2k and
    2k + 1, the value at the coarse node k (:func:`coarse_azimuth_grid`) of a field linear
    between them."""
    a5 = a.reshape(a.shape[0], n_mu, n_phi, *a.shape[2:])
    return (0.5 * (a5[:, :, 0::2] + a5[:, :, 1::2])).reshape(a.shape[0], n_mu * (n_phi // 2), *a.shape[2:])


def azimuths_to_fine(a: np.ndarray, axis: int) -> np.ndarray:
    """A field on the coarse azimuths (:func:`coarse_azimuth_grid`) read linearly at twice as
    many along ``axis``: each fine node lies a quarter of a coarse cell from its coarse node
    (the field is even about 0 and pi: beyond the ends, the end node's mirror is itself)."""
    r = np.moveaxis(a, axis, 0)
    fine = np.empty((2 * r.shape[0],) + r.shape[1:], dtype=r.dtype)
    fine[0::2] = fine[1::2] = 0.75 * r
    fine[2::2] += 0.25 * r[:-1]  # fine 2k: toward coarse k - 1
    fine[0] += 0.25 * r[0]
    fine[1:-2:2] += 0.25 * r[1:]  # fine 2k + 1: toward coarse k + 1
    fine[-1] += 0.25 * r[-1]
    return np.moveaxis(fine, 0, axis)


# ------------------------------------------------------------------ scattering


def aerosol_phase_function(profile, medium: FactoredMedium, regime: int):
    """The delta-M truncated phase function of aerosol ``regime`` (sr^-1, normalised over
    the sphere with the cut peak removed): a function of the scattering angle's cosine,
    any shape -> shape + (n_wl,), linear in the angle between the profile's tabulated
    angles."""
    ang = profile.aerosol_phase_angles_deg
    tab = medium.truncated_phase[regime]

    def phase(c):
        theta = np.degrees(np.arccos(np.clip(c, -1, 1)))
        i = np.clip(np.searchsorted(ang, theta, side="right") - 1, 0, ang.size - 2)
        tt = ((theta - ang[i]) / (ang[i + 1] - ang[i]))[..., None]
        return tab[i] * (1 - tt) + tab[i + 1] * tt
    return phase


def direction_pair_cosines(grid: TableGrid) -> tuple[np.ndarray, np.ndarray]:
    """Cosines of the scattering angle between every pair of grid directions, (n_dir,
    n_dir) each: with the incoming azimuth +phi and, for the folded half, -phi."""
    mu_d, sin_d, phi_d = grid.dir_mu, grid.dir_sin, grid.dir_phi
    cos_plus = (mu_d[:, None] * mu_d[None, :] + sin_d[:, None] * sin_d[None, :] * np.cos(phi_d[:, None] - phi_d[None, :]))
    cos_minus = (mu_d[:, None] * mu_d[None, :] + sin_d[:, None] * sin_d[None, :] * np.cos(phi_d[:, None] + phi_d[None, :]))
    return cos_plus, cos_minus


def phase_matrix(phase_function, grid: TableGrid, pair_cosines) -> np.ndarray:
    """P, (n_wl, n_dir out, n_dir in) float64: the phase function between every pair of
    grid directions times the quadrature weight of the incoming one (sr), each row
    normalised to sum 1 on the grid (so that scattering conserves energy exactly).
    ``pair_cosines`` from :func:`direction_pair_cosines`."""
    cos_plus, cos_minus = pair_cosines
    wq = (np.repeat(grid.mu_weights, grid.n_phi) * grid.phi_weight)[None, :]  # weight of the incoming direction
    pm = (phase_function(cos_plus) + phase_function(cos_minus)) * wq[..., None]  # (n_dir, n_dir, n_wl)
    pm = pm / pm.sum(axis=1, keepdims=True)  # exact normalisation on the grid
    return np.ascontiguousarray(np.moveaxis(pm, -1, 0))  # (n_wl, n_dir, n_dir)


def azimuth_modes(grid: TableGrid) -> np.ndarray:
    """C, (n_phi, n_phi): C[j, m] = cos(m phi_j) at the azimuth nodes, the cosine modes of a
    field that is even in the azimuth. On the midpoints of [0, pi] they are orthogonal,
    sum_j C[j, m] C[j, m'] = n_phi (m = m' = 0), n_phi / 2 (m = m' > 0), 0 otherwise
    (the DCT-II), so the coefficients of a field f(phi_j) are (C.T @ f) / that norm."""
    return np.cos(np.arange(grid.n_phi)[None, :] * grid.phi_nodes[:, None])


def _mode_projection(grid: TableGrid) -> np.ndarray:
    """(n_phi nodes, n_phi modes): C divided by each mode's norm, so that a field's cosine
    coefficients are ``projection.T @ f`` (:func:`azimuth_modes`)."""
    n_phi = grid.n_phi
    return azimuth_modes(grid) * np.where(np.arange(n_phi) == 0, 1.0 / n_phi, 2.0 / n_phi)[None, :]


def phase_modes(pm: np.ndarray, grid: TableGrid) -> np.ndarray:
    """The phase matrix P (:func:`phase_matrix`) by azimuth mode: (n_phi modes, n_wl, n_mu
    out, n_mu in) float32, P_m with (P f)(mu, phi) = sum_m cos(m phi) (P_m f_m)(mu) for f =
    sum_m f_m(mu) cos(m phi).

    P couples two directions through the phase function of their scattering angle, which
    depends on the azimuths only through phi - phi' (and phi + phi', the folded half); on
    the equally spaced azimuth nodes each (mu, mu') block of P is a circulant in the
    azimuth, diagonal in the cosine modes (the row normalisation depends on mu only, as the
    rows of one mu see the same set of azimuth differences). Scattering by mode is n_phi
    times fewer operations than with P itself (the scattering step of every order);
    measured against P in float32: P rebuilt from its modes differs from it by 6e-8 of
    its largest element, the float32 rounding of P."""
    n_wl, n_mu, n_phi = grid.n_wl, grid.n_mu, grid.n_phi
    # P applied to the mode cos(m phi') gives lambda_m(mu, mu') cos(m phi); project on cos(m phi)
    applied = pm.reshape(-1, n_phi) @ azimuth_modes(grid)
    applied = applied.reshape(n_wl, n_mu, n_phi, n_mu, n_phi)  # (w, mu, phi, mu', m)
    lam = (applied * _mode_projection(grid)[None, None, :, None, :]).sum(axis=2)  # (w, mu, mu', m)
    return np.ascontiguousarray(np.moveaxis(lam, -1, 0), dtype=np.float32)


def phase_modes_of(phase_function, grid: TableGrid) -> np.ndarray:
    """:func:`phase_modes` of :func:`phase_matrix` for ``phase_function``, from one column of
    each circulant: the same (n_phi modes, n_wl, n_mu out, n_mu in) float32, with n_phi times
    fewer phase-function evaluations (the solver's phase step, quadratic in the direction count
    through P, becomes linear in the azimuth count).

    On the midpoints phi_j = (j + 1/2) pi / n_phi the (mu, mu') block of P is
    g(j - k) + g(j + k + 1) times the incoming weight, with g(d) the phase function at the
    scattering angle of an azimuth difference d pi / n_phi (even, of period 2 n_phi); the two
    halves together are one circular convolution over a whole period, so its eigenvalue on
    cos(m phi) is sum over d in [-n_phi, n_phi) of g(d) cos(m d pi / n_phi), and the row
    normalisation of P (constant along a row's azimuths) is mode 0's sum over mu'. Measured
    against the dense route at 5, 7 and 24 azimuths: within the float32 rounding
    (tests/test_scattering_modes.py)."""
    n_phi = grid.n_phi
    d = np.arange(n_phi + 1)  # azimuth differences 0 .. n_phi, in steps of pi / n_phi
    mu = grid.mu_nodes
    sin = np.sqrt(np.clip(1.0 - mu**2, 0.0, None))
    cos_d = (mu[:, None, None] * mu[None, :, None]
             + sin[:, None, None] * sin[None, :, None] * np.cos(d * np.pi / n_phi)[None, None, :])
    g = phase_function(cos_d)  # (mu, mu', d, n_wl)
    # a whole period: d = 0 and n_phi once, 1 .. n_phi - 1 twice (d and -d)
    m = np.arange(n_phi)
    basis = np.cos(np.outer(d, m) * np.pi / n_phi) * np.where((d == 0) | (d == n_phi), 1.0, 2.0)[:, None]  # (d, m)
    lam = np.einsum("abdw,dm->mwab", g, basis) * (grid.mu_weights * grid.phi_weight)[None, None, None, :]
    lam /= lam[0].sum(axis=-1, keepdims=True)[None]  # P's rows sum to 1 on the grid
    return np.ascontiguousarray(lam, dtype=np.float32)


def scattering_species(profile, medium: FactoredMedium, grid: TableGrid) -> list:
    """[(P_m, sigma_s)] for the air and every aerosol regime present: the phase matrix by
    azimuth mode (:func:`phase_modes_of`) and the scattering coefficient at the altitude
    nodes, (n_h, n_wl) float32 in m^-1 (delta-M scaled for the aerosols)."""
    species = [(phase_modes_of(profile.rayleigh_phase, grid), medium.rayleigh.at(grid.h_nodes).astype(np.float32))]
    for reg in range(len(medium.aerosol_scaled)):
        sig = medium.aerosol_scaled[reg].at(grid.h_nodes)
        if np.any(sig > 0):
            species.append((phase_modes_of(aerosol_phase_function(profile, medium, reg), grid), sig.astype(np.float32)))
    return species


def combined_phase_modes(species: list, grid: TableGrid) -> np.ndarray:
    """Q, (n_wl, n_phi modes, n_h, n_mu out, n_mu in) float32: sum over the species of
    sigma_s(h) P_m (:func:`scattering_species`), what one order's scattering applies to
    each mode at each altitude (computed once per solve; 0.2 GB at ``final``, 41 wavelengths)."""
    sig = np.stack([s for _, s in species]).astype(np.float32).transpose(2, 1, 0)  # (w, h, species)
    modes = np.stack([p for p, _ in species]).astype(np.float32)  # (species, m, w, mu, mu')
    n_s, n_m, n_wl, n_a, n_b = modes.shape
    q = np.empty((n_wl, n_m, sig.shape[1], n_a, n_b), dtype=np.float32)
    for w in range(n_wl):  # one (h, species) @ (species, m mu mu') product per wavelength
        # (one broadcast product per species over the whole array was 0.6 s at 24 azimuths, 41 wavelengths)
        prod = sig[w] @ np.ascontiguousarray(modes[:, :, w]).reshape(n_s, -1)
        q[w] = prod.reshape(-1, n_m, n_a, n_b).transpose(1, 0, 2, 3)
    return q


def scattered_source(radiance: np.ndarray, species, grid: TableGrid, out: np.ndarray | None = None) -> np.ndarray:
    """The source of the next order, J_{n+1} = sum over species of sigma_s(h) P L_n:
    ``radiance`` L_n (dir layout, W m^-2 sr^-1 nm^-1) -> J_{n+1} (dir layout, the same per
    metre), float32. ``species``: the list of :func:`scattering_species` or its
    :func:`combined_phase_modes`. By azimuth mode (:func:`phase_modes`): L_n's cosine
    coefficients, each mode at each altitude scattered by Q = sum_s sigma_s(h) P_m (one
    32 x 32 matrix product per wavelength, mode and altitude at ``final``), then back to
    the azimuth nodes; every step a matrix product on the dir layout's own memory (no
    transposed copies; measured, CPU time of one step at ``final``, load 7: dense P 0.6-1.2 s,
    by mode and species 0.26-0.35 s, with Q 0.08-0.15 s; J within 2.2e-6 of the dense
    product).

    The azimuth transforms are n_phi x n_phi by n_phi x n_mus products, one per wavelength,
    zenith node and altitude, on strided views: small enough that numpy's OpenBLAS keeps
    them on one thread. One n_phi x (n_h n_mus) product per wavelength and zenith node, as
    before, was threaded here from between 16 and 20 azimuths on, and those threads stalled
    whenever the other core was busy: 0.11-0.13 s per transform at 24 azimuths idle or beside
    a busy loop, 1.2-2.8 s under load ~4, against 0.03 s now (notebooks/azimuth_count).

    One wavelength at a time (the same products as on the whole field at once): the modes
    in between need one wavelength's array, not a field's. ``out``: a float32 array of the
    field's size (any shape, :class:`WorkArrays`) for J_{n+1}; a new one when None."""
    n_wl, n_mu, n_phi, n_h, n_mus = grid.n_wl, grid.n_mu, grid.n_phi, grid.n_h, grid.n_mus
    assert radiance.shape == (n_wl, grid.n_dir, n_h, n_mus), radiance.shape
    q = species if isinstance(species, np.ndarray) else combined_phase_modes(species, grid)
    forward = np.ascontiguousarray(_mode_projection(grid).T, dtype=np.float32)  # (m, phi)
    back = azimuth_modes(grid).astype(np.float32)  # (phi, m)
    dtype = np.result_type(forward, radiance)
    l_m = np.empty(radiance.shape, dtype=dtype) if out is None else _as_field(out, radiance.shape, dtype)
    j_m = np.empty((n_mu, n_phi, n_h, n_mus), dtype=dtype)

    def by_altitude(a):  # (n_mu, phi or m, n_h, n_mus) viewed as (n_mu, n_h, phi or m, n_mus)
        return a.reshape(n_mu, n_phi, n_h, n_mus).transpose(0, 2, 1, 3)

    def by_mode(a):  # (n_mu, m, n_h, n_mus) viewed as (m, n_h, n_mu, n_mus)
        return a.reshape(n_mu, n_phi, n_h, n_mus).transpose(1, 2, 0, 3)

    for w in range(n_wl):
        # coefficients, laid out (n_mu, m, n_h, n_mus) as the field's (n_mu, phi, ...)
        np.matmul(forward, by_altitude(radiance[w]), out=by_altitude(l_m[w]))
        # per (mode, altitude): Q (mu, mu') @ L_m (mu', mu_s), on strided views
        np.matmul(q[w], by_mode(l_m[w]), out=by_mode(j_m))
        # back to the azimuth nodes, into l_m's memory: (n_mu, phi, n_h, n_mus), the dir layout
        np.matmul(back, by_altitude(j_m), out=by_altitude(l_m[w]))
    return l_m.reshape(n_wl, grid.n_dir, n_h, n_mus)


def gathered_radiance(source: np.ndarray, ground_radiance: np.ndarray, M: np.ndarray, G: np.ndarray,
                      grid: TableGrid, out: np.ndarray | None = None) -> np.ndarray:
    """Radiance arriving at every grid node in the independent columns, L = M J + G L_g:
    ``source`` J (dir layout, W m^-2 sr^-1 nm^-1 m^-1), ``ground_radiance`` L_g (n_mus,
    n_wl) the radiance leaving the Lambertian ground -> L (dir layout, W m^-2 sr^-1 nm^-1).
    One wavelength at a time, through arrays of one wavelength laid out by grid ray (the
    products of M by the whole field in the ray layout took two more field-sized copies);
    the wavelengths on :data:`~skymodel.render.threads.SOLVER_THREADS` threads, each product
    on one BLAS thread. (Left to BLAS's own two threads, one product at a time, the
    products waited on each other's threads: on a machine busy with other work (two
    ``nice`` loops) this transport took 3.7x its idle time, 8.7 s of a cold ``final`` build;
    on threads of their own the same products are unaffected by such load, and idle they take
    0.53 against 0.59 s (41 wavelengths at ``final``'s size); the numbers are the same bit for
    bit.) ``out``: a float32 array of the field's
    size (any shape, :class:`WorkArrays`) for L; a new one when None."""
    n_wl, n_mu, n_phi, n_h, n_mus = grid.n_wl, grid.n_mu, grid.n_phi, grid.n_h, grid.n_mus
    n_rays = n_h * n_mu
    assert ground_radiance.shape == (n_mus, n_wl), ground_radiance.shape
    dtype = np.result_type(M, source)
    dir_shape = (n_wl, grid.n_dir, n_h, n_mus)
    out = np.empty(dir_shape, dtype=dtype) if out is None else _as_field(out, dir_shape, dtype)
    ray_shape = (n_h, n_mu, n_phi, n_mus)

    def wavelengths(ws):  # one thread's wavelengths, through its own ray-layout arrays
        src_ray = np.empty((n_rays, n_phi * n_mus), dtype=dtype)
        l_ray = np.empty_like(src_ray)
        for w in ws:
            np.copyto(src_ray.reshape(ray_shape), dir_in_ray_order(source[w], n_mu, n_phi))
            np.matmul(M[w], src_ray, out=l_ray)
            l_ray.reshape(n_rays, n_phi, n_mus)[...] += G[w, :, None, None] * ground_radiance[:, w]
            np.copyto(dir_in_ray_order(out[w], n_mu, n_phi), l_ray.reshape(ray_shape))

    chunks_in_threads(wavelengths, range(n_wl), SOLVER_THREADS)
    return out


class WorkArrays:
    """Arrays kept from one order of scattering to the next, by name. Each order's
    field-sized arrays (0.16 GB at ``final``, 41 wavelengths), allocated anew, were fresh
    memory that the kernel zeroes page by page on first use (perf, cold ``final`` 512x256:
    11 % of the build's CPU time went to clearing pages, 9 % with these arrays kept and the
    order loop's other field-sized temporaries gone). ``get`` returns the named array viewed
    with ``shape`` while its size and type stay; otherwise (the coarse orders' smaller fields)
    the old one is let go before a new one is made."""

    def __init__(self):
        self._flat = {}

    def get(self, name: str, shape: tuple, dtype=np.float32) -> np.ndarray:
        size, dtype = int(np.prod(shape)), np.dtype(dtype)
        flat = self._flat.get(name)
        if flat is None or flat.size != size or flat.dtype != dtype:
            self._flat.pop(name, None)
            flat = self._flat[name] = np.empty(size, dtype=dtype)
        return flat.reshape(shape)


def abs_sums(a: np.ndarray) -> np.ndarray:
    """Sum of |a| over all but the first axis (the wavelengths), float64, one wavelength
    at a time (no field-sized temporary)."""
    work = np.empty(a.shape[1:], dtype=a.dtype)
    return np.array([np.abs(a[w], out=work).sum(dtype=np.float64) for w in range(a.shape[0])])


def _as_field(a: np.ndarray, shape: tuple, dtype) -> np.ndarray:
    """``a`` (a contiguous work array of the same size and type) viewed with ``shape``."""
    assert a.dtype == dtype and a.size == int(np.prod(shape)) and a.flags.c_contiguous, (a.dtype, a.shape, shape)
    return a.reshape(shape)


def ground_diffuse_irradiance(radiance: np.ndarray, grid: TableGrid) -> np.ndarray:
    """Downwelling irradiance on the ground (h = 0) from a field: ``radiance`` (dir
    layout, W m^-2 sr^-1 nm^-1) -> (n_mus, n_wl) W m^-2 nm^-1, sum of L mu dOmega over
    the downward-travelling grid directions (mu > 0 looks up; azimuth folded: factor 2)."""
    up = grid.dir_mu > 0
    irr_w = (grid.dir_mu * np.repeat(grid.mu_weights, grid.n_phi) * 2.0 * grid.phi_weight)[up]
    irr_w = irr_w.astype(np.float32)
    return np.einsum("wdm,d->mw", radiance[:, up, 0, :], irr_w)


def first_order_column_source(profile, medium: FactoredMedium, sun_table: SunTransmittance,
                              grid: TableGrid) -> tuple[np.ndarray, np.ndarray]:
    """The source of light scattered once, J_1 (dir layout, float32, W m^-2 sr^-1 nm^-1
    per metre), with the sun transmittance of each node (Earth's shadow included), and
    the radiance the direct sun leaves on the ground, (n_mus, n_wl) float32: what the
    independent-column transport of the first order starts from."""
    n_wl, n_dir, n_h, n_mus = grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus
    mu_d, sin_d, phi_d, mus_nodes = grid.dir_mu, grid.dir_sin, grid.dir_phi, grid.mus_nodes
    e_sun = profile.solar_irradiance  # (n_wl,)
    albedo = profile.ground_albedo.astype(np.float32)  # float32, as the order loop's (the result depends on it)
    hs, ms = np.meshgrid(grid.h_nodes, mus_nodes, indexing="ij")  # (n_h, n_mus)
    t_sun = sun_table.transmittance(hs, ms, which=1)  # (n_h, n_mus, n_wl) delta-M scaled, solver wavelengths
    sin_s = np.sqrt(1.0 - mus_nodes**2)
    cos_sun = mu_d[:, None] * mus_nodes[None, :] + sin_d[:, None] * sin_s[None, :] * np.cos(phi_d)[:, None]
    j1 = np.zeros((n_wl, n_dir, n_h, n_mus))
    ray_p = profile.rayleigh_phase(cos_sun)  # (n_dir, n_mus, n_wl)
    j1 += np.einsum("dmw,hw,hmw->wdhm", ray_p, medium.rayleigh.at(grid.h_nodes), t_sun)
    for reg in range(len(medium.aerosol_scaled)):
        sig = medium.aerosol_scaled[reg].at(grid.h_nodes)
        if np.any(sig > 0):
            j1 += np.einsum("dmw,hw,hmw->wdhm", aerosol_phase_function(profile, medium, reg)(cos_sun), sig, t_sun)
    j1 *= e_sun[:, None, None, None]
    e_direct_ground = e_sun[None, :] * t_sun[0] * np.maximum(mus_nodes, 0.0)[:, None]  # (n_mus, n_wl)
    return j1.astype(np.float32), (albedo[None, :] / np.pi * e_direct_ground).astype(np.float32)


def first_order_radiance(profile, medium: FactoredMedium, sun_table: SunTransmittance, grid: TableGrid,
                         rays: GridRays, M: np.ndarray, G: np.ndarray, spherical: bool) -> np.ndarray:
    """Radiance of light scattered once arriving at every grid node, (dir layout, float32,
    W m^-2 sr^-1 nm^-1): transported with every point's own sun angle (``spherical``,
    :func:`_first_order_spherical`) or in the independent columns (M J_1 + G L_g1)."""
    if not spherical:
        return gathered_radiance(*first_order_column_source(profile, medium, sun_table, grid), M, G, grid)
    n_reg = len(medium.aerosol_scaled)
    return to_dir_layout(_first_order_spherical(
        sun_table, profile, species_sigma_at=[medium.rayleigh] + [medium.aerosol_scaled[r] for r in range(n_reg)],
        species_phase=[profile.rayleigh_phase] + [aerosol_phase_function(profile, medium, r) for r in range(n_reg)],
        r0=rays.r0, mu0=rays.mu0, t=rays.t, dt=rays.dt, h=rays.h, trans=rays.trans, hits=rays.hits,
        ground_t=rays.ground_t, mus_nodes=grid.mus_nodes, phi_nodes=grid.phi_nodes, n_mu=grid.n_mu,
        R=profile.planet_radius_m).astype(np.float32), grid)


# ------------------------------------------------------------------ the series of orders


@dataclass
class OrderSeries:
    """The sum of orders 2..n: source J_ms (dir layout, float32, W m^-2 sr^-1 nm^-1 m^-1)
    and the diffuse irradiance on the ground (orders 1..n, (n_mus, n_wl) float32,
    W m^-2 nm^-1), with the last order's source and ground irradiance and each order's
    size per wavelength (for the geometric tail)."""

    source: np.ndarray
    ground_irradiance: np.ndarray
    orders: int  # the highest order summed (1: none beyond single scattering)
    contributions: list  # per order: sum |J_n| / sum |J_2 + .. + J_n| (the convergence test)
    sizes: list  # per order: sum of |J_n| per wavelength, (n_wl,) float64
    last_source: np.ndarray | None = None
    last_ground_irradiance: np.ndarray | None = None


#: The largest spherical correction an order after ``spherical_orders`` takes from the last one
#: (``spherical_tail``). Order 3's factor lies within 0.4-3.6 at 98 % of the corrected nodes (rural
#: AOD 0.2, sun -4 degrees, ``final``) and the later orders' within 0.1 % of it at half of them, but
#: it reaches 1e3 where order 3's column light is ~0; a node there would multiply the next orders'
#: light by as much. Uncapped, the tail on ``reference``'s 48 x 24 nodes put desert 5 degrees'
#: horizon up to 0.5 % above every order spherical; capped, within 0.01 % (notebooks/spherical_tail).
SPHERICAL_TAIL_RATIO_MAX = 10.0


@dataclass
class CoarseOrders:
    """The orders from ``from_order`` on, solved on half the azimuth nodes: the coarse
    grid (:func:`coarse_azimuth_grid`); ``operators()`` makes its phase modes
    (:func:`combined_phase_modes`) and peak term (a
    :class:`~skymodel.render.peak_diffuse.PeakDiffuse` on it, or None) when the series
    reaches ``from_order`` (made earlier, they would be held beside the fine grid's through
    the fine orders, at the solve's peak of memory)."""

    from_order: int
    grid: TableGrid
    operators: Callable[[], tuple[np.ndarray, PeakDiffuse | None]]


def _corrected(radiance, factor, n_sub: int) -> None:
    """``radiance[..., :n_sub] *= factor``, then 0 where that is negative. The factor (>= 0) is
    the spherical transport over the column one; at a node the column geometry puts in the
    dark, the column light is ~0 and may be slightly negative (the sources' rounding-level
    negatives), while a factor read back from the pair-averaged azimuths
    (``spherical_coarse_phi``) can be 1e4: their product was a negative radiance of 38 % of the
    field's largest (desert AOD 0.5, `final`, a sun node at -6.2 degrees, 2.8 km up, looking
    0.7 degrees above the horizon), which the cut peak's small-angle term spread into the
    next order's source at 1 % of its largest. A radiance is never negative."""
    part = radiance[..., :n_sub]
    part *= factor
    np.maximum(part, 0.0, out=part)


def sum_scattering_orders(radiance: np.ndarray, species: list, M: np.ndarray, G: np.ndarray, grid: TableGrid,
                          ground_albedo: np.ndarray, *, orders: int | None, max_orders: int, tolerance: float,
                          spherical: _SphericalTransport | None = None, spherical_orders: int = 0,
                          spherical_tail: bool = False, progress=None, peak=None,
                          coarse: CoarseOrders | None = None) -> OrderSeries:
    """Orders 2, 3, ... from the first-order ``radiance`` (dir layout): each order
    scatters the last order's radiance into a source (:func:`scattered_source`), then
    transports it with the ground's reflection (:func:`gathered_radiance`; through
    ``spherical``'s correction for orders up to ``spherical_orders``; with ``spherical_tail``
    every later order takes the last correction computed, when that order is 3 or more: order
    2's is not the diffuse orders' and can be ~1e15 where its column light is ~0). Up to ``orders``
    when given, else until an order adds less than ``tolerance`` of the sum of the source
    (relative, summed over the grid and the wavelengths) or ``max_orders`` is reached.
    ``ground_albedo`` (n_wl,) float32; ``progress(n, size)`` after each order; ``peak`` (a
    :class:`~skymodel.render.peak_diffuse.PeakDiffuse` or None) adds the cut forward peaks'
    scattering of each order's radiance near the horizon. ``coarse``: the orders from
    ``coarse.from_order`` on (after ``spherical_orders``) on half the azimuths, from the pair
    means of the last fine order's radiance, their sum read back linearly on ``grid``
    (:func:`azimuths_to_fine`; the diffuse orders are smooth in the azimuth). The sizes of the
    coarse orders are scaled by the ratio of the node counts, as if summed on ``grid``."""
    assert tolerance >= 0.0 and max_orders >= 1, (tolerance, max_orders)
    assert coarse is None or coarse.from_order > max(2, spherical_orders), "coarse orders come after the corrected ones"
    albedo = ground_albedo
    fine_grid = grid
    species = combined_phase_modes(species, grid) if not isinstance(species, np.ndarray) else species
    series = OrderSeries(np.zeros((grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus), dtype=np.float32),
                         ground_diffuse_irradiance(radiance, grid), 1, [], [])
    j_ms, e_diffuse = series.source, series.ground_irradiance
    limit = max_orders if orders is None else orders
    j_n = e_n = last_ratio = None
    scale, fine_abs = 1.0, 0.0  # the coarse sums' weight, the fine orders' share of sum |J|
    n_sub = 0 if spherical is None else spherical.n_sub
    work = WorkArrays()  # J_n and L_n, kept from order to order
    for n in range(2, limit + 1):
        if coarse is not None and n == coarse.from_order:  # on to half the azimuths
            species = peak = None  # the fine grid's, freed before the coarse ones are made
            grid, (species, peak) = coarse.grid, coarse.operators()
            radiance = azimuth_pair_mean(radiance, grid.n_mu, fine_grid.n_phi)
            if last_ratio is not None:
                last_ratio = azimuth_pair_mean(last_ratio, grid.n_mu, fine_grid.n_phi)
            scale, fine_abs = fine_grid.n_phi / grid.n_phi, float(abs_sums(j_ms).sum())
            j_ms = np.zeros((grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus), dtype=np.float32)
        field = (grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus)
        j_n = scattered_source(radiance, species, grid, out=work.get("source", field))
        if peak:
            peak.add_source(radiance, j_n)
        j_ms += j_n
        series.orders = n
        sizes_n = abs_sums(j_n)  # per wavelength
        size = scale * float(sizes_n.sum()) / max(fine_abs + scale * float(abs_sums(j_ms).sum()), 1e-300)
        series.contributions.append(size)
        if progress is not None:
            progress(n, size)
        lg = albedo[None, :] / np.pi * ground_diffuse_irradiance(radiance, grid)  # radiance leaving the ground
        # (the last order's L_n is not read after this: L_{n+1} takes its array)
        radiance = gathered_radiance(j_n, lg, M, G, grid, out=work.get("radiance", field))
        if spherical is not None and n <= spherical_orders:
            ratio = spherical.correction(j_n, lg, radiance)  # at the first n_sub sun nodes
            _corrected(radiance, ratio, n_sub)
            last_ratio = np.minimum(ratio, SPHERICAL_TAIL_RATIO_MAX) if (spherical_tail and n >= 3) else None
        elif last_ratio is not None:
            _corrected(radiance, last_ratio, n_sub)
        e_n = ground_diffuse_irradiance(radiance, grid)
        e_diffuse = e_diffuse + e_n
        series.sizes.append(scale * sizes_n)
        if orders is None and size < tolerance:
            break
    if grid is not fine_grid:  # the coarse orders' sum and the last order back on the solver's azimuths
        def to_fine(a):
            a = a.reshape(grid.n_wl, grid.n_mu, grid.n_phi, grid.n_h, grid.n_mus)
            return azimuths_to_fine(a, axis=2).reshape(grid.n_wl, fine_grid.n_dir, grid.n_h, grid.n_mus)
        j_ms = series.source + to_fine(j_ms)
        j_n = to_fine(j_n)
    series.source, series.ground_irradiance = j_ms, e_diffuse
    series.last_source, series.last_ground_irradiance = j_n, e_n
    return series


def add_geometric_tail(series: OrderSeries) -> OrderSeries:
    """The orders still missing, as a geometric series (in place; needs three orders).

    High orders of scattering take the shape of the scattering operator's leading
    eigenfunction and shrink by its eigenvalue q per order (q -> 1 in thick, bright
    media), so the rest of the series is J_n q / (1 - q), likewise for the ground
    irradiance. q is each wavelength's ratio of the last two orders, used when the ratios
    of the last three agree (the series has settled). Measured: desert AOD 10, sun 30
    deg: stopping at max_orders = 20 left the radiance up to 8 % low (650 nm); with the
    tail it is within 0.1 % of the series run to 1e-6 (58 orders)."""
    sizes = series.sizes
    if len(sizes) < 3:
        return series
    q = sizes[-1] / np.maximum(sizes[-2], 1e-300)
    q_prev = sizes[-2] / np.maximum(sizes[-3], 1e-300)
    settled = (q > 0.0) & (q < 0.99) & (np.abs(q - q_prev) <= 0.1 * q)
    tail = np.where(settled, q / (1.0 - np.where(settled, q, 0.0)), 0.0).astype(np.float32)
    series.source = series.source + series.last_source * tail[:, None, None, None]
    series.ground_irradiance = series.ground_irradiance + series.last_ground_irradiance * tail[None, :]
    return series


def solve_multiple_scattering(profile, medium: FactoredMedium, sun_table: SunTransmittance, *,
                              n_altitudes: int = 24, n_mu: int = 32, n_phi: int = 12, n_mus: int = 24,
                              n_steps: int = 48, orders: int | None = None, max_orders: int = 20,
                              tolerance: float = 1e-3, spherical_orders: int = 2, spherical_tail: bool = False,
                              spherical_probe_step_nm: float = 100.0, peak_diffuse: bool = False,
                              source_by_scattering: bool = False, mu_horizon_deg: float = 0.0,
                              mu_horizon_nodes: int = 0, spherical_coarse_phi: bool = False,
                              coarse_phi_from_order: int = 0, progress=None) -> MultipleScatteringField:
    """Solve orders 2..N of scattering for ``profile`` (already at the solver's
    wavelengths). ``sun_table`` must hold the delta-M scaled extinction as medium 1.
    ``orders`` fixes the highest order (1 = single scattering only, no field); otherwise
    orders are added until the last one adds less than ``tolerance`` of the total.
    ``spherical_orders`` is how many transports (of the light scattered once, twice,
    ...) follow the sun angle of every point along the grid rays instead of keeping
    the independent columns: 0 none, 1 the first (exact, :func:`_first_order_spherical`),
    n > 1 also orders 2..n, corrected at probe wavelengths about
    ``spherical_probe_step_nm`` apart (:class:`_SphericalTransport`); ``spherical_tail``: the
    orders after ``spherical_orders`` take the last order's correction. ``peak_diffuse``: add
    the cut forward peaks' small-angle scattering of every order's radiance near the horizon
    (:mod:`skymodel.render.peak_diffuse`). ``source_by_scattering``: read the source between
    the altitude nodes as sigma_s(h) times J / sigma_s (:func:`scattering_reference`), in the
    transport and in the field's :meth:`~MultipleScatteringField.source_at`, instead of J
    linearly, which overestimates J between nodes (rural AOD 0.2, ``final``'s 32 nodes: the
    column of sigma_s +0.6 %). ``mu_horizon_deg``, ``mu_horizon_nodes``: the zenith nodes'
    composite rule (:func:`zenith_nodes`; 0 nodes = double Gauss-Legendre).
    ``spherical_coarse_phi``: the spherical correction of orders 2.. on every other azimuth
    (:class:`_SphericalTransport`'s ``coarse_phi``; an even ``n_phi``). ``coarse_phi_from_order``
    (0: none, else 3 or more): the orders from this one on, and after ``spherical_orders``, on
    half the azimuths (:class:`CoarseOrders`; an even ``n_phi``).

    The steps: :func:`build_table_grid`, :func:`trace_grid_rays`, the column transport
    (:func:`transport_row_scale`, :func:`column_transport_matrix`), the phase matrices
    (:func:`scattering_species`), :func:`first_order_radiance`,
    :func:`sum_scattering_orders` and :func:`add_geometric_tail`."""
    grid = build_table_grid(profile, medium, n_altitudes=n_altitudes, n_mu=n_mu, n_phi=n_phi, n_mus=n_mus,
                            horizon_deg=mu_horizon_deg, horizon_nodes=mu_horizon_nodes)
    if orders is not None and orders <= 1:
        return grid.empty_field()
    rays = trace_grid_rays(grid, medium, profile.planet_radius_m, profile.top_altitude_m, n_steps)
    scattering = scattering_reference(medium) if source_by_scattering else None
    sigma = {} if scattering is None else {"sigma_nodes": scattering.at(grid.h_nodes),
                                           "sigma_samples": scattering.at(rays.h)}  # once for all three
    row_scale = transport_row_scale(grid, rays, medium, **sigma)
    M = column_transport_matrix(grid, rays, row_scale, **sigma)
    G = ground_transmittance_vector(rays)
    species = scattering_species(profile, medium, grid)
    spherical = None
    if spherical_orders > 1:
        spherical = _SphericalTransport(
            ih=rays.ih, fh=rays.fh, im=rays.im, fm=rays.fm, weight=(rays.dt[..., None] * rays.trans) * row_scale[:, None, :],
            r0=rays.r0, mu0=rays.mu0, t=rays.t, dt=rays.dt, h=rays.h, R=profile.planet_radius_m, hits=rays.hits,
            ground_t=rays.ground_t, h_nodes=grid.h_nodes, mu_nodes=grid.mu_nodes, phi_nodes=grid.phi_nodes,
            mus_nodes=grid.mus_nodes, wavelengths_nm=grid.wavelengths_nm, probe_step_nm=spherical_probe_step_nm,
            ozone_depth=ozone_column(profile), coarse_phi=spherical_coarse_phi, **sigma)
    peak = PeakDiffuse(profile, medium, grid) if peak_diffuse else None
    coarse = None
    if coarse_phi_from_order:
        coarse_grid = coarse_azimuth_grid(grid)
        coarse = CoarseOrders(max(coarse_phi_from_order, 3, spherical_orders + 1), coarse_grid, lambda: (
            combined_phase_modes(scattering_species(profile, medium, coarse_grid), coarse_grid),
            None if peak is None else peak.on_grid(coarse_grid)))
    # the first order's radiance goes straight into the series, which lets it go after order 2
    # (held here, it would keep one more field-sized array alive through every order)
    series = sum_scattering_orders(first_order_radiance(profile, medium, sun_table, grid, rays, M, G,
                                                        spherical=spherical_orders >= 1),
                                   species, M, G, grid, profile.ground_albedo.astype(np.float32),
                                   orders=orders, max_orders=max_orders, tolerance=tolerance, spherical=spherical,
                                   spherical_orders=spherical_orders, spherical_tail=spherical_tail,
                                   progress=progress, peak=peak, coarse=coarse)
    if orders is None:
        add_geometric_tail(series)
    # float32, as solved (the interpolation table is float32 too; a float64 copy was 0.13 GB at final)
    source = series.source.reshape(grid.n_wl, grid.n_mu, grid.n_phi, grid.n_h, grid.n_mus)
    return MultipleScatteringField(grid.wavelengths_nm, grid.h_nodes, grid.mu_nodes, grid.phi_nodes, grid.mus_nodes,
                                   source, series.ground_irradiance.astype(np.float64), series.orders,
                                   series.contributions, scattering=scattering)


def _ray_sun_cosine(mu0, phi_nodes, mus):
    """Cosine of the angle between a grid ray (zenith cosine ``mu0``, (rays,)) and the sun
    for every (azimuth ``phi_nodes``, sun cosine ``mus``) pair: (rays, n_phi * n_mus),
    azimuth-major as in the solver's ray layout."""
    sin_s = np.sqrt(np.clip(1.0 - mus**2, 0.0, None))
    sin0 = np.sqrt(np.clip(1.0 - mu0**2, 0.0, None))
    return (mu0[:, None, None] * mus[None, None, :]
            + sin0[:, None, None] * np.cos(phi_nodes)[None, :, None] * sin_s[None, None, :]).reshape(mu0.size, -1)


def _sun_cosine_along(r0, mus_p, t, cs, r):
    """The sun's zenith cosine at distance ``t`` (m) along straight grid rays,
    mu_s(t) = (r0 mu_s0 + t d.s) / r(t): ``r0`` (rays,) the start radius (m), ``mus_p``
    (n_p,) mu_s0 at the start for every (azimuth, sun node) pair, ``cs`` (rays, n_p) d.s the
    cosine between ray and sun, ``r`` the radius reached (m). Samples along each ray: ``t``
    and ``r`` (rays, steps) -> (rays, steps, n_p); one point per ray: ``t`` (rays,) and a
    scalar ``r`` -> (rays, n_p)."""
    if t.ndim == 2:
        return (r0[:, None, None] * mus_p + t[:, :, None] * cs[:, None, :]) / r[:, :, None]
    return (r0[:, None] * mus_p + t[:, None] * cs) / r


def _first_order_spherical(sun_table, profile, *, species_sigma_at, species_phase, r0, mu0, t, dt, h, trans,
                           hits, ground_t, mus_nodes, phi_nodes, n_mu, R, max_elements: int = 8_000_000):
    """Radiance of light scattered once, arriving at every grid node, with the true
    spherical geometry of the sun: (n_wl, n_h * n_mu rays, n_phi * n_mus).

    The independent-column transport would give every point of a grid ray the sun
    cosine of the ray's start. In the sphere the sun is higher by about one degree for
    every 111 km travelled toward it, which matters most in twilight: from a point in
    the Earth's shadow, air a few hundred kilometres toward the sun is sunlit. The first
    order is known in closed form at any point, so here it is evaluated at every
    sample of every grid ray with that sample's own sun cosine,

        mu_s(t) = (r0 mu_s0 + t d.s) / r(t),   d.s = mu0 mu_s0 + sin0 sin_s0 cos phi0,

    and with the sun transmittance (Earth's shadow included) of the point; the
    scattering angle is constant along the ray (parallel sun). Rays that meet the
    ground add the direct sunlight reflected there, at the ground point's sun cosine.
    Measured in notebooks/twilight_accuracy and docs/validation.md.

    Arguments are the grid rays of :func:`solve_multiple_scattering`: start radius
    ``r0`` (m) and zenith cosine ``mu0`` (rays,), samples ``t``, ``dt`` (m) and
    altitudes ``h`` (rays, steps), scaled transmittance ``trans`` (rays, steps, n_wl),
    ``hits`` / ``ground_t`` for rays that end on the ground. The sun's optical depth
    is read from ``sun_table`` (medium 1) the way :meth:`SunTransmittance.optical_depth`
    reads it, reorganised for speed: its low-rank table is first interpolated to each
    sample's altitude, then along the distance parameter for every sun node, in float32.
    The (azimuth, sun node) pairs in the Earth's shadow at every sample of a chunk's rays
    are left out of it (their light is exactly 0): a quarter of them at ``final`` (rural,
    the sun nodes down to -20 degrees), a third of the (sample, sun node) pairs being dark.
    """
    f32 = np.float32
    n_rays, n_steps = t.shape
    n_phi, n_mus = phi_nodes.size, mus_nodes.size
    n_p = n_phi * n_mus
    n_wl = trans.shape[-1]
    st = sun_table
    cs = _ray_sun_cosine(mu0, phi_nodes, mus_nodes)  # cosine of the scattering angle, (rays, n_phi * n_mus)
    # phase of every species at the scattering angle, which depends on (mu0, phi, mu_s)
    # only: the rays of one altitude share it (ray index = altitude * n_mu + mu index)
    phases = np.stack([np.moveaxis(np.asarray(pf(cs[:n_mu]), dtype=f32), -1, 1)
                       for pf in species_phase])  # (K species, n_mu, n_wl, n_p)
    # dt T sigma_k along every grid ray, (rays, n_wl, K, steps)
    weights = np.stack([(m.at(h) * (dt[..., None] * trans)).astype(f32) for m in species_sigma_at], axis=-1)
    weights = np.ascontiguousarray(weights.transpose(0, 2, 3, 1))
    tab = st.tables[1].astype(f32)  # (n_h_sun, n_x, k) optical depth of the basis functions
    wk = st.weights[1].astype(f32)  # (k, n_wl)
    minus_wk_t = -wk.T  # (the same memory layout as wk.T: the same matrix product)
    n_x = st.x_nodes.size
    x_scale = (n_x - 1) / st.x_nodes[-1]
    # per sample: altitude interpolation of the table, and the geometry of the sun table
    hc = np.clip(h, st.h_nodes[0], st.h_nodes[-1])
    ih, fh = st.altitude_weights(hc)
    fh = fh.astype(f32)
    rs = R + hc
    mu_hor = horizon_mu(R, rs)  # cosine of the local horizon
    alpha = SUN_ANGULAR_RADIUS_RAD
    e_hor = np.arcsin(np.clip(mu_hor, -1.0, 1.0))
    mu_lo, mu_hi = np.sin(e_hor - alpha), np.sin(e_hor + alpha)  # edges of the setting disc
    r_t = R + h
    mus_p = np.tile(mus_nodes, n_phi)  # sun cosine of each (phi, sun) node
    out = np.zeros((n_wl, n_rays, n_p), dtype=f32)
    # chunks of rays on SOLVER_THREADS threads (each chunk writes its own rays of ``out``);
    # each thread keeps one work array for the chunk's optical depth, reused chunk after
    # chunk: allocated anew each time, its pages were zeroed by the kernel again and again
    chunk = max(1, max_elements // max(1, SOLVER_THREADS) // max(1, n_steps * n_p * n_wl))

    def ground_light(rays):
        """Direct sunlight reflected where the ``rays`` (indices, all meeting the ground) end:
        (n_wl, rays, n_p) float32, at the ground point's own sun cosine."""
        t_end = t[rays, -1] + 0.5 * dt[rays, -1]
        mus_g = np.clip(_sun_cosine_along(r0[rays], mus_p, t_end, cs[rays], R), -1.0, 1.0)
        t_sun_g = st.transmittance(np.zeros_like(mus_g), mus_g, which=1)  # (G, n_p, n_wl)
        return np.moveaxis((profile.ground_albedo / np.pi) * t_sun_g * np.maximum(mus_g, 0.0)[..., None]
                           * ground_t[rays][:, None, :], -1, 0).astype(f32)

    def rays_of_thread(own_starts):
        work = np.empty(chunk * n_wl * n_steps * n_p, dtype=f32)
        for a in own_starts:
            b = min(n_rays, a + chunk)
            c = b - a
            hit = a + np.flatnonzero(hits[a:b])
            if hit.size:
                out[:, hit] += ground_light(hit)
            mus_t = _sun_cosine_along(r0[a:b], mus_p, t[a:b], cs[a:b], r_t[a:b])  # (c, steps, n_p)
            lit = slice(None)  # the (azimuth, sun node) columns computed: all, or those lit somewhere
            if st.earth_shadow:
                lo, hi = mu_lo[a:b, :, None], mu_hi[a:b, :, None]
                cols = np.flatnonzero(np.any(mus_t > lo, axis=(0, 1)))
                if cols.size == 0:
                    continue
                if cols.size < n_p:  # every sample of the chunk's rays in the Earth's shadow: exact zeros
                    lit, mus_t = cols, np.ascontiguousarray(mus_t[..., cols])  # (indexing leaves the columns outermost)
            m = mus_t.shape[-1]
            # the table interpolated to each sample's altitude: (c * steps * n_x, k)
            tab_h = (tab[ih[a:b]] * (1 - fh[a:b, :, None, None]) + tab[ih[a:b] + 1] * fh[a:b, :, None, None])
            tab_h = tab_h.reshape(-1, tab.shape[-1])
            # as SunTransmittance.optical_depth: under the horizon, the grazing ray
            xs = st._x_from_mu(rs[a:b, :, None], np.maximum(mus_t, mu_hor[a:b, :, None])) * x_scale
            j = np.clip(xs.astype(np.int64), 0, n_x - 2)
            fx = np.clip(xs - j, 0.0, 1.0).astype(f32)[..., None]
            row = (np.arange(c * n_steps).reshape(c, n_steps, 1) * n_x + j).ravel()
            tau_k = np.take(tab_h, row, axis=0).reshape(c, n_steps, m, -1) * (1 - fx)
            tau_k += np.take(tab_h, row + 1, axis=0).reshape(c, n_steps, m, -1) * fx
            # optical depth per wavelength, laid out (c, n_wl, steps, m) for the matrix product below
            # (minus the optical depth: the product with -W, exactly the negated sums)
            tau = np.matmul(minus_wk_t, np.ascontiguousarray(tau_k.transpose(0, 3, 1, 2)).reshape(c, -1, n_steps * m),
                            out=work[:c * n_wl * n_steps * m].reshape(c, n_wl, n_steps * m))
            trans_sun = np.exp(tau, out=tau).reshape(c, n_wl, n_steps, m)
            # visible fraction of the disc (0 in the Earth's shadow)
            if st.earth_shadow:
                vis = (mus_t >= hi).astype(f32)
                part = (mus_t > lo) & (mus_t < hi)
                if np.any(part):
                    vis[part] = st.visible_fraction(np.broadcast_to(hc[a:b, :, None], mus_t.shape)[part], mus_t[part])
                trans_sun *= vis[:, None]
            # sum over the steps for every species at once: (c, n_wl, K, steps) @ (c, n_wl, steps, m)
            gathered = np.matmul(weights[a:b], trans_sun)  # (c, n_wl, K, m)
            out[:, a:b, lit] += np.einsum("cwkp,kcwp->wcp", gathered, phases[:, np.arange(a, b) % n_mu][..., lit])

    chunks_in_threads(rays_of_thread, range(0, n_rays, chunk), SOLVER_THREADS)
    out *= profile.solar_irradiance.astype(f32)[:, None, None]
    return out  # (n_wl, rays, n_phi * n_mus)


class _SphericalTransport:
    """Transport of a higher-order source J_n along the grid rays with the sun angle
    of every point, as a correction to the independent-column transport.

    The column transport (the matrix M) reads J_n at each sample of a grid ray from the
    altitude and zenith-angle nodes around it, but at the sun cosine of the ray's
    start. Here the same samples and weights read J_n at the sample's own sun cosine
    mu_s(t) = (r0 mu_s0 + t d.s) / r(t) (interpolated between sun nodes as in
    :meth:`MultipleScatteringField.source_at`: a cubic in log J), and ground light at
    the ground point's sun cosine.

    Two economies keep its cost near that of one more order of the column solver:

    * the ratio of the two transports is smooth in wavelength (it depends on where the
      light comes from, not on its colour), so it is evaluated at a few probe
      wavelengths: L_n = (M J_n + G L_g) * ratio(lambda), the ratio carried to every
      solver wavelength by the log-ozone model of :class:`SolverSpectrumMap` (``ozone_depth``:
      the profile's vertical ozone optical depth at the solver wavelengths). Read linearly
      from probes 100 nm apart it moved ``final``'s sky at sun -4 degrees by up to 0.58 %
      (rural AOD 0.2, 425 nm, view 88/0; CIE Z 0.32 %) against probes at every solver
      wavelength; read through the map, 0.37 % (Z 0.18 %; notebooks/solver_spectrum/probes.py);
    * it is evaluated only for the sun nodes up to ``max_elevation_deg``; above, the
      ratio is 1. Measured (rural AOD 0.2, converged settings): correcting order 2
      changes the sky by at most 0.03 % with the sun at 20 degrees, 0.3 % at 5 and
      1.2 % at 0 (the horizons).

    ``coarse_phi`` (an even count of azimuth nodes): the ratio is formed on half as many
    azimuths and read back linearly. The midpoints of n_phi / 2 cells on [0, pi] are each
    the mean of two neighbouring nodes of the n_phi, and the column transport acts on
    every (azimuth, sun node) column alike, so the column light of the pair-averaged
    source is the pair average of the column light; the spherical transport is run on
    that source at the coarse azimuths only (about half its cost). The ratio is smooth in
    the azimuth; the forward lobe, which is not, stays in the first order's transport at
    every azimuth. Measured at 24 azimuths (``final``'s other tables; notebooks/azimuth_count):
    within 0.15 % of the correction at every azimuth on the views of the ten scenes of the
    truth table (desert -4 degrees; the other nine within 0.04 %).

    Sizes: ``weight`` (rays, steps, n_wl) are the quadrature weights dt T of the
    transport matrix (row-scaled as M); ``ih, fh`` / ``im, fm`` (rays, steps) the
    altitude and zenith-cosine interpolation of every sample.
    """

    def __init__(self, *, ih, fh, im, fm, weight, r0, mu0, t, dt, h, R, hits, ground_t, h_nodes, mu_nodes, phi_nodes,
                 mus_nodes, wavelengths_nm, probe_step_nm, ozone_depth=None, max_elevation_deg: float = 10.0,
                 max_elements: int = 2_000_000, sigma_nodes=None, sigma_samples=None, coarse_phi: bool = False):
        self.fine_n_phi = phi_nodes.size  # the solver's azimuth count
        self.coarse = bool(coarse_phi)
        if self.coarse:
            phi_nodes = coarse_azimuths(phi_nodes)
        wl = np.asarray(wavelengths_nm, float)
        self.probe = spread_indices(wl, probe_step_nm)
        # probes -> every solver wavelength (applied to the factor in float32: in float64 it was the
        # solve's largest transient array)
        self.to_all = (None if self.probe.size == wl.size
                       else SolverSpectrumMap(wl[self.probe], wl, ozone_depth))
        self.n_h, self.n_mu, self.n_phi, self.n_mus = h_nodes.size, mu_nodes.size, phi_nodes.size, mus_nodes.size
        self.mus_nodes = mus_nodes
        # the sun nodes corrected: the lowest ``n_sub`` of them (mus_nodes ascend)
        assert np.all(np.diff(mus_nodes) > 0), "mus_nodes must ascend"
        self.n_sub = int(np.count_nonzero(mus_nodes <= np.sin(np.radians(max_elevation_deg))))
        n_rays, n_steps = t.shape
        self.n_p = self.n_phi * self.n_sub  # output (phi, corrected sun node) pairs
        self.n_rays, self.n_steps = n_rays, n_steps
        f32 = np.float32
        # the four (altitude, zenith) nodes of every sample and their weights, (rays, steps, 4)
        self.node = np.stack([(ih + dh) * self.n_mu + (im + dm) for dh in (0, 1) for dm in (0, 1)], axis=-1)
        self.node_w = np.stack([wh * wm for wh in (1 - fh, fh) for wm in (1 - fm, fm)], axis=-1).astype(f32)
        # with the source read as sigma_s(h) J / sigma_s (``sigma_nodes`` (n_h, n_wl) at the nodes,
        # ``sigma_samples`` (rays, steps, n_wl) at the samples), as the column transport M reads it
        if sigma_samples is not None:
            weight = weight * sigma_samples
        self.inv_sigma = (None if sigma_nodes is None  # (n_h, P)
                          else (1.0 / _safe(sigma_nodes))[:, self.probe].astype(f32))
        self.weight = np.ascontiguousarray(weight[..., self.probe], dtype=f32)  # (rays, steps, n_probe)
        mus_sub = mus_nodes[:self.n_sub]
        self.cs = _ray_sun_cosine(mu0, phi_nodes, mus_sub)  # (rays, n_p)
        self.mus_p = np.tile(mus_sub, self.n_phi)
        self.r0, self.t, self.r_t = r0, t, R + h
        # rays per chunk: each of SOLVER_THREADS threads holds the source of its chunk's samples at
        # every (phi, sun node), J and its slope, twice (``max_elements`` values in all)
        self.chunk = max(1, max_elements // (2 * max(1, SOLVER_THREADS))
                         // max(1, 2 * n_steps * self.n_phi * self.n_mus * self.probe.size))
        # the highest sun node any sample reads (its cell's upper node), + 1
        # (the node index grows with mu_s: that of the largest mu_s of any sample)
        top = max(float(_sun_cosine_along(r0[a:a + 64], self.mus_p, t[a:a + 64], self.cs[a:a + 64],
                                          self.r_t[a:a + 64]).max()) for a in range(0, n_rays, 64))
        self.n_read = int(_axis(mus_nodes, np.clip(np.array([top]), -1.0, 1.0))[0][0]) + 2
        self.hits = np.nonzero(hits)[0]
        t_end = t[self.hits, -1] + 0.5 * dt[self.hits, -1]
        mus_g = _sun_cosine_along(r0[self.hits], self.mus_p, t_end, self.cs[self.hits], R)
        self.ground_sun = _axis(mus_nodes, np.clip(mus_g, -1.0, 1.0))  # (G, n_p) node index and fraction
        self.ground_t = ground_t[self.hits][:, self.probe].astype(f32)  # (G, n_probe)

    def transport(self, j_probe, lg):
        """Spherical transport at the probe wavelengths for the corrected sun nodes:
        (n_probe, rays, n_phi, n_sub). ``j_probe`` (n_probe, n_mu * n_phi, n_h, n_mus) the
        source at the probe wavelengths on this transport's azimuths, ``lg`` (n_mus, n_wl)
        the light leaving the ground."""
        n_pr = self.probe.size
        n_nodes = self.n_h * self.n_mu
        f32 = np.float32
        # source laid out (probe, altitude * n_mu + mu, phi, mu_s)
        src = j_probe
        if self.inv_sigma is not None:  # J / sigma_s at the nodes
            src = src * self.inv_sigma.T[:, None, :, None]
        src = np.ascontiguousarray(dir_in_ray_order(src, self.n_mu, self.n_phi)).reshape(
            n_pr, n_nodes, self.n_phi, self.n_mus)
        out = np.zeros((self.n_rays, self.n_p, n_pr), dtype=f32)
        n_sub = self.n_sub

        # J and d(log J)/d(mu_s) at the sun nodes that some sample reads (``n_read``: the sun is
        # never far above the corrected nodes along a grid ray), laid out (J or slope, probe,
        # node, phi * mu_s): every array below is long in its last axis (with the probe last,
        # numpy's loops ran over 5 values at a time and the cubic took 2.3x longer)
        n_read = self.n_read
        flat_src = np.stack([src[..., :n_read], _log_slopes(self.mus_nodes, src, axis=3)[..., :n_read].astype(f32)])
        flat_src = flat_src.reshape(2 * n_pr, n_nodes, self.n_phi * n_read)

        def rays_of_thread(own_starts):  # each chunk writes its own rays of ``out``
            # the source at the samples' altitude and zenith cosine, the sum of the four
            # corners' rows weighted, in two work arrays kept from chunk to chunk (gathered
            # whole, (rays, steps, 4 corners, row), they were ~90 MB a chunk, allocated anew)
            size = 2 * n_pr * self.chunk * self.n_steps * flat_src.shape[2]
            at_hm, term = np.empty(size, dtype=f32), np.empty(size, dtype=f32)
            for a in own_starts:
                b = min(self.n_rays, a + self.chunk)
                c = b - a
                n_s = c * self.n_steps  # the chunk's samples
                shape = (2 * n_pr, n_s, flat_src.shape[2])
                acc, tmp = at_hm[:np.prod(shape)].reshape(shape), term[:np.prod(shape)].reshape(shape)
                for corner in range(4):  # (mode "clip": the nodes are in range; "raise" copies through a buffer)
                    np.take(flat_src, self.node[a:b, :, corner].ravel(), axis=1, out=tmp if corner else acc,
                            mode="clip")
                    if corner:
                        tmp *= self.node_w[a:b, :, corner].reshape(1, -1, 1)
                        acc += tmp
                    else:
                        acc *= self.node_w[a:b, :, 0].reshape(1, -1, 1)
                mus_t = _sun_cosine_along(self.r0[a:b], self.mus_p, self.t[a:b], self.cs[a:b],
                                          self.r_t[a:b])  # (c, s, n_p)
                i, f = _axis(self.mus_nodes, np.clip(mus_t, -1.0, 1.0))
                # read along the sun axis at each sample's own sun cosine
                rows = (np.arange(n_s * self.n_phi).reshape(c, self.n_steps, self.n_phi, 1) * n_read
                        + i.reshape(c, self.n_steps, self.n_phi, n_sub)).ravel()
                vals = acc.reshape(2, n_pr, -1)
                lo, hi = np.take(vals, rows, axis=2, mode="clip"), np.take(vals, rows + 1, axis=2, mode="clip")
                # in float32, as the source (in float64 the cubic's arrays were twice the memory traffic)
                dx = (self.mus_nodes[i + 1] - self.mus_nodes[i]).ravel().astype(f32)
                got = _sun_interp_cubic(lo[0], hi[0], lo[1], hi[1], dx, f.ravel().astype(f32),
                                        (self.mus_nodes[i + 1] <= 0.0).ravel())  # (probe, samples * n_p)
                out[a:b] = np.einsum("csw,wcsp->cpw", self.weight[a:b], got.reshape(n_pr, c, self.n_steps, self.n_p))

        chunks_in_threads(rays_of_thread, range(0, self.n_rays, self.chunk), SOLVER_THREADS)
        if self.hits.size:
            i, f = self.ground_sun
            lgp = lg[:, self.probe]  # (n_mus, P)
            sl = _log_slopes(self.mus_nodes, lgp, axis=0)
            g = _sun_interp_cubic(lgp[i], lgp[i + 1], sl[i], sl[i + 1], (self.mus_nodes[i + 1] - self.mus_nodes[i])[..., None],
                                  f[..., None], (self.mus_nodes[i + 1] <= 0.0)[..., None])  # (G, n_p, P)
            out[self.hits] += g * self.ground_t[:, None, :]
        return np.moveaxis(out, -1, 0).reshape(n_pr, self.n_rays, self.n_phi, n_sub)

    def correction(self, j_dir, lg, column_dir):
        """Factor (n_wl, n_dir, n_h, n_sub) float32 turning the column transport ``column_dir``
        (the dir layout of M J + G L_g) into the spherical one at the corrected sun nodes, the
        first ``n_sub`` (above them the factor is 1): ``column_dir[..., :n_sub] *= factor``."""
        n_wl = column_dir.shape[0]
        if self.n_sub == 0:
            return np.ones((n_wl, column_dir.shape[1], self.n_h, 0), dtype=np.float32)
        j_probe, col = j_dir[self.probe], column_dir[self.probe, ..., :self.n_sub]
        if self.coarse:
            j_probe, col = (azimuth_pair_mean(x, self.n_mu, self.fine_n_phi) for x in (j_probe, col))
        sph = self.transport(j_probe, lg)  # (P, rays, n_phi, n_sub)
        col = dir_in_ray_order(col, self.n_mu, self.n_phi).reshape(sph.shape)
        # a radiance is never negative: the transport's few negative values (linear sun-angle reads of
        # sources with rounding-level negatives) are 0 (a negative factor, applied again to the tail's
        # orders, made the series diverge at a dark node: desert -4 degrees, sun node -7.5 degrees,
        # factor -416, the node's radiance x11 an order)
        r = np.where(col > 0.0, np.maximum(sph, 0.0) / np.where(col > 0.0, col, 1.0), 1.0)  # (P, rays, n_phi, n_sub)
        if self.coarse:  # back on the solver's azimuths (at the probe wavelengths: n_wl / P times less work)
            r = azimuths_to_fine(r, axis=2)
        if self.to_all is not None:
            r = self.to_all(r.astype(np.float32, copy=False), axis=0, dtype=np.float32)
        factor = np.empty((n_wl, self.n_mu * self.fine_n_phi, self.n_h, self.n_sub), dtype=np.float32)
        np.copyto(dir_in_ray_order(factor, self.n_mu, self.fine_n_phi),
                  r.reshape(n_wl, self.n_h, self.n_mu, self.fine_n_phi, self.n_sub))
        return factor
