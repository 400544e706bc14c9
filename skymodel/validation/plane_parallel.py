"""An optical profile as homogeneous plane-parallel layers, in the form discrete-ordinates
solvers (DISORT and its kin) take: per layer and wavelength the optical depth, the
single-scattering albedo and the Legendre moments of the mixed phase function.

Each layer is a shell of :meth:`skymodel.optics.profile.OpticalProfile.layered` (the mean of
every coefficient over the layer, so each species keeps its optical depth), and

* optical depth   tau   = (sigma_R + sum_r sigma_a,r + k_O3 + k_a) dz,
* albedo          omega = (sigma_R + sum_r sigma_a,r) / (sigma_R + sum_r sigma_a,r + k_O3 + k_a),
* moments         chi_l = (sigma_R chi_l^R + sum_r sigma_a,r chi_l^a,r) / (sigma_R + sum_r sigma_a,r),

with chi^R the depolarised Rayleigh moments and chi^a,r the moments of aerosol regime r's
phase table (:mod:`skymodel.optics.legendre`). Arrays run from the top layer down (index 0 at the
top of the atmosphere), the order of DISORT's ``DTAUC``/``SSALB``/``PMOM``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymodel.optics.legendre import rayleigh_moments, tabulated_moments
from skymodel.optics.profile import LayeredProfile, OpticalProfile


@dataclass(frozen=True)
class PlaneParallelLayers:
    """Homogeneous layers, top first. Shapes: ``edges_m`` (n_layer + 1,) decreasing from
    the top of the atmosphere to the ground; ``optical_depth`` and
    ``single_scattering_albedo`` (n_layer, n_wl); ``moments`` (n_layer, n_moments + 1, n_wl)
    with moments[:, 0] = 1; ``ground_albedo`` and ``solar_irradiance`` (n_wl,), the latter
    in W m^-2 nm^-1 at the top of the atmosphere."""

    wavelengths_nm: np.ndarray
    edges_m: np.ndarray
    optical_depth: np.ndarray
    single_scattering_albedo: np.ndarray
    moments: np.ndarray
    ground_albedo: np.ndarray
    solar_irradiance: np.ndarray

    @property
    def n_layers(self) -> int:
        return int(self.optical_depth.shape[0])

    @property
    def total_optical_depth(self) -> np.ndarray:
        return self.optical_depth.sum(axis=0)


def plane_parallel_layers(profile, n_layers: int | None = 100, edges_m=None,
                          n_moments: int = 256) -> PlaneParallelLayers:
    """Layers of ``profile`` (an :class:`OpticalProfile`, split with ``n_layers`` or
    ``edges_m`` as :meth:`OpticalProfile.layered` does, or a :class:`LayeredProfile` used
    as it is) with phase moments up to ``n_moments``."""
    if isinstance(profile, OpticalProfile):
        lay = profile.layered(n_layers=None if edges_m is not None else n_layers, edges_m=edges_m)
    elif isinstance(profile, LayeredProfile):
        lay = profile
    else:
        raise TypeError("profile must be an OpticalProfile or a LayeredProfile")
    dz = np.diff(lay.edges_m)[:, None]  # (n_layer, 1) metres
    ray = lay.rayleigh_scattering * dz  # optical depths, (n_layer, n_wl)
    aer = lay.aerosol_scattering_by_regime * dz[None]  # (R, n_layer, n_wl)
    absorption = (lay.ozone_absorption + lay.aerosol_absorption) * dz
    scat = ray + aer.sum(axis=0)
    tau = scat + absorption
    omega = np.divide(scat, tau, out=np.zeros_like(tau), where=tau > 0)
    chi_r = rayleigh_moments(lay.rayleigh_depolarization, n_moments)  # (L+1, W)
    mom = ray[:, None, :] * chi_r[None]
    if np.any(aer > 0):
        # (L+1, R, W): each regime's table, angles first
        chi_a = tabulated_moments(lay.aerosol_phase_angles_deg, np.moveaxis(lay.aerosol_phase, 1, 0), n_moments)
        mom = mom + np.einsum("rnw,lrw->nlw", aer, chi_a)
    safe = np.where(scat > 0, scat, 1.0)[:, None, :]
    mom = np.where(scat[:, None, :] > 0, mom / safe, chi_r[None])
    return PlaneParallelLayers(
        wavelengths_nm=np.asarray(lay.wavelengths_nm, float),
        edges_m=lay.edges_m[::-1].copy(),
        optical_depth=tau[::-1].copy(),
        single_scattering_albedo=omega[::-1].copy(),
        moments=mom[::-1].copy(),
        ground_albedo=np.asarray(lay.ground_albedo, float),
        solar_irradiance=np.asarray(lay.solar_irradiance, float),
    )
