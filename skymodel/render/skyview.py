"""The sky-view table: a sky marched once on a direction grid, then resampled to any image.

A panorama of 4096x2048 pixels has 8.4 million directions; the sky's radiance varies
slowly over most of them. :class:`SkyViewTable` holds the radiance of one
:class:`~skymodel.render.marcher.SkyMarcher` (one atmosphere, sun and observer), already
reduced to the output channels (a linear map of the spectrum, e.g. CIE XYZ: 3 numbers per
node instead of 81), on two direction grids (as the sky-view LUT of Hillaire 2020):

* the **main grid**: the marcher's own direction grid (zenith angle x azimuth from the
  sun's vertical plane, 0..180 degrees since the sky of a horizontally homogeneous
  atmosphere is symmetric about that plane; the zenith nodes are split at the observer's
  horizon and crowded toward it on both sides, ``MarchSettings.grid_zenith``,
  ``grid_zenith_ground``, ``grid_azimuth``). Its nodes are marched once when the marcher
  is built; a pixel outside the sun cap is interpolated bilinearly from it, which is what
  the marcher itself does for such a pixel, so the table's value equals direct marching
  there up to rounding (a linear reduction commutes with linear interpolation);
* the **sun cap**: directions within ``MarchSettings.sun_exact_deg`` (8-12 degrees) of the
  sun, which direct marching evaluates exactly (the aureole), on a polar grid centred on
  the sun: angle from the sun evenly spaced in its logarithm from :data:`CAP_EXACT_DEG` to
  the cap's edge (:data:`CAP_RADIAL` nodes for an 8-degree cap, in proportion to the
  logarithm of the edge's angle over :data:`CAP_EXACT_DEG` for others, so the spacing stays)
  x angle around the sun, 0..180 degrees (the
  same symmetry, :data:`CAP_AROUND` nodes), marched exactly once per sun. A pixel in the
  cap is interpolated bilinearly in (log angle, angle around): within
  :data:`CAP_RATIO_DEG` of the horizon the ratio exact / main grid (the main grid's
  crowded zenith nodes carry the horizon's steep gradient; read in its logarithm for this, along
  its rows linearly in the logarithm of the angle from the sun, so that its cells beside a low sun
  do not cut the aureole's power-law fall into kinks),
  elsewhere the logarithm of the value (the aureole falls as a power of the angle). A cap whose lowest point is
  :data:`CAP_RATIO_DEG` + :data:`CAP_CLEAR_MARGIN_DEG` or more above the horizon (a sun
  above 17 degrees for ``final``'s 12-degree cap) is *clear*: it keeps every other node
  (21 x 25 instead of 41 x 49 at ``final``, a quarter of the marching), and a pixel is
  its single scattering plus the rest (multiple scattering, peak aureole), interpolated
  apart: the rest's logarithm, and single scattering's ratio to a reference that carries
  the phase functions' fall and ripples in the angle from the sun (the reduced spectrum
  of one column's single scattering, E_sun sum_s p_s(gamma) tau_s, evaluated at each
  pixel's angle; :meth:`SkyViewTable._phase_reference`). Against direct marching this
  cuts the largest error of coarse desert dust's aureole under a high sun 4-12 fold with
  a quarter of the nodes (docs/benchmarks.md, "A cheaper sun cap"). Pixels closer to the sun than
  :data:`CAP_EXACT_DEG`, closer to the horizon than :data:`CAP_HORIZON_DEG`, or whose four
  nodes are not all on their side of the horizon (a low sun's cap straddles the sky/ground
  edge) are marched exactly: a few thousand pixels of a 4096x2048 panorama.

Resampling error against direct marching of every pixel is measured by
``benchmarks/bench_skyview.py`` (docs/benchmarks.md, "Large environment maps"), which
sized the cap grid; ``tests/test_skyview.py`` checks it at small sizes.

References
----------
S. Hillaire, "A Scalable and Production Ready Sky and Atmosphere Rendering Technique",
Computer Graphics Forum 39(4), 2020 (the sky-view LUT: a latitude/longitude table crowded
toward the horizon, rendered once per frame and sampled per pixel).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["Reduction", "SkyViewTable", "xyz_reduction", "rgb_reduction", "CAP_RADIAL", "CAP_AROUND",
           "CAP_CLEAR_MARGIN_DEG", "cap_radial_nodes", "cap_is_clear", "cap_shape", "TABLE_MIN_PIXELS"]

#: Nodes of the sun cap's polar grid: from the sun outward (log-spaced, for a cap of
#: :data:`CAP_RADIAL_DEG`; :func:`cap_radial_nodes` for other caps) and around it
#: (0..180 degrees). Sized by ``benchmarks/bench_skyview.py`` (see the module doc).
CAP_RADIAL = 32
CAP_RADIAL_DEG = 8.0
CAP_AROUND = 49
#: Pixels closer than this to the sun (degrees) are marched exactly: the aureole of coarse
#: dust falls by 10x per degree there and carries 5-10 % ripples over 0.1 degree, which no
#: affordable node spacing resolves (measured: 2-6 % error 1 degree from the sun, desert).
CAP_EXACT_DEG = 2.0
#: Pixels of the cap this close to the horizon (degrees) are marched exactly: the ground
#: seen at grazing angles toward a low sun changes by 2x over a fraction of a degree.
CAP_HORIZON_DEG = 0.5
#: Within this many degrees of the horizon the cap holds exact / main grid (the main grid's
#: crowded zenith nodes carry the horizon's steep gradient), elsewhere the exact values.
CAP_RATIO_DEG = 4.0
#: A cap whose lowest point is at least CAP_RATIO_DEG + this many degrees above the horizon
#: is "clear": it keeps every other node of the full grid (:class:`SkyViewTable`).
CAP_CLEAR_MARGIN_DEG = 1.0
#: Images with at least this many valid pixels go through the table in ``render_sky``'s
#: ``method="auto"``: below it the table's own nodes (about 12 000 at ``final``) are not
#: fewer than the pixels near the sun it saves marching.
TABLE_MIN_PIXELS = 1 << 18


def cap_radial_nodes(cap_deg: float) -> int:
    """Radial nodes of a sun cap reaching ``cap_deg`` from the sun: :data:`CAP_RADIAL` at
    :data:`CAP_RADIAL_DEG`, in proportion to log(cap_deg / CAP_EXACT_DEG) otherwise (the same
    log spacing: ``final``'s 12-degree cap has 41)."""
    ratio = np.log(max(float(cap_deg), 1.01 * CAP_EXACT_DEG) / CAP_EXACT_DEG) / np.log(CAP_RADIAL_DEG / CAP_EXACT_DEG)
    return max(2, int(round(CAP_RADIAL * ratio)))


def cap_is_clear(sun_zenith_rad: float, cap_deg: float, horizon_zenith_rad: float) -> bool:
    """Whether a sun cap reaching ``cap_deg`` [deg] from a sun at ``sun_zenith_rad`` [rad] stays
    :data:`CAP_RATIO_DEG` + :data:`CAP_CLEAR_MARGIN_DEG` above the horizon at ``horizon_zenith_rad``
    [rad]: such a cap holds no steep gradient and keeps every other node (:func:`cap_shape`)."""
    return bool(float(sun_zenith_rad) + np.radians(float(cap_deg))
                < float(horizon_zenith_rad) - np.radians(CAP_RATIO_DEG + CAP_CLEAR_MARGIN_DEG))


def cap_shape(cap_deg: float, clear: bool, cap_radial: int | None = None, cap_around: int = CAP_AROUND):
    """(radial, around) nodes of a sun cap reaching ``cap_deg`` [deg] (``cap_radial`` None:
    :func:`cap_radial_nodes`); a clear cap (:func:`cap_is_clear`) keeps every other node."""
    radial = cap_radial_nodes(cap_deg) if cap_radial is None else int(cap_radial)
    around = int(cap_around)
    if clear:
        radial, around = (radial + 1) // 2, (around + 1) // 2
    return radial, around


@dataclass(frozen=True)
class Reduction:
    """How spectra become output channels: ``matrix`` (n_wl, K) applied first (linear, so
    it commutes with the table's interpolation; None keeps the spectra), then ``finish``
    ((n, K) -> (n, n_channels), e.g. a gamut fit; None: none) on each pixel."""

    matrix: np.ndarray | None
    n_channels: int
    finish: object = None

    def linear(self, spectra: np.ndarray) -> np.ndarray:
        return spectra if self.matrix is None else spectra @ self.matrix

    def final(self, values: np.ndarray) -> np.ndarray:
        return values if self.finish is None else np.asarray(self.finish(values), dtype=float)

    def __call__(self, spectra, wavelengths_nm=None):
        """The whole reduction of spectra (n, n_wl) -> (n, n_channels)."""
        return self.final(self.linear(np.asarray(spectra, dtype=float)))


def xyz_reduction(wavelengths_nm) -> Reduction:
    """Spectra -> CIE 1931 XYZ (:func:`skymodel.colorimetry.cmf_weights`)."""
    from skymodel.colorimetry import cmf_weights

    return Reduction(cmf_weights(wavelengths_nm), 3)


def rgb_reduction(wavelengths_nm, space: str = "rec709", finish=None) -> Reduction:
    """Spectra -> scene-linear RGB of ``space``, then ``finish`` (e.g. a gamut fit)."""
    from skymodel.colorimetry import cmf_weights, xyz_to_rgb_matrix

    return Reduction(cmf_weights(wavelengths_nm) @ xyz_to_rgb_matrix(space).T, 3, finish)


def _bilinear(tab, i, fi, j, fj):
    """tab (A, B, K) at fractional nodes (i + fi, j + fj) -> (N, K)."""
    fi, fj = fi[:, None], fj[:, None]
    return ((tab[i, j] * (1 - fj) + tab[i, j + 1] * fj) * (1 - fi)
            + (tab[i + 1, j] * (1 - fj) + tab[i + 1, j + 1] * fj) * fi)


def _cell(axis, x):
    """Index of the cell of ``axis`` (ascending) holding x (clipped) and the fraction in it."""
    x = np.clip(x, axis[0], axis[-1])
    i = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, axis.size - 2)
    return i, (x - axis[i]) / (axis[i + 1] - axis[i])


class SkyViewTable:
    """The radiance of ``marcher``'s sky reduced by ``reduction.matrix`` on the main grid and
    the sun cap (module doc). ``lookup(directions)`` gives (N, K) values; ``timings`` the
    seconds spent building the cap (the main grid is the marcher's)."""

    def __init__(self, marcher, reduction: Reduction, cap_radial: int | None = None, cap_around: int = CAP_AROUND,
                 coarse_when_clear: bool = True):
        if marcher._grid is None:
            raise ValueError("the sky-view table needs a marcher with a direction grid (settings.exact is False)")
        t0 = time.perf_counter()
        self.marcher = marcher
        self.reduction = reduction
        sky, ground, az, images = marcher._grid
        self.sky_zenith, self.ground_zenith, self.azimuth = sky, ground, az
        self.sky = reduction.linear(sum(images[0]))  # (n_zen, n_az, K)
        self.ground = reduction.linear(sum(images[1]))
        # their logarithms: the base of the cap's ratio near the horizon (:meth:`_main`)
        self.log_sky, self.log_ground = (np.log(np.maximum(t, np.finfo(float).tiny)) for t in (self.sky, self.ground))
        self.pos_sky, self.pos_ground = ((t > 0).astype(float) for t in (self.sky, self.ground))
        self.horizon = marcher.horizon_zenith_rad()
        self.sun = np.asarray(marcher.sun, float)
        self.cap_max = np.radians(marcher.settings.sun_exact_deg)
        self.cos_cap = np.cos(self.cap_max)
        # the cap's frame: e1 in the sun's vertical plane toward the zenith, e2 = sun x e1
        zen = np.array([0.0, 0.0, 1.0])
        e1 = zen - self.sun[2] * self.sun
        if np.linalg.norm(e1) < 1e-9:  # sun at the zenith: any horizontal axis
            e1 = np.array([np.sin(np.radians(marcher.sun_azimuth_deg)), np.cos(np.radians(marcher.sun_azimuth_deg)),
                           0.0])
        self.e1 = e1 / np.linalg.norm(e1)
        self.e2 = np.cross(self.sun, self.e1)
        # a cap clear of the horizon's band holds no steep gradient: every other node suffices
        self.clear = cap_is_clear(np.arccos(np.clip(self.sun[2], -1.0, 1.0)), marcher.settings.sun_exact_deg,
                                  self.horizon)
        cap_radial, cap_around = cap_shape(marcher.settings.sun_exact_deg, self.clear and coarse_when_clear,
                                           cap_radial, cap_around)
        self.cap_u = np.linspace(0.0, 1.0, int(cap_radial))
        self.cap_psi = np.linspace(0.0, np.pi, int(cap_around))
        self.cap_min = np.radians(CAP_EXACT_DEG)
        self.horizon_band = np.radians(CAP_HORIZON_DEG)
        g = self._gamma(self.cap_u)
        gg, pp = np.meshgrid(g, self.cap_psi, indexing="ij")
        d = (np.cos(gg)[..., None] * self.sun + np.sin(gg)[..., None]
             * (np.cos(pp)[..., None] * self.e1 + np.sin(pp)[..., None] * self.e2)).reshape(-1, 3)
        zen_d = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        below_d = zen_d >= self.horizon
        single, rest = self._march_split(d)
        exact = single + rest
        base = self._main(d, zen_d, below_d, log=True)
        # the cap holds log(exact / main grid): 0 where the main grid is already right, smooth
        # across the horizon's steep gradient (which the main grid's crowded zenith nodes carry);
        # the main grid read in its logarithm, as the aureole falls as a power of the angle from
        # the sun across its cells (read linearly, the kinks at its nodes beside a low sun showed:
        # 3.5 % against 8.6 %, `preview`, urban sun 4)
        ok = (exact > 0) & (base > 0)
        ratio = np.where(ok, exact / np.where(ok, base, 1.0), 1.0)
        self.log_ratio = np.log(ratio).reshape(gg.shape + (-1,))
        self.log_cap = np.log(np.where(exact > 0, exact, 1.0)).reshape(gg.shape + (-1,))
        self.cap_positive = np.all(exact > 0, axis=-1).reshape(gg.shape)
        # away from the horizon, single scattering over its reference (:meth:`_phase_reference`,
        # which carries the phase functions' fall and ripples in the angle from the sun) and
        # the rest (multiple scattering, the peak aureole, the ground), each smooth, apart
        self.ref_gamma, self.ref_values = self._phase_reference()
        ref = self._reference(gg.ravel())
        split = (single > 0) & (rest > 0) & (ref > 0)
        self.log_single = np.log(np.where(split, single, 1.0) / np.where(split, ref, 1.0)).reshape(gg.shape + (-1,))
        self.log_rest = np.log(np.where(split, rest, 1.0)).reshape(gg.shape + (-1,))
        self.cap_split = np.all(split, axis=-1).reshape(gg.shape) & self.clear
        self.cap_below = below_d.reshape(gg.shape)
        self.timings = {"cap_s": time.perf_counter() - t0, "cap_nodes": int(d.shape[0])}
        self.exact_pixels = 0
        self._count_lock = threading.Lock()

    def _gamma(self, u):
        """Angle from the sun [rad] of the cap's radial coordinate u in [0, 1]."""
        return self.cap_min * (self.cap_max / self.cap_min) ** u

    def _march(self, d):
        """Exactly marched, reduced values (N, K) of directions d (N, 3)."""
        if d.shape[0] == 0:
            return np.zeros((0, self.sky.shape[-1]))
        parts = self.marcher.exact_in_threads(d)
        return np.concatenate([self.reduction.linear(s + mu + g) for s, mu, g in parts])

    def _march_split(self, d):
        """Exactly marched, reduced single scattering and the rest (multiple + ground),
        each (N, K), of directions d (N, 3)."""
        parts = self.marcher.exact_in_threads(d)
        red = self.reduction.linear
        return (np.concatenate([red(s) for s, _, _ in parts]), np.concatenate([red(mu + g) for _, mu, g in parts]))

    def _phase_reference(self):
        """The shape of single scattering in the angle gamma from the sun: the reduced
        spectrum of sunlight scattered once by a vertical column of the medium,
        E_sun (p_R(gamma) tau_R + sum_r p_r(gamma) tau_r) (tau: each species' vertical
        scattering optical depth), tabulated at the angles of the aerosol phase tables
        inside the cap (between which the phase functions are linear in the angle, as
        ``aerosol_phase_at`` interpolates them) and at 256 even steps. Returns (gamma [rad]
        (M,), values (M, K))."""
        m = self.marcher
        prof, med = m.profile, m.medium
        deg = np.asarray(prof.aerosol_phase_angles_deg, float)
        lo, hi = np.degrees(self.cap_min), np.degrees(self.cap_max)
        gam = np.radians(np.unique(np.concatenate([deg[(deg > lo) & (deg < hi)], np.linspace(lo, hi, 256)])))
        z = np.linspace(0.0, m.top, 801)
        dz = np.full(z.size, z[1] - z[0])
        dz[[0, -1]] *= 0.5  # the trapezoid rule
        c = np.cos(gam)
        spec = prof.rayleigh_phase(c) * (dz @ med.rayleigh.at(z))
        pa = prof.aerosol_phase_at(c)  # (R, M, W)
        for r, lr in enumerate(med.aerosol):
            spec = spec + pa[r] * (dz @ lr.at(z))
        return gam, self.reduction.linear(spec * prof.solar_irradiance)

    def _reference(self, gamma):
        """The reference (:meth:`_phase_reference`) at angles ``gamma`` [rad] from the sun, (N, K)."""
        g = np.clip(gamma, self.ref_gamma[0], self.ref_gamma[-1])
        return np.stack([np.interp(g, self.ref_gamma, v) for v in self.ref_values.T], axis=-1)

    @property
    def n_nodes(self) -> int:
        return int(self.sky.shape[0] * self.sky.shape[1] + self.ground.shape[0] * self.ground.shape[1]
                   + self.log_ratio.shape[0] * self.log_ratio.shape[1])

    def _main(self, d, zen, below, log: bool = False):
        """Bilinear values (N, K) of the main grid at directions d (N, 3). ``log``: the base of the
        cap's ratio near the horizon, interpolated in the logarithm, along each row of equal
        zenith angle linearly in the logarithm of the angle from the sun (exact for a power law of
        it, the aureole's fall; that angle grows monotonically with the azimuth from the sun along
        a row), then linearly in the zenith angle; linear where a weighted node is not positive."""
        dh = d[:, :2]
        sun_h = self.sun[:2]
        nrm = np.linalg.norm(dh, axis=1) * np.linalg.norm(sun_h)
        c = np.where(nrm > 1e-12, (dh @ sun_h) / np.where(nrm > 1e-12, nrm, 1.0), 1.0)
        rel = np.arccos(np.clip(c, -1.0, 1.0))
        j, fj = _cell(self.azimuth, rel)
        vals = np.empty((d.shape[0], self.sky.shape[-1]))
        for mask, axis, tab, log_tab, pos_tab in ((~below, self.sky_zenith, self.sky, self.log_sky, self.pos_sky),
                                                  (below, self.ground_zenith, self.ground, self.log_ground,
                                                   self.pos_ground)):
            if np.any(mask):
                i, fi = _cell(axis, zen[mask])
                cell = (i, fi, j[mask], fj[mask])
                vals[mask] = _bilinear(tab, *cell)
                if log:
                    positive = _bilinear(pos_tab, *cell) > 1.0 - 1e-12
                    vals[mask] = np.where(positive, np.exp(self._log_rows(log_tab, axis, *cell, rel[mask])),
                                          vals[mask])
        return vals

    def _log_rows(self, log_tab, axis, i, fi, j, fj, rel):
        """``log_tab`` (a main-grid table's logarithm, zenith nodes ``axis``) at cells (i, fi) x
        (j, fj) of directions at azimuth ``rel`` [rad] from the sun: along the rows i and i + 1
        linearly in log(angle from the sun) between the azimuth nodes j and j + 1 (in the
        azimuth where the two angles are equal), then linearly in zenith. (N, K)."""
        cos_zs, sin_zs = self.sun[2], np.sqrt(max(0.0, 1.0 - self.sun[2] ** 2))

        def log_gamma(zr, a):
            c = np.cos(zr) * cos_zs + np.sin(zr) * sin_zs * np.cos(a)
            return np.log(np.maximum(np.arccos(np.clip(c, -1.0, 1.0)), 1e-6))

        rows = []
        for r in (i, i + 1):
            g0, g1, g = log_gamma(axis[r], self.azimuth[j]), log_gamma(axis[r], self.azimuth[j + 1]), log_gamma(axis[r], rel)
            span = np.abs(g1 - g0) > 1e-9
            w = np.clip(np.where(span, (g - g0) / np.where(span, g1 - g0, 1.0), fj), 0.0, 1.0)[:, None]
            rows.append(log_tab[r, j] * (1.0 - w) + log_tab[r, j + 1] * w)
        return rows[0] * (1.0 - fi[:, None]) + rows[1] * fi[:, None]

    def lookup(self, directions) -> np.ndarray:
        """Reduced values (N, K) for unit ``directions`` (N, 3)."""
        d = np.asarray(directions, float).reshape(-1, 3)
        cos_g = d @ self.sun
        zen = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        below = zen >= self.horizon
        out = self._main(d, zen, below)
        in_cap = cos_g > self.cos_cap
        if np.any(in_cap):
            idx = np.nonzero(in_cap)[0]
            dc = d[idx]
            gam = np.arccos(np.clip(cos_g[idx], -1.0, 1.0))
            u = np.clip(np.log(np.maximum(gam, self.cap_min) / self.cap_min) / np.log(self.cap_max / self.cap_min),
                        0.0, 1.0)
            psi = np.arctan2(np.abs(dc @ self.e2), dc @ self.e1)
            i, fi = _cell(self.cap_u, u)
            j, fj = _cell(self.cap_psi, psi)
            b = below[idx]
            cb = self.cap_below
            same = ((cb[i, j] == b) & (cb[i + 1, j] == b) & (cb[i, j + 1] == b) & (cb[i + 1, j + 1] == b))
            same &= (gam >= self.cap_min) & (np.abs(zen[idx] - self.horizon) >= self.horizon_band)
            # near the horizon: the main grid times the interpolated ratio; elsewhere the
            # exact values interpolated in the logarithm (the aureole falls as a power of gamma)
            cp = self.cap_positive
            pos = cp[i, j] & cp[i + 1, j] & cp[i, j + 1] & cp[i + 1, j + 1]
            low = np.abs(zen[idx] - self.horizon) < np.radians(CAP_RATIO_DEG)
            cs = self.cap_split
            split = same & ~low & cs[i, j] & cs[i + 1, j] & cs[i, j + 1] & cs[i + 1, j + 1]
            ref = self._reference(gam[split])
            ok = np.all(ref > 0, axis=-1)
            split[np.nonzero(split)[0][~ok]] = False
            for sel, tab in ((same & low, self.log_ratio), (same & ~low & ~split & pos, self.log_cap)):
                k = idx[sel]
                v = np.exp(_bilinear(tab, i[sel], fi[sel], j[sel], fj[sel]))
                out[k] = self._main(dc[sel], zen[k], below[k], log=True) * v if tab is self.log_ratio else v
            a = (i[split], fi[split], j[split], fj[split])
            out[idx[split]] = (np.exp(_bilinear(self.log_single, *a)) * ref[ok]
                               + np.exp(_bilinear(self.log_rest, *a)))
            same &= low | pos | split
            exact = idx[~same]  # next to the sun, the horizon, or with nodes across the horizon
            if exact.size:
                out[exact] = self._march(d[exact])
                with self._count_lock:  # look-ups may run on several threads
                    self.exact_pixels += int(exact.size)
        return out
