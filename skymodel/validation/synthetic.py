"""Synthetic optical profiles built directly (no data tables): exponential Rayleigh,
an exponential aerosol with a Henyey-Greenstein phase table, a Gaussian ozone layer.
Used by the tests and the validation benchmarks to check the renderers independently of
the data modules."""

import numpy as np

from skymodel.optics import rayleigh
from skymodel.geometry import altitude_grid
from skymodel.optics.profile import OpticalProfile


def hg_table(angles_deg, g, n_wl):
    mu = np.cos(np.radians(angles_deg))
    p = (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * mu) ** 1.5)
    return np.repeat(p[:, None], n_wl, axis=1)


def synthetic_profile(wavelengths=(450.0, 550.0, 650.0), aod550=0.2, g=0.7, ssa=0.95, albedo=0.2,
                      ozone_tau550=0.03, aerosol_scale_m=1200.0, n_alt=401, e_sun=None):
    wl = np.asarray(wavelengths, dtype=float)
    h = altitude_grid(n_alt)
    ray = rayleigh.scattering_coefficient(h, wl)
    aer_shape = np.exp(-h / aerosol_scale_m) / aerosol_scale_m  # integrates to ~1
    aer_ext = aod550 * aer_shape[:, None] * (wl / 550.0) ** -1.3
    o3_shape = np.exp(-0.5 * ((h - 25e3) / 5e3) ** 2) / (5e3 * np.sqrt(2 * np.pi))
    o3_spec = np.exp(-0.5 * ((wl - 600.0) / 60.0) ** 2)
    o3 = ozone_tau550 * o3_shape[:, None] * o3_spec[None, :] / np.exp(-0.5 * ((550 - 600) / 60.0) ** 2)
    angles = np.concatenate([np.linspace(0, 5, 51), np.linspace(5.5, 180, 350)])
    phase = np.stack([hg_table(angles, g, wl.size), hg_table(angles, 0.6, wl.size)])
    aer_sca = np.stack([aer_ext * ssa, np.zeros_like(aer_ext)])
    return OpticalProfile(
        wavelengths_nm=wl, rayleigh_depolarization=rayleigh.depolarization_factor(wl),
        aerosol_phase_angles_deg=angles, aerosol_phase=phase, ground_albedo=np.full(wl.size, albedo),
        solar_irradiance=np.ones(wl.size) * 1.8 if e_sun is None else np.asarray(e_sun, float),
        altitudes_m=h, rayleigh_scattering=ray, ozone_absorption=o3,
        aerosol_scattering_by_regime=aer_sca, aerosol_absorption=aer_ext * (1 - ssa),
    )
