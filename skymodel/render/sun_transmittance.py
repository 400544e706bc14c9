"""Transmittance toward the sun from any point of the atmosphere, with the Earth's shadow.

In a spherically symmetric atmosphere the optical depth from a point at radius r to
the top of the atmosphere along a direction whose cosine with the local vertical is mu
depends on (r, mu) only. We tabulate it once per render on a grid of altitudes and of
Bruneton & Neyret's (2008) distance parameter: with rho = sqrt(r^2 - R^2) and
H = sqrt(r_top^2 - R^2), the distance d to the top boundary runs from r_top - r
(looking straight up) to rho + H (the ray grazing the ground), and we take nodes evenly
in x = (d - d_min) / (d_max - d_min). This spreads the nodes where the optical depth
changes fastest, near the horizon. The altitude nodes are evenly spaced in sqrt(rho / H)
(rho = H u^2, u even: Bruneton 2017's x_r = rho / H, squared), and the table is
interpolated linearly in rho between them. Near
the ground rho = sqrt(2 R h) changes fastest: the horizon distance d_max grows by 40 km in
the lowest 125 m, so at a fixed x the direction, and with a low sun the optical depth,
changes as sqrt(h) there. Altitude nodes interpolated in h miss that: with 128 nodes
on a stretched altitude grid (the first at 125 m) a point 35 m above the ground with the
sun at 5 degrees got an optical depth 0.08 too small at 450 nm (rural aerosol, AOD 0.2:
8 % too much sunlight), and the horizon toward that sun (88/0) came out 0.9-1.6 % above
the Monte Carlo tracer's (se 0.1-0.2 %). Evenly in rho, the lowest nodes lie 6, 25, 56,
100 m up; that optical depth error is 0.006, and 88/0 is within -0.0..+0.5 %
(notebooks/sunward_horizon, "88/0 with the sun at 5 degrees").
Linear in rho is not linear in h = rho^2 / 2R: between nodes i and i + 1 a depth that
falls linearly with h is read too small by its slope times (rho - rho_i)(rho_i+1 - rho)
/ 2R, 2.8 m of altitude mid-interval with 96 nodes evenly in rho: at sun 5 degrees up to
0.012 of a depth of 5 in the lowest few hundred metres (rural, 450 nm; 1.2 % too much
sunlight on the horizon's single scattering). With the nodes evenly in sqrt(rho) the
low intervals are much narrower (the first rho step H / 95^2, 125 m) and the top ones
twice the even step, where the air is thin: the error is 0.0025 (tests/
test_sun_transmittance.py; 96 nodes against 768: sun 60/20/5/2 degrees 0.0013/0.0033/
0.0116/0.024 -> 0.0003/0.0007/0.0021/0.0038 in the lowest 20 km, rural AOD 0.2).

Directions below the local horizon (mu < -rho / r) meet the planet: the point is in the
Earth's shadow. The sun is a disc of angular radius alpha, so near the horizon it sets
gradually: the visible fraction is the area of a uniform disc above a straight horizon
at angular distance e (elevation of the sun's centre above the local horizon),
0.5 + (c sqrt(1 - c^2) + asin c) / pi with c = clip(e / alpha, -1, 1).
The optical depth is tabulated for the low-rank basis functions of the extinction
(:mod:`skymodel.render.medium`), so one table serves every wavelength.
"""

from __future__ import annotations

import numpy as np

from skymodel.render.medium import LowRank, march_samples
from skymodel.render.rays import altitude_along
from skymodel.render.threads import SOLVER_THREADS, in_threads

#: Angular radius of the sun at 1 AU, radians (IAU nominal radius 695,700 km).
SUN_ANGULAR_RADIUS_RAD = np.arcsin(695_700.0 / 149_597_870.7)


def horizon_mu(planet_radius_m: float, r_m) -> np.ndarray:
    """Sine of the local horizon's elevation (the cosine, from the zenith, of the grazing
    direction) seen from radius ``r_m`` (metres from the planet's centre; r <= R gives 0)."""
    return -np.sqrt(np.clip(1.0 - (planet_radius_m / r_m) ** 2, 0.0, 1.0))


#: Altitude rows of the table integrated at a time (on :data:`SOLVER_THREADS` threads):
#: whole, the samples' basis values were ~0.35 GB at ``final`` and their allocation,
#: not the arithmetic, took most of the table's time.
_TABLE_ROWS = 2


#: the altitude nodes: rho = H u**_RHO_POWER, u evenly spaced (module docstring)
_RHO_POWER = 2.0


class SunTransmittance:
    """Optical depth to the top of the atmosphere for several low-rank media at once.

    ``earth_shadow=False`` (``MarchSettings.earth_shadow`` passes it; an approximation, for
    measuring what the shadow does: the effect planner's table) lets the planet block no
    sunlight: the whole disc counts as
    visible everywhere, and points under the local horizon get the optical depth of the
    grazing ray."""

    def __init__(self, media: list[LowRank], ground_radius: float, top_altitude: float,
                 n_altitudes: int = 96, n_x: int = 192, n_steps: int = 256, earth_shadow: bool = True):
        self.earth_shadow = bool(earth_shadow)
        self.media = list(media)
        self.R = float(ground_radius)
        self.top = float(top_altitude)
        self.r_top = self.R + self.top
        big_h = np.sqrt(self.r_top**2 - self.R**2)
        self._rho_power = float(_RHO_POWER)
        self.rho_nodes = big_h * np.linspace(0.0, 1.0, n_altitudes) ** self._rho_power * (1.0 - 1e-9)
        self.h_nodes = np.sqrt(self.rho_nodes**2 + self.R**2) - self.R
        self.x_nodes = np.linspace(0.0, 1.0, n_x) * (1.0 - 1e-9)
        # integrals of every basis function along every tabulated ray: (n_h, n_x, k_total),
        # the bases of all media stacked (they share the profile's altitude nodes)
        stacked = LowRank(self.media[0].nodes_m, np.concatenate([m.basis for m in self.media], axis=1),
                          np.zeros((1, 1)), self.media[0].layered, self.media[0].top_m)
        table = np.empty((n_altitudes, n_x, stacked.rank))

        def rows(a):  # a few altitude rows at a time: the samples' basis values stay small
            b = min(n_altitudes, a + _TABLE_ROWS)
            hh, xx = np.meshgrid(self.h_nodes[a:b], self.x_nodes, indexing="ij")
            mu = self._mu_from_x(hh, xx)
            r = self.R + hh
            p = np.stack([np.zeros_like(r), np.zeros_like(r), r], axis=-1)
            d = np.stack([np.sqrt(np.clip(1 - mu * mu, 0, None)), np.zeros_like(mu), mu], axis=-1)
            t, dt = march_samples(p, d, np.zeros_like(r), self._distance_to_top(r, mu), n_steps, self.R)
            table[a:b] = np.einsum("hxsk,hxs->hxk", stacked.basis_at(altitude_along(p, d, t, self.R)), dt)

        in_threads(rows, range(0, n_altitudes, _TABLE_ROWS), SOLVER_THREADS)
        splits = np.cumsum([m.rank for m in self.media])[:-1]
        # each its own contiguous array: basis_depths gathers rows of table.reshape(-1, rank)
        self.tables = [np.ascontiguousarray(t) for t in np.split(table, splits, axis=-1)]
        # each medium's weights (rank, n_wl); add_depth_columns appends rows (and table columns)
        self.weights = [m.weights for m in self.media]
        self.base_ranks = [m.rank for m in self.media]

    def add_depth_columns(self, which: int, columns, weights) -> None:
        """Add an optical depth to medium ``which``: ``columns`` (n_h, n_x, P) at the table's
        nodes, read with the table's interpolation and ``weights`` (P, n_wl) to the medium's
        wavelengths (:mod:`skymodel.render.peak_paths`). ``straight=`` of
        :meth:`transmittances` still gives the medium without them."""
        columns = np.asarray(columns, dtype=float)
        weights = np.asarray(weights, dtype=float)
        assert columns.shape[:2] == self.tables[which].shape[:2] and columns.shape[2] == weights.shape[0]
        assert weights.shape[1] == self.weights[which].shape[1]
        self.tables[which] = np.concatenate([self.tables[which], columns], axis=-1)
        self.weights[which] = np.concatenate([self.weights[which], weights], axis=0)

    def _distance_to_top(self, r, mu):
        disc = r * r * (mu * mu - 1.0) + self.r_top**2
        return -r * mu + np.sqrt(np.clip(disc, 0.0, None))

    def _mu_from_x(self, h, x):
        r = self.R + h
        rho = np.sqrt(np.clip(r * r - self.R**2, 0.0, None))
        big_h = np.sqrt(self.r_top**2 - self.R**2)
        d_min = self.r_top - r
        d_max = rho + big_h
        d = d_min + x * (d_max - d_min)
        mu = np.where(d > 0, (big_h**2 - rho**2 - d * d) / (2.0 * r * np.where(d > 0, d, 1.0)), 1.0)
        return np.clip(mu, -1.0, 1.0)

    def _x_from_mu(self, r, mu):
        rho = np.sqrt(np.clip(r * r - self.R**2, 0.0, None))
        big_h = np.sqrt(self.r_top**2 - self.R**2)
        d_min = self.r_top - r
        d_max = rho + big_h
        d = self._distance_to_top(r, mu)
        return np.clip((d - d_min) / np.maximum(d_max - d_min, 1e-9), 0.0, self.x_nodes[-1])

    def altitude_weights(self, altitudes_m):
        """Index i of the node below each altitude and the weight fi of node i + 1 for
        the table's interpolation, linear in rho = sqrt(r^2 - R^2) (see the module's
        docstring); altitudes are clamped to the table's range."""
        h = np.clip(np.asarray(altitudes_m, dtype=float), self.h_nodes[0], self.h_nodes[-1])
        rho = np.sqrt(h * (2.0 * self.R + h))
        n = self.rho_nodes.size
        power = getattr(self, "_rho_power", 1.0)  # a table pickled before the rule (evenly in rho)
        u = (rho / (self.rho_nodes[-1] / (1.0 - 1e-9))) ** (1.0 / power) * (n - 1)
        i = np.clip(u.astype(np.int64), 0, n - 2)
        lo = self.rho_nodes[i]
        fi = np.clip((rho - lo) / (self.rho_nodes[i + 1] - lo), 0.0, 1.0)
        return i, fi

    def visible_fraction(self, altitudes_m, mu_sun):
        """Fraction of the solar disc above the local horizon (0 in the Earth's shadow;
        1 everywhere when ``earth_shadow`` is False)."""
        if not self.earth_shadow:
            return np.ones(np.broadcast_shapes(np.shape(altitudes_m), np.shape(mu_sun)))
        r = self.R + np.maximum(np.asarray(altitudes_m, dtype=float), 0.0)
        sin_horizon = horizon_mu(self.R, r)
        e = np.arcsin(np.clip(mu_sun, -1.0, 1.0)) - np.arcsin(sin_horizon)
        c = np.clip(e / SUN_ANGULAR_RADIUS_RAD, -1.0, 1.0)
        return 0.5 + (c * np.sqrt(1.0 - c * c) + np.arcsin(c)) / np.pi

    def optical_depth(self, altitudes_m, mu_sun, which: int = 0):
        """Optical depth (…, n_wl) toward the sun of medium ``which``, for points at
        ``altitudes_m`` whose local vertical makes cosine ``mu_sun`` with the sun
        direction. Directions under the horizon are clamped to the grazing ray (their
        light is removed by :meth:`visible_fraction`)."""
        return self.basis_depths(altitudes_m, mu_sun, (which,))[0] @ self.weights[which]

    def basis_depths(self, altitudes_m, mu_sun, which):
        """The tabulated optical depths of the basis functions of each medium in ``which``
        (…, rank), interpolated at the points (one lookup for all the media)."""
        h = np.clip(np.asarray(altitudes_m, dtype=float), self.h_nodes[0], self.h_nodes[-1])
        r = self.R + h
        mu_h = horizon_mu(self.R, r)
        mu = np.maximum(np.asarray(mu_sun, dtype=float), mu_h)
        x = self._x_from_mu(r, mu)
        i, fi = self.altitude_weights(h)
        fi = fi[..., None]
        xs = x * (self.x_nodes.size - 1) / self.x_nodes[-1]
        j = np.clip(xs.astype(int), 0, self.x_nodes.size - 2)
        fj = np.clip(xs - j, 0.0, 1.0)[..., None]
        tab = self.tables[which[0]] if len(which) == 1 else np.concatenate([self.tables[w] for w in which], axis=-1)
        # the four corners by one flat index each (np.take on rows: faster than tab[i, j])
        n_x = tab.shape[1]
        rows = tab.reshape(-1, tab.shape[-1])
        k = i * n_x + j
        tau_k = ((np.take(rows, k, axis=0) * (1 - fj) + np.take(rows, k + 1, axis=0) * fj) * (1 - fi)
                 + (np.take(rows, k + n_x, axis=0) * (1 - fj) + np.take(rows, k + n_x + 1, axis=0) * fj) * fi)
        return np.split(tau_k, np.cumsum([self.weights[w].shape[0] for w in which])[:-1], axis=-1)

    def transmittance(self, altitudes_m, mu_sun, which: int = 0):
        """exp(-tau) times the visible fraction of the disc, (…, n_wl)."""
        return self.transmittances(altitudes_m, mu_sun, (which,))[0]

    def transmittances(self, altitudes_m, mu_sun, which=(0,), dtype=np.float64, straight=()):
        """:meth:`transmittance` of each medium in ``which`` at the same points, with one
        table lookup: a list of (…, n_wl) arrays of ``dtype``; then, for each medium in
        ``straight`` (also in ``which``), the same without the columns of
        :meth:`add_depth_columns` (the very array where it has none). In float32 (the
        marcher's per-sun march) the optical depths are summed from the basis and
        exponentiated in float32: exp is 8x cheaper there, and a transmittance needs no more
        than float32's relative 6e-8."""
        vis = self.visible_fraction(altitudes_m, mu_sun)[..., None].astype(dtype, copy=False)
        which = tuple(which)
        depths = dict(zip(which, self.basis_depths(altitudes_m, mu_sun, which)))

        def trans(tau_k, weights):
            t = tau_k.astype(dtype, copy=False) @ weights.astype(dtype, copy=False)
            np.negative(t, out=t)
            np.exp(t, out=t)
            t *= vis
            return t

        out = [trans(depths[w], self.weights[w]) for w in which]
        for w in straight:
            k = self.base_ranks[w]
            out.append(out[which.index(w)] if self.weights[w].shape[0] == k
                       else trans(depths[w][..., :k], self.weights[w][:k]))
        return out
