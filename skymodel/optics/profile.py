"""Optical properties of the atmosphere per height and wavelength: the data contract
between the physics core, the renderers and the Blender add-on.

Units: altitudes in metres above the ground, wavelengths in nanometres, scattering and
absorption coefficients in per-metre (m^-1), phase functions in sr^-1 normalised so that
their integral over the full sphere is 1, irradiance in W m^-2 nm^-1.

Two views of the same medium:

* :class:`OpticalProfile` — the smooth profile: coefficients on an altitude grid,
  linearly interpolated in between (and zero above the top of the atmosphere).
* :class:`LayeredProfile` — piecewise-constant shells (the Cycles volume shells): layer
  edges and the per-layer mean of every coefficient (so each layer keeps the optical
  depth of the smooth profile across it).

Both offer :meth:`sample`, returning a :class:`MediumSample` at arbitrary altitudes,
so a renderer can march either one with the same code.

Aerosols come in *regimes* (0 = troposphere, 1 = stratosphere): each has its own
mixture of components and hence its own phase table; at any altitude the aerosol phase
function is the scattering-weighted mean of the regimes' tables.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from skymodel.errors import SkymodelInputError
from skymodel.geometry import EARTH_RADIUS_M, TOA_ALTITUDE_M
from skymodel.numerics import trapezoid


@dataclass(frozen=True)
class MediumSample:
    """Coefficients (m^-1) at a set of points; every array is shaped ``points + (n_wl,)``
    except ``aerosol_scattering_by_regime`` which is ``(n_regime,) + points + (n_wl,)``."""

    rayleigh_scattering: np.ndarray
    ozone_absorption: np.ndarray
    aerosol_scattering_by_regime: np.ndarray
    aerosol_absorption: np.ndarray

    @property
    def aerosol_scattering(self) -> np.ndarray:
        return self.aerosol_scattering_by_regime.sum(axis=0)

    @property
    def scattering(self) -> np.ndarray:
        return self.rayleigh_scattering + self.aerosol_scattering

    @property
    def extinction(self) -> np.ndarray:
        return self.scattering + self.ozone_absorption + self.aerosol_absorption


@dataclass(frozen=True)
class _MediumBase:
    wavelengths_nm: np.ndarray  # (n_wl,)
    rayleigh_depolarization: np.ndarray  # (n_wl,) depolarisation factor rho_n (Bates 1984)
    aerosol_phase_angles_deg: np.ndarray  # (n_angle,) scattering angle grid, 0..180
    aerosol_phase: np.ndarray  # (n_regime, n_angle, n_wl) sr^-1, normalised over 4 pi
    ground_albedo: np.ndarray  # (n_wl,) Lambertian albedo
    solar_irradiance: np.ndarray  # (n_wl,) top-of-atmosphere solar irradiance, W m^-2 nm^-1
    planet_radius_m: float = EARTH_RADIUS_M
    top_altitude_m: float = TOA_ALTITUDE_M
    metadata: dict = field(default_factory=dict)

    @property
    def n_wavelengths(self) -> int:
        return int(self.wavelengths_nm.size)

    @property
    def rayleigh_gamma(self) -> np.ndarray:
        """Chandrasekhar's gamma = rho / (2 - rho) per wavelength."""
        rho = self.rayleigh_depolarization
        return rho / (2.0 - rho)

    def rayleigh_phase(self, cos_theta: np.ndarray) -> np.ndarray:
        """Rayleigh phase function with depolarisation (Chandrasekhar 1950), sr^-1.

        p(theta) = 3 / (16 pi) / (1 + 2 gamma) * ((1 + 3 gamma) + (1 - gamma) cos^2 theta);
        shape ``cos_theta.shape + (n_wl,)``.
        """
        g = self.rayleigh_gamma
        c2 = np.asarray(cos_theta, dtype=float)[..., None] ** 2
        return 3.0 / (16.0 * np.pi) / (1.0 + 2.0 * g) * ((1.0 + 3.0 * g) + (1.0 - g) * c2)

    def aerosol_phase_at(self, cos_theta: np.ndarray) -> np.ndarray:
        """Each regime's aerosol phase function at ``cos_theta``, sr^-1, linear in angle;
        shape ``(n_regime,) + cos_theta.shape + (n_wl,)``."""
        theta = np.degrees(np.arccos(np.clip(np.asarray(cos_theta, dtype=float), -1.0, 1.0)))
        grid = self.aerosol_phase_angles_deg
        idx = np.clip(np.searchsorted(grid, theta, side="right") - 1, 0, grid.size - 2)
        t = ((theta - grid[idx]) / (grid[idx + 1] - grid[idx]))[..., None]
        tab = self.aerosol_phase  # (R, A, W)
        return tab[:, idx, :] * (1.0 - t) + tab[:, idx + 1, :] * t


@dataclass(frozen=True)
class OpticalProfile(_MediumBase):
    """Smooth profile: coefficients on ``altitudes_m`` (n_alt,), each (n_alt, n_wl)."""

    altitudes_m: np.ndarray = None
    rayleigh_scattering: np.ndarray = None
    ozone_absorption: np.ndarray = None
    aerosol_scattering_by_regime: np.ndarray = None  # (n_regime, n_alt, n_wl)
    aerosol_absorption: np.ndarray = None

    @property
    def aerosol_scattering(self) -> np.ndarray:
        return self.aerosol_scattering_by_regime.sum(axis=0)

    @property
    def extinction(self) -> np.ndarray:
        return self.rayleigh_scattering + self.ozone_absorption + self.aerosol_scattering + self.aerosol_absorption

    def vertical_optical_depth(self, coefficient: np.ndarray) -> np.ndarray:
        """Trapezoidal column integral of a (n_alt, n_wl) coefficient from ground to top."""
        return trapezoid(coefficient, self.altitudes_m, axis=0)

    def sample(self, altitudes_m) -> MediumSample:
        """Linear interpolation of every coefficient at ``altitudes_m`` (any shape);
        zero above the top and clamped to the ground value below 0."""
        h = np.asarray(altitudes_m, dtype=float)
        grid = self.altitudes_m
        hc = np.clip(h, grid[0], grid[-1])
        idx = np.clip(np.searchsorted(grid, hc, side="right") - 1, 0, grid.size - 2)
        t = ((hc - grid[idx]) / (grid[idx + 1] - grid[idx]))[..., None]
        inside = (h <= self.top_altitude_m)[..., None]

        def lerp(a):
            return np.where(inside, a[idx] * (1.0 - t) + a[idx + 1] * t, 0.0)

        aer = np.stack([lerp(a) for a in self.aerosol_scattering_by_regime])
        return MediumSample(lerp(self.rayleigh_scattering), lerp(self.ozone_absorption), aer, lerp(self.aerosol_absorption))

    def layered(self, n_layers: int | None = None, edges_m=None) -> "LayeredProfile":
        """Piecewise-constant shells. Give ``edges_m`` (increasing, from 0 to the top) or
        ``n_layers``, in which case edges are spaced evenly in the Rayleigh optical depth
        (so layers are thin near the ground where the air is dense).
        Each layer's coefficient is the mean of the smooth profile over the layer, which
        preserves the vertical optical depth of every species."""
        if edges_m is None:
            if n_layers is None or int(n_layers) < 1:
                raise SkymodelInputError("n_layers", n_layers, "an integer >= 1")
            edges_m = layer_edges_by_optical_depth(self, int(n_layers))
        edges = np.asarray(edges_m, dtype=float)
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or edges[0] < 0:
            raise SkymodelInputError("edges_m", edges_m, "increasing altitudes in metres starting at >= 0")
        # cumulative integrals on a fine grid, then differences over each layer
        fine = np.union1d(self.altitudes_m, edges)
        fine = fine[(fine >= edges[0]) & (fine <= edges[-1])]
        s = self.sample(fine)
        thick = np.diff(edges)[:, None]

        def layer_mean(a):  # a: (n_fine, n_wl)
            cum = np.concatenate([np.zeros((1, a.shape[-1])), np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(fine)[:, None], axis=0)])
            at_edges = cum[np.searchsorted(fine, edges)]
            return np.diff(at_edges, axis=0) / thick

        return LayeredProfile(
            wavelengths_nm=self.wavelengths_nm,
            rayleigh_depolarization=self.rayleigh_depolarization,
            aerosol_phase_angles_deg=self.aerosol_phase_angles_deg,
            aerosol_phase=self.aerosol_phase,
            ground_albedo=self.ground_albedo,
            solar_irradiance=self.solar_irradiance,
            planet_radius_m=self.planet_radius_m,
            top_altitude_m=float(edges[-1]),
            metadata=dict(self.metadata),
            edges_m=edges,
            rayleigh_scattering=layer_mean(s.rayleigh_scattering),
            ozone_absorption=layer_mean(s.ozone_absorption),
            aerosol_scattering_by_regime=np.stack([layer_mean(a) for a in s.aerosol_scattering_by_regime]),
            aerosol_absorption=layer_mean(s.aerosol_absorption),
        )

    def with_(self, **changes) -> "OpticalProfile":
        """A copy with some fields replaced (e.g. ``with_(ground_albedo=...)``)."""
        return replace(self, **changes)


@dataclass(frozen=True)
class LayeredProfile(_MediumBase):
    """Piecewise-constant shells: ``edges_m`` (n_layer + 1,), coefficients (n_layer, n_wl)."""

    edges_m: np.ndarray = None
    rayleigh_scattering: np.ndarray = None
    ozone_absorption: np.ndarray = None
    aerosol_scattering_by_regime: np.ndarray = None  # (n_regime, n_layer, n_wl)
    aerosol_absorption: np.ndarray = None

    @property
    def n_layers(self) -> int:
        return int(self.edges_m.size - 1)

    @property
    def aerosol_scattering(self) -> np.ndarray:
        return self.aerosol_scattering_by_regime.sum(axis=0)

    @property
    def extinction(self) -> np.ndarray:
        return self.rayleigh_scattering + self.ozone_absorption + self.aerosol_scattering + self.aerosol_absorption

    def vertical_optical_depth(self, coefficient: np.ndarray) -> np.ndarray:
        return (coefficient * np.diff(self.edges_m)[:, None]).sum(axis=0)

    def layer_index(self, altitudes_m) -> np.ndarray:
        """Index of the layer holding each altitude; -1 outside [edges[0], edges[-1]]."""
        h = np.asarray(altitudes_m, dtype=float)
        idx = np.searchsorted(self.edges_m, h, side="right") - 1
        idx = np.where(h == self.edges_m[-1], self.n_layers - 1, idx)
        return np.where((h < self.edges_m[0]) | (h > self.edges_m[-1]), -1, idx)

    def sample(self, altitudes_m) -> MediumSample:
        idx = self.layer_index(altitudes_m)
        inside = (idx >= 0)[..., None]
        j = np.clip(idx, 0, self.n_layers - 1)

        def pick(a):
            return np.where(inside, a[j], 0.0)

        aer = np.stack([pick(a) for a in self.aerosol_scattering_by_regime])
        return MediumSample(pick(self.rayleigh_scattering), pick(self.ozone_absorption), aer, pick(self.aerosol_absorption))


def layer_edges_by_optical_depth(profile: OpticalProfile, n_layers: int) -> np.ndarray:
    """Layer edges (m) with equal shares of the 550 nm (or middle-wavelength) total
    extinction optical depth, top edge at the top of the atmosphere."""
    wl = profile.wavelengths_nm
    j = int(np.argmin(np.abs(wl - 550.0)))
    ext = profile.extinction[:, j]
    h = profile.altitudes_m
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (ext[1:] + ext[:-1]) * np.diff(h))])
    targets = np.linspace(0.0, cum[-1], n_layers + 1)
    edges = np.interp(targets, cum, h)
    edges[0], edges[-1] = h[0], h[-1]
    # guard against duplicate edges where the extinction is ~0
    return np.maximum.accumulate(edges + np.arange(n_layers + 1) * 1e-6)
