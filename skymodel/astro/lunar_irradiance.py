"""Moonlight above the atmosphere: the ROLO lunar reflectance times the solar spectrum.

Model
    Kieffer & Stone (2005), "The spectral irradiance of the Moon", AJ 129, 2887 (the USGS
    ROLO model). The irradiance of the whole disc on a surface facing the moon is (their eq. 8)

        E_moon(lambda) = A(lambda, g, Phi) * Omega_M * E_sun(lambda) / pi
                         * (384400 km / d_obs)^2 * (1 AU / d_sun-moon)^2

    with A the disk-equivalent reflectance of their eq. 10 (coefficients of their Table 4 in
    ``skymodel/data/sources/moon/rolo_kieffer_stone_2005.csv``; the constants c1..c4 and
    p1..p4 below), Omega_M = 6.4177e-5 sr the disc at 384400 km, and E_sun the solar
    spectrum of :func:`skymodel.sun.solar_irradiance` (ASTM G173 / Gueymard 2004; ROLO was
    built on Wehrli 1985, a few per cent apart). Kieffer & Stone give the model's absolute
    scale as uncertain by 5-10 % and its relative (phase) behaviour as good to about 1 %.

Choices made here (each stated where it is used)
    * The observer's selenographic latitude and longitude (libration, up to about 7-8
      degrees) are set to 0: the c-terms are then 0, which moves ln A by at most about
      0.01-0.02. The sun's selenographic longitude Phi is taken as +g for a waxing moon and
      -g for a waning one (:attr:`skymodel.astro.moon.MoonPosition.sun_selenographic_longitude_deg`).
    * Smoothing in wavelength: the model is tabulated in bands that are independently
      fitted, and neighbouring bands differ by up to 8 % (412.3 and 414.4 nm). skymodel
      evaluates ln A in the 20 bands between 350 and 900 nm outside telluric absorption
      (763.7 nm, the O2 A band, left out) and fits a quadratic in wavelength by least squares;
      the fit's residuals are 4-5 % rms (10 % at 355 nm), well inside the model's absolute
      uncertainty, and give a smooth visible spectrum instead of band-to-band steps.
    * Phase angles: ROLO was fitted between about 1.5 and 97 degrees. Up to
      :data:`ROLO_MAX_PHASE_DEG` the model is used as it is (below 1.5 degrees its opposition
      terms are extrapolated); beyond it, the crescent, the ROLO reflectance at 97 degrees is
      carried on with the ratio of the visual phase law quoted by Krisciunas & Schaefer (1991,
      PASP 103, 1033, eq. 9, after Allen 1973): m(g) = -12.73 + 0.026 |g| + 4e-9 g^4, so the
      result is continuous at 97 degrees.
    * A lunar eclipse is not modelled.

Checks (``tests/test_astro_lunar_irradiance.py``): the V magnitude of the model follows the
Allen phase law; a full moon gives about 1e-6 of the sun's irradiance in V and an
illuminance of 0.2-0.3 lux on a surface facing it above the atmosphere.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from skymodel.colorimetry import K_M, cmf_weights
from skymodel.data import csv_columns
from skymodel.errors import SkymodelInputError, check_array_range
from skymodel.sun import solar_irradiance
from skymodel.wavelengths import as_wavelengths

#: Band-independent ROLO constants (Kieffer & Stone 2005, Table 4): c1..c4 (per degree of
#: the observer's selenographic latitude/longitude) and p1..p4 (degrees).
ROLO_C = (0.00034115, -0.0013425, 0.00095906, 0.00066229)
ROLO_P_DEG = (4.06054, 12.8802, -30.5858, 16.7498)
#: Solid angle of the lunar disc at 384400 km, sr (Kieffer & Stone 2005).
ROLO_DISC_SOLID_ANGLE_SR = 6.4177e-5
#: Earth-moon distance that ROLO is normalised to, km.
ROLO_MOON_DISTANCE_KM = 384_400.0
#: Largest phase angle at which the ROLO model is used as it stands (degrees).
ROLO_MAX_PHASE_DEG = 97.0
#: Bands used in the wavelength fit: 350-900 nm, the O2 A band (763.7 nm) left out.
FIT_RANGE_NM = (350.0, 900.0)
TELLURIC_BANDS_NM = (763.7, 928.4, 939.3, 942.1)

#: V-band zero point: f_lambda of a V = 0 star at the band's effective wavelength, W m^-2 nm^-1
#: (Bessell, Castelli & Plez 1998, A&A 333, 231, Table A2: 363.1e-11 erg cm^-2 s^-1 A^-1 at 545 nm).
V_ZERO_POINT_W_M2_NM = 3.631e-11
V_EFFECTIVE_WAVELENGTH_NM = 545.0

_ROLO_CSV = "sources/moon/rolo_kieffer_stone_2005.csv"


@functools.lru_cache(maxsize=1)
def _rolo_table():
    c = csv_columns(_ROLO_CSV)
    wl = c["wavelength_nm"]
    keep = (wl >= FIT_RANGE_NM[0]) & (wl <= FIT_RANGE_NM[1]) & ~np.isin(wl, TELLURIC_BANDS_NM)
    names = ("a0", "a1", "a2", "a3", "b1", "b2", "b3", "d1", "d2", "d3")
    return wl[keep], np.stack([c[n][keep] for n in names], axis=1)


def allen_phase_law_v_mag(phase_angle_deg) -> np.ndarray:
    """Visual magnitude of the moon at mean distance against phase angle (degrees):
    m = -12.73 + 0.026 |g| + 4e-9 g^4 (Krisciunas & Schaefer 1991, eq. 9, after Allen 1973)."""
    g = np.abs(np.asarray(phase_angle_deg, dtype=float))
    return -12.73 + 0.026 * g + 4.0e-9 * g**4


def rolo_band_log_reflectance(phase_angle_deg, sun_selenographic_longitude_deg) -> tuple[np.ndarray, np.ndarray]:
    """``(band wavelengths nm, ln A)`` of the ROLO model (Kieffer & Stone 2005 eq. 10) in the
    bands the fit uses, for the observer at selenographic (0, 0); ``ln A`` has shape
    ``phase.shape + (n_bands,)``. Phase angles are used as given (no crescent extension)."""
    gd = np.abs(np.asarray(phase_angle_deg, dtype=float))[..., None]
    phi = np.radians(np.asarray(sun_selenographic_longitude_deg, dtype=float))[..., None]
    g = np.radians(gd)
    wl, k = _rolo_table()
    p1, p2, p3, p4 = ROLO_P_DEG
    ln_a = (k[:, 0] + k[:, 1] * g + k[:, 2] * g**2 + k[:, 3] * g**3
            + k[:, 4] * phi + k[:, 5] * phi**3 + k[:, 6] * phi**5
            + k[:, 7] * np.exp(-gd / p1) + k[:, 8] * np.exp(-gd / p2) + k[:, 9] * np.cos((gd - p3) / p4))
    return wl, ln_a


def _smoothed_log_reflectance(wavelengths_nm, phase_angle_deg, sun_lon_deg):
    band_wl, ln_a = rolo_band_log_reflectance(phase_angle_deg, sun_lon_deg)
    x = (band_wl - 600.0) / 100.0
    design = np.stack([np.ones_like(x), x, x * x], axis=1)  # (n_bands, 3)
    coef = np.linalg.lstsq(design, ln_a.reshape(-1, band_wl.size).T, rcond=None)[0]  # (3, m)
    xo = (np.asarray(wavelengths_nm) - 600.0) / 100.0
    out = np.stack([np.ones_like(xo), xo, xo * xo], axis=1) @ coef  # (n_wl, m)
    return out.T.reshape(ln_a.shape[:-1] + (xo.size,))


def lunar_reflectance(wavelengths_nm=None, phase_angle_deg=7.0, sun_selenographic_longitude_deg=None) -> np.ndarray:
    """Disk-equivalent reflectance A of the moon (dimensionless), shape ``phase.shape + (n_wl,)``.

    ``phase_angle_deg`` in [0, 180] (scalar or array). ``sun_selenographic_longitude_deg``
    (-180..180) defaults to ``+phase_angle_deg`` (waxing); pass ``-g`` for a waning moon, or
    :attr:`~skymodel.astro.moon.MoonPosition.sun_selenographic_longitude_deg`. Beyond
    :data:`ROLO_MAX_PHASE_DEG` the value at 97 degrees is scaled by the Allen phase law
    (module docstring)."""
    wl = as_wavelengths(wavelengths_nm)
    g = check_array_range("phase_angle_deg", phase_angle_deg, 0.0, 180.0, "degrees")
    if sun_selenographic_longitude_deg is None:
        lon = g
    else:
        lon = check_array_range("sun_selenographic_longitude_deg", sun_selenographic_longitude_deg, -180.0, 180.0, "degrees")
    try:
        g, lon = np.broadcast_arrays(g, lon)
    except ValueError:
        raise SkymodelInputError("sun_selenographic_longitude_deg", f"shape {np.shape(lon)}",
                                 f"a shape that broadcasts with phase_angle_deg {np.shape(g)}") from None
    g_model = np.minimum(g, ROLO_MAX_PHASE_DEG)
    lon_model = np.sign(lon) * np.minimum(np.abs(lon), ROLO_MAX_PHASE_DEG)
    ln_a = _smoothed_log_reflectance(wl, g_model, lon_model)
    extra = -0.4 * math.log(10.0) * (allen_phase_law_v_mag(g) - allen_phase_law_v_mag(g_model))
    return np.exp(ln_a + extra[..., None])


def lunar_irradiance(wavelengths_nm=None, phase_angle_deg=7.0, *, sun_selenographic_longitude_deg=None,
                     moon_distance_km=ROLO_MOON_DISTANCE_KM, sun_moon_distance_au=1.0) -> np.ndarray:
    """Spectral irradiance of the whole lunar disc above the atmosphere, W m^-2 nm^-1, on a
    surface facing the moon (Kieffer & Stone 2005 eq. 8).

    ``moon_distance_km`` is the observer-moon distance (300000-420000 km; topocentric, e.g.
    :attr:`~skymodel.astro.moon.MoonPosition.distance_km`), ``sun_moon_distance_au`` the
    sun-moon distance (0.9-1.1 AU). Arrays broadcast with the phase angle; the result has
    shape ``broadcast.shape + (n_wl,)``. The solar spectrum is band-averaged on the grid as
    :func:`skymodel.sun.solar_irradiance` does."""
    wl = as_wavelengths(wavelengths_nm)
    d = check_array_range("moon_distance_km", moon_distance_km, 300_000.0, 420_000.0, "km")
    s = check_array_range("sun_moon_distance_au", sun_moon_distance_au, 0.9, 1.1, "AU")
    a = lunar_reflectance(wl, phase_angle_deg, sun_selenographic_longitude_deg)
    scale = (ROLO_DISC_SOLID_ANGLE_SR / math.pi) * (ROLO_MOON_DISTANCE_KM / d) ** 2 / s**2
    return a * np.asarray(scale)[..., None] * solar_irradiance(wl, 1.0)


def moon_irradiance(moon, wavelengths_nm=None) -> np.ndarray:
    """:func:`lunar_irradiance` for a :class:`~skymodel.astro.moon.MoonPosition` (its phase
    angle, sun selenographic longitude, topocentric distance and sun-moon distance)."""
    return lunar_irradiance(wavelengths_nm, moon.phase_angle_deg,
                            sun_selenographic_longitude_deg=moon.sun_selenographic_longitude_deg,
                            moon_distance_km=moon.distance_km, sun_moon_distance_au=moon.sun_moon_distance_au)


def illuminance_lux(irradiance, wavelengths_nm=None) -> np.ndarray:
    """Illuminance (lux) of a spectral irradiance (W m^-2 nm^-1, last axis on the grid):
    K_m * integral(E ybar dlambda) with the CIE 1931 2-degree ybar (:mod:`skymodel.colorimetry`)."""
    wl = as_wavelengths(wavelengths_nm)
    return K_M * (np.asarray(irradiance, dtype=float) @ cmf_weights(wl)[:, 1])


def v_magnitude(irradiance, wavelengths_nm=None) -> np.ndarray:
    """Johnson V magnitude of a spectral irradiance, taken at the V band's effective wavelength
    (545 nm; Bessell, Castelli & Plez 1998 zero point), by linear interpolation on the grid.
    A monochromatic stand-in for the V passband: for smooth spectra such as the moon's and a
    star's the difference from the band integral is a few hundredths of a magnitude."""
    wl = as_wavelengths(wavelengths_nm)
    e = np.asarray(irradiance, dtype=float)
    f = np.apply_along_axis(lambda row: np.interp(V_EFFECTIVE_WAVELENGTH_NM, wl, row), -1, e)
    return -2.5 * np.log10(f / V_ZERO_POINT_W_M2_NM)
