"""The natural night sky of a dark site: airglow, zodiacal light and unresolved starlight.

Zenith brightness
    Benn & Ellison (1998), "Brightness of the night sky over La Palma", New Astronomy
    Reviews 42, 503 (La Palma Technical Note 115): the darkest moonless sky at the zenith,
    near solar minimum and away from the Galaxy and the ecliptic, is U 22.0, B 22.7, V 21.9,
    R 21.0, I 20.0 mag/arcsec^2 (:data:`DARK_SKY_ZENITH_MAG_ARCSEC2`). Krisciunas & Schaefer
    (1991, PASP 103, 1033) adopt 21.587 mag/arcsec^2 in V (79 nL) at Mauna Kea. Benn &
    Ellison find the sky 0.4 mag brighter at solar maximum and 0.4 mag brighter at low
    ecliptic latitude; the zenith V is therefore a parameter (``zenith_v_mag``) and the
    other bands keep their published offsets from V.

Spectrum
    Each band's surface brightness is turned into spectral radiance at the band's effective
    wavelength with the zero points of Bessell, Castelli & Plez (1998, A&A 333, 231, Table A2;
    U 366, B 438, V 545, R 641, I 798 nm), and the spectrum between them is interpolated
    linearly in log radiance. The airglow's emission lines (O I 557.7 and 630.0 nm, Na D
    589 nm, OH bands in the red) are thereby spread over their broad bands: the result has
    the right colour and brightness per band, not the line spectrum.

Zenith angle
    :func:`van_rhijn_factor`: the emitting layer (airglow, about 90-100 km) is seen through a
    longer path toward the horizon, X = (1 - 0.96 sin^2 Z)^(-1/2) (Krisciunas & Schaefer 1991
    eq. 3; Garstang's form of the van Rhijn factor). :func:`dark_sky_radiance` is their eq. 2,
    B(Z) = B_zen X 10^(-0.4 k (X - 1)), with the extinction either as their grey k or as the
    ratio T(Z)/T(0) of the caller's own line-of-sight transmittance.
"""

from __future__ import annotations

import numpy as np

from skymodel.errors import SkymodelInputError, check_array_range
from skymodel.wavelengths import as_wavelengths

#: Darkest zenith sky at La Palma, mag/arcsec^2 (Benn & Ellison 1998).
DARK_SKY_ZENITH_MAG_ARCSEC2 = {"U": 22.0, "B": 22.7, "V": 21.9, "R": 21.0, "I": 20.0}
#: Effective wavelengths (nm) and f_lambda zero points (W m^-2 nm^-1) of the Johnson-Cousins
#: bands (Bessell, Castelli & Plez 1998, Table A2).
BAND_EFFECTIVE_WAVELENGTH_NM = {"U": 366.0, "B": 438.0, "V": 545.0, "R": 641.0, "I": 798.0}
BAND_ZERO_POINT_W_M2_NM = {"U": 4.175e-11, "B": 6.32e-11, "V": 3.631e-11, "R": 2.177e-11, "I": 1.126e-11}
#: Square arcseconds in a steradian.
ARCSEC2_PER_SR = (180.0 / np.pi * 3600.0) ** 2
#: Krisciunas & Schaefer's (1991) V extinction at Mauna Kea, mag per airmass.
KS91_EXTINCTION_V = 0.172
#: Zenith V accepted (mag/arcsec^2): from a bright suburban sky to below the darkest sites.
ZENITH_V_RANGE = (16.0, 23.0)


def surface_brightness_to_radiance(mag_arcsec2, band: str = "V"):
    """Spectral radiance (W m^-2 sr^-1 nm^-1) at the band's effective wavelength of a surface
    brightness in mag/arcsec^2: zero point * 10^(-0.4 m) * arcsec^2 per sr."""
    if band not in BAND_ZERO_POINT_W_M2_NM:
        raise SkymodelInputError("band", band, "one of " + ", ".join(BAND_ZERO_POINT_W_M2_NM))
    m = np.asarray(mag_arcsec2, dtype=float)
    return BAND_ZERO_POINT_W_M2_NM[band] * 10.0 ** (-0.4 * m) * ARCSEC2_PER_SR


def radiance_to_surface_brightness(radiance, band: str = "V"):
    """Inverse of :func:`surface_brightness_to_radiance` (mag/arcsec^2)."""
    if band not in BAND_ZERO_POINT_W_M2_NM:
        raise SkymodelInputError("band", band, "one of " + ", ".join(BAND_ZERO_POINT_W_M2_NM))
    return -2.5 * np.log10(np.asarray(radiance, dtype=float) / (BAND_ZERO_POINT_W_M2_NM[band] * ARCSEC2_PER_SR))


def dark_sky_zenith_radiance(wavelengths_nm=None, zenith_v_mag: float = DARK_SKY_ZENITH_MAG_ARCSEC2["V"]) -> np.ndarray:
    """Spectral radiance (W m^-2 sr^-1 nm^-1) of the moonless zenith sky at a dark site, as
    measured from the ground (module docstring), on the wavelength grid (380-780 nm)."""
    wl = as_wavelengths(wavelengths_nm)
    v = float(check_array_range("zenith_v_mag", zenith_v_mag, *ZENITH_V_RANGE, "mag/arcsec^2"))
    bands = ("U", "B", "V", "R", "I")
    shift = v - DARK_SKY_ZENITH_MAG_ARCSEC2["V"]
    x = np.array([BAND_EFFECTIVE_WAVELENGTH_NM[b] for b in bands])
    logl = np.log(np.array([surface_brightness_to_radiance(DARK_SKY_ZENITH_MAG_ARCSEC2[b] + shift, b) for b in bands]))
    return np.exp(np.interp(wl, x, logl))


def van_rhijn_factor(zenith_deg) -> np.ndarray:
    """X = (1 - 0.96 sin^2 Z)^(-1/2) (Krisciunas & Schaefer 1991 eq. 3): 1 at the zenith, 5 at the horizon."""
    z = np.radians(check_array_range("zenith_deg", zenith_deg, 0.0, 90.0, "degrees"))
    return (1.0 - 0.96 * np.sin(z) ** 2) ** -0.5


def dark_sky_radiance(wavelengths_nm=None, zenith_deg=0.0, *, zenith_v_mag: float = DARK_SKY_ZENITH_MAG_ARCSEC2["V"],
                      transmittance_ratio=None, extinction_mag_per_airmass: float = KS91_EXTINCTION_V) -> np.ndarray:
    """Moonless night-sky radiance seen from the ground at zenith angle ``zenith_deg`` (0-90),
    W m^-2 sr^-1 nm^-1, shape ``zenith.shape + (n_wl,)``.

    Krisciunas & Schaefer (1991) eq. 2: the zenith spectrum times the van Rhijn factor X,
    dimmed by the extinction between the zenith and Z. ``transmittance_ratio``: None uses
    their grey form 10^(-0.4 k (X - 1)) with ``extinction_mag_per_airmass`` k (default their
    0.172); otherwise an array broadcastable to ``zenith.shape + (n_wl,)`` holding T(Z)/T(0)
    of the caller's atmosphere (the ratio of the direct transmittances along the line of
    sight and at the zenith), so that a renderer dims the glow with the same atmosphere that
    lights the rest of its sky."""
    wl = as_wavelengths(wavelengths_nm)
    x = van_rhijn_factor(zenith_deg)[..., None]
    base = dark_sky_zenith_radiance(wl, zenith_v_mag)
    if transmittance_ratio is None:
        k = float(check_array_range("extinction_mag_per_airmass", extinction_mag_per_airmass, 0.0, 2.0, "mag"))
        ratio = 10.0 ** (-0.4 * k * (x - 1.0))
    else:
        ratio = np.asarray(transmittance_ratio, dtype=float)
        if not np.all(np.isfinite(ratio)) or np.any(ratio < 0):
            raise SkymodelInputError("transmittance_ratio", "negative or non-finite values", "finite values >= 0")
    return base * x * ratio
