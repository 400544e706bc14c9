"""Rayleigh scattering by air molecules.

Cross section after Bucholtz (1995, Appl. Opt. 34, 2765, Eq. 2):

    sigma(lambda) = 24 pi^3 (n_s^2 - 1)^2 / (lambda^4 N_s^2 (n_s^2 + 2)^2) * F_K(lambda)

with

* n_s — refractive index of standard air (15 degC, 1013.25 hPa, 300 ppm CO2) from Peck &
  Reeder (1972, JOSA 62, 958, Eq. 2, sigma = 1/lambda in um^-1):
  (n_s - 1) 1e8 = 8060.51 + 2480990 / (132.274 - sigma^2) + 17455.7 / (39.32957 - sigma^2),
  corrected to ``co2_ppm`` with Edlén's factor 1 + 0.54 (C - 0.0003) (as Bodhaine et al.
  1999, Eq. 19);
* N_s — molecular number density of that standard air, 2.546899e25 m^-3 (Bodhaine et al.
  1999; 288.15 K, 1013.25 hPa; the product (n_s^2-1)^2/N_s^2 is what matters and scales
  with the density at which n_s is given);
* F_K — the King correction factor (6 + 3 rho)/(6 - 7 rho) of air, the volume-weighted
  mean of the King factors of N2, O2, Ar and CO2 from Bates (1984, Planet. Space Sci. 32,
  785) (lambda in um):
  F(N2) = 1.034 + 3.17e-4 / lambda^2,
  F(O2) = 1.096 + 1.385e-3 / lambda^2 + 1.448e-4 / lambda^4,
  F(Ar) = 1.00, F(CO2) = 1.15,
  with volume fractions 78.084 %, 20.946 %, 0.934 % and ``co2_ppm``.

The depolarisation factor rho = 6 (F - 1) / (3 + 7 F) feeds Chandrasekhar's phase
function p = 3 / (16 pi (1 + 2 gamma)) ((1 + 3 gamma) + (1 - gamma) cos^2 theta) with
gamma = rho / (2 - rho) (Chandrasekhar 1950; Bucholtz 1995 Eq. 12), implemented in
:meth:`skymodel.optics.profile.OpticalProfile.rayleigh_phase`.

The scattering coefficient at altitude z is sigma(lambda) N(z), with N(z) from the U.S.
Standard Atmosphere 1976 (:mod:`skymodel.optics.standard_atmosphere`).
"""

from __future__ import annotations

import numpy as np

from skymodel.optics import standard_atmosphere
from skymodel.wavelengths import as_wavelengths

#: Number density of standard air (288.15 K, 1013.25 hPa), m^-3 (Bodhaine et al. 1999).
N_STANDARD_AIR = 2.546899e25
#: Default CO2 volume mixing ratio, ppm (Bodhaine et al. 1999 use 360 ppm for their tables).
DEFAULT_CO2_PPM = 360.0


def refractive_index_standard_air(wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Refractive index n_s of standard dry air (Peck & Reeder 1972 with Edlén's CO2 term)."""
    wl_um = np.asarray(wavelengths_nm, dtype=float) / 1000.0
    s2 = (1.0 / wl_um) ** 2
    n300_minus_1 = (8060.51 + 2480990.0 / (132.274 - s2) + 17455.7 / (39.32957 - s2)) * 1e-8
    return 1.0 + n300_minus_1 * (1.0 + 0.54 * (co2_ppm * 1e-6 - 0.0003))


def king_factor(wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """King correction factor F_K of air (Bates 1984), concentration-weighted."""
    wl_um = np.asarray(wavelengths_nm, dtype=float) / 1000.0
    f_n2 = 1.034 + 3.17e-4 / wl_um**2
    f_o2 = 1.096 + 1.385e-3 / wl_um**2 + 1.448e-4 / wl_um**4
    c_co2 = co2_ppm * 1e-4  # percent
    weights = np.array([78.084, 20.946, 0.934, c_co2])
    return (weights[0] * f_n2 + weights[1] * f_o2 + weights[2] * 1.00 + weights[3] * 1.15) / weights.sum()


def depolarization_factor(wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Depolarisation factor rho_n = 6 (F_K - 1) / (3 + 7 F_K)."""
    f = king_factor(wavelengths_nm, co2_ppm)
    return 6.0 * (f - 1.0) / (3.0 + 7.0 * f)


def cross_section(wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Rayleigh scattering cross section per molecule, m^2 (Bucholtz 1995 Eq. 2)."""
    wl_m = as_wavelengths(wavelengths_nm) * 1e-9
    n = refractive_index_standard_air(wl_m * 1e9, co2_ppm)
    n2 = n * n
    return (24.0 * np.pi**3 * (n2 - 1.0) ** 2 / (wl_m**4 * N_STANDARD_AIR**2 * (n2 + 2.0) ** 2)
            * king_factor(wl_m * 1e9, co2_ppm))


def scattering_coefficient(altitudes_m, wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Rayleigh scattering coefficient, m^-1, shaped (n_alt, n_wl)."""
    n_air = standard_atmosphere.number_density(altitudes_m)
    return np.asarray(n_air)[..., None] * cross_section(wavelengths_nm, co2_ppm)


def optical_depth(wavelengths_nm, co2_ppm: float = DEFAULT_CO2_PPM, altitudes_m=None) -> np.ndarray:
    """Vertical Rayleigh optical depth of the standard atmosphere from the ground to 100 km."""
    from skymodel.geometry import altitude_grid
    from skymodel.numerics import trapezoid

    h = altitude_grid() if altitudes_m is None else np.asarray(altitudes_m, dtype=float)
    return trapezoid(scattering_coefficient(h, wavelengths_nm, co2_ppm), h, axis=0)
