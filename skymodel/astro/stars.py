"""The naked-eye stars: catalogue, place in the sky, spectrum, and point sources in an image.

Catalogue
    :func:`catalogue` reads ``skymodel/data/generated/bright_stars_xhip.csv``: the 8874 stars
    of XHIP (Anderson & Francis 2012, the Hipparcos new reduction with compiled photometry)
    with V <= 6.5, Hipparcos number, J2000 right ascension and declination, V and B-V,
    extracted from the npm package d3-celestial 0.7.35 (BSD-3-Clause) by
    ``make_bright_stars.py`` beside it. Proper motion is not carried: a star moves by
    |mu| * |year - 2000|, below 1" per year for all but a few dozen of these stars (Sirius
    1.3"/yr, 0.01 degrees by 2026; the fastest naked-eye stars, 61 Cygni and alpha Centauri,
    4-5"/yr, 0.03-0.04 degrees by 2026).

Place
    :func:`star_positions` takes the J2000 mean places to the apparent place of the date:
    precession (IAU 1976, Lieske et al. 1977: zeta, z, theta as in Meeus eq. 21.3), nutation
    (the four largest terms of Meeus ch. 22, as :mod:`skymodel.sun`) and annual aberration
    (20.49552" toward the Earth's velocity, a circular orbit: the neglected eccentricity term
    is below 0.35"), then to topocentric elevation and azimuth with Greenwich apparent sidereal
    time (Meeus eq. 12.4, UT1 ~ UTC); stellar parallax (below 0.8") is neglected; refraction is
    optional (:func:`skymodel.sun.refraction_correction`). Checked against skyfield with JPL
    DE421 (``tests/test_astro_stars.py``).

Spectrum
    :func:`star_irradiance`: a blackbody at the temperature of Ballesteros (2012, EPL 97,
    34008), T = 4600 K (1 / (0.92 (B-V) + 1.7) + 1 / (0.92 (B-V) + 0.62)), scaled so that its
    irradiance at 545 nm is that of a star of the catalogue's V magnitude (the V zero point of
    Bessell, Castelli & Plez 1998: 3.631e-11 W m^-2 nm^-1 at V = 0). A blackbody has no
    absorption lines and no Balmer jump; for the colour of a point of light that is enough.
    The 4 stars without a B-V get :data:`DEFAULT_B_V`.

Point sources in an equirectangular image
    :func:`splat_stars` adds each star's irradiance E (W m^-2 nm^-1, optionally dimmed by a
    transmittance function of zenith angle) to an equirectangular radiance image as radiance
    E w_i / Omega_i over the four pixels around its projected position (bilinear weights
    w_i summing to 1, Omega_i the pixel's solid angle), so that sum(L Omega) over the image
    equals the sum of E exactly and a star moving across the image changes pixels smoothly.
    The image conventions are those of :class:`skymodel.render.cameras.EquirectangularCamera`
    (zenith at the top row, azimuth increasing to the right, the centre line looking toward
    ``center_azimuth_deg``; default 90 as the environment maps of
    :mod:`skymodel.render.environment`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from skymodel.astro.lunar_irradiance import V_EFFECTIVE_WAVELENGTH_NM, V_ZERO_POINT_W_M2_NM
from skymodel.data import csv_columns
from skymodel.errors import SkymodelInputError, check_array_range
from skymodel.sun import (
    STANDARD_PRESSURE_HPA,
    STANDARD_TEMPERATURE_C,
    as_utc_datetime64,
    nutation,
    refraction_correction,
    solar_position,
)
from skymodel.wavelengths import as_wavelengths

_CATALOGUE_CSV = "generated/bright_stars_xhip.csv"
#: B-V given to catalogue stars that have none (the sun's, 0.65).
DEFAULT_B_V = 0.65
#: Faintest V magnitude in the shipped catalogue.
CATALOGUE_LIMIT_V = 6.5
#: Constant of annual aberration, arcseconds.
ABERRATION_ARCSEC = 20.49552
_J2000 = np.datetime64("2000-01-01T12:00:00", "us")
_US_PER_DAY = 86_400e6
# Planck's law constants (CODATA 2018): 2 h c^2 (W m^2 sr^-1) and h c / k (m K).
_C1 = 2.0 * 6.62607015e-34 * 299792458.0**2
_C2 = 6.62607015e-34 * 299792458.0 / 1.380649e-23


@dataclass(frozen=True)
class StarCatalogue:
    """The catalogue as arrays (one entry per star)."""

    hip: np.ndarray  #: Hipparcos number
    ra_deg: np.ndarray  #: J2000 right ascension, degrees
    dec_deg: np.ndarray  #: J2000 declination, degrees
    v_mag: np.ndarray  #: Johnson V magnitude
    b_v: np.ndarray  #: B-V colour index (DEFAULT_B_V where the source has none)

    def __len__(self) -> int:
        return int(self.hip.size)

    def index_of(self, hip: int) -> int:
        """Row of the star with Hipparcos number ``hip`` (SkymodelInputError if absent)."""
        rows = np.flatnonzero(self.hip == hip)
        if rows.size == 0:
            raise SkymodelInputError("hip", hip, "a Hipparcos number of a star in the catalogue (V <= 6.5)")
        return int(rows[0])


@functools.lru_cache(maxsize=1)
def catalogue() -> StarCatalogue:
    """The shipped catalogue (module docstring), read once."""
    c = csv_columns(_CATALOGUE_CSV)
    bv = np.where(np.isfinite(c["b_v"]), c["b_v"], DEFAULT_B_V)
    return StarCatalogue(hip=c["hip"].astype(np.int64), ra_deg=c["ra_deg"], dec_deg=c["dec_deg"],
                         v_mag=c["v_mag"], b_v=bv)


# ----------------------------------------------------------------------------- place


def _rot(axis: int, angle):
    c, s = np.cos(angle), np.sin(angle)
    m = np.zeros(np.shape(angle) + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[..., axis, axis] = 1.0
    m[..., i, i] = c
    m[..., j, j] = c
    m[..., i, j] = s
    m[..., j, i] = -s
    return m


@dataclass(frozen=True)
class StarPlaces:
    """Stars seen from one place at one time; arrays of shape (n_stars,), degrees."""

    elevation_deg: np.ndarray  #: topocentric elevation (apparent if refraction was asked for)
    azimuth_deg: np.ndarray  #: clockwise from north, [0, 360)
    right_ascension_deg: np.ndarray  #: apparent right ascension of the date
    declination_deg: np.ndarray  #: apparent declination of the date

    def direction_enu(self) -> np.ndarray:
        """Unit vectors (east, north, up), shape (n_stars, 3)."""
        el, az = np.radians(self.elevation_deg), np.radians(self.azimuth_deg)
        return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


def star_positions(latitude_deg: float, longitude_deg: float, time_utc, ra_deg=None, dec_deg=None, *,
                   refraction: bool = False, pressure_hpa: float = STANDARD_PRESSURE_HPA,
                   temperature_c: float = STANDARD_TEMPERATURE_C) -> StarPlaces:
    """Apparent place of stars (J2000 ``ra_deg``, ``dec_deg``; default the whole catalogue)
    for one observer (latitude -90..90, longitude -180..180 degrees) at one time (as
    :func:`skymodel.sun.solar_position` accepts, years 1900-2100)."""
    lat = float(check_array_range("latitude_deg", latitude_deg, -90.0, 90.0, "degrees"))
    lon = float(check_array_range("longitude_deg", longitude_deg, -180.0, 180.0, "degrees"))
    t = as_utc_datetime64(time_utc)
    if t.ndim != 0:
        raise SkymodelInputError("time_utc", f"an array of shape {t.shape}", "one time")
    if ra_deg is None and dec_deg is None:
        cat = catalogue()
        ra, dec = cat.ra_deg, cat.dec_deg
    else:
        ra = np.atleast_1d(check_array_range("ra_deg", ra_deg, 0.0, 360.0, "degrees"))
        dec = np.atleast_1d(check_array_range("dec_deg", dec_deg, -90.0, 90.0, "degrees"))
        if ra.shape != dec.shape:
            raise SkymodelInputError("dec_deg", f"shape {dec.shape}", f"the shape of ra_deg {ra.shape}")
    if refraction:
        check_array_range("pressure_hpa", pressure_hpa, 0.0, 1100.0, "hPa")
        check_array_range("temperature_c", temperature_c, -90.0, 60.0, "degC")

    days = float((t - _J2000).astype("timedelta64[us]").astype(np.int64) / _US_PER_DAY)
    T = days / 36525.0
    # precession J2000 -> date (Meeus eq. 21.3, IAU 1976), arcseconds -> radians
    as2r = math.radians(1.0 / 3600.0)
    zeta = (2306.2181 * T + 0.30188 * T**2 + 0.017998 * T**3) * as2r
    z = (2306.2181 * T + 1.09468 * T**2 + 0.018203 * T**3) * as2r
    theta = (2004.3109 * T - 0.42665 * T**2 - 0.041833 * T**3) * as2r
    precession = _rot(2, -z) @ _rot(1, theta) @ _rot(2, -zeta)
    # nutation (Meeus ch. 22, four terms) and the obliquity, radians
    dpsi, deps, eps = (math.radians(float(v)) for v in nutation(T))
    eps0 = eps - deps
    nutation_matrix = _rot(0, -eps) @ _rot(2, -dpsi) @ _rot(0, eps0)
    a, d = np.radians(ra), np.radians(dec)
    u = np.stack([np.cos(d) * np.cos(a), np.cos(d) * np.sin(a), np.sin(d)], axis=-1)
    u = u @ (nutation_matrix @ precession).T
    # annual aberration: the Earth's velocity points 90 degrees behind the sun's longitude
    sp = solar_position(0.0, 0.0, t)
    sa, sd = math.radians(float(sp.right_ascension_deg)), math.radians(float(sp.declination_deg))
    sun_lam = math.atan2(math.sin(sa) * math.cos(eps) + math.tan(sd) * math.sin(eps), math.cos(sa))
    v_ecl = np.array([math.sin(sun_lam), -math.cos(sun_lam), 0.0])  # direction of the Earth's velocity
    v = _rot(0, -eps) @ v_ecl
    u = u + ABERRATION_ARCSEC * as2r * v
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    ra_app = np.degrees(np.arctan2(u[:, 1], u[:, 0])) % 360.0
    dec_app = np.degrees(np.arcsin(np.clip(u[:, 2], -1.0, 1.0)))
    # horizon coordinates
    gmst = 280.46061837 + 360.98564736629 * days + T * T * (0.000387933 - T / 38710000.0)
    gast = gmst + math.degrees(dpsi) * math.cos(eps)
    h = np.radians((gast + lon - ra_app) % 360.0)
    phi = math.radians(lat)
    dr = np.radians(dec_app)
    east = -np.cos(dr) * np.sin(h)
    north = np.sin(dr) * math.cos(phi) - np.cos(dr) * np.cos(h) * math.sin(phi)
    up = np.sin(dr) * math.sin(phi) + np.cos(dr) * np.cos(h) * math.cos(phi)
    az = np.degrees(np.arctan2(east, north)) % 360.0
    az = np.where(az >= 360.0, az - 360.0, az)
    el = np.degrees(np.arctan2(up, np.hypot(east, north)))
    if refraction:
        el = np.minimum(el + refraction_correction(el, pressure_hpa, temperature_c), 90.0)
    return StarPlaces(elevation_deg=el, azimuth_deg=az, right_ascension_deg=ra_app, declination_deg=dec_app)


# ----------------------------------------------------------------------------- spectrum


def ballesteros_temperature_k(b_v) -> np.ndarray:
    """Blackbody temperature (K) of a star of colour B-V (Ballesteros 2012, EPL 97, 34008, eq. 14),
    for B-V in [-0.5, 4.0] (the catalogue spans -0.31 to 3.33; the reddest, carbon stars and
    Miras with B-V > 2, are far from blackbodies, but a handful of faint points)."""
    bv = check_array_range("b_v", b_v, -0.5, 4.0, "magnitudes")
    return (4600.0 * (1.0 / (0.92 * bv + 1.7) + 1.0 / (0.92 * bv + 0.62)))[()]


def planck_radiance(wavelengths_nm, temperature_k) -> np.ndarray:
    """Blackbody spectral radiance, W m^-2 sr^-1 nm^-1, shape ``T.shape + (n_wl,)``."""
    lam = np.asarray(wavelengths_nm, dtype=float) * 1e-9
    t = np.asarray(temperature_k, dtype=float)[..., None]
    return _C1 / lam**5 / np.expm1(_C2 / (lam * t)) * 1e-9


def star_irradiance(wavelengths_nm=None, v_mag=None, b_v=None) -> np.ndarray:
    """Spectral irradiance above the atmosphere (W m^-2 nm^-1) of stars of magnitude ``v_mag``
    and colour ``b_v`` (arrays of one shape; default the whole catalogue), shape
    ``v_mag.shape + (n_wl,)``: a blackbody at the Ballesteros temperature, equal at 545 nm to
    3.631e-11 * 10^(-0.4 V) (module docstring)."""
    wl = as_wavelengths(wavelengths_nm)
    if v_mag is None and b_v is None:
        cat = catalogue()
        v, bv = cat.v_mag, cat.b_v
    else:
        v = check_array_range("v_mag", v_mag, -2.0, 20.0, "magnitudes")
        bv = np.asarray(b_v, dtype=float)
    t = ballesteros_temperature_k(bv)
    shape = planck_radiance(wl, t) / planck_radiance(np.array([V_EFFECTIVE_WAVELENGTH_NM]), t)
    return V_ZERO_POINT_W_M2_NM * 10.0 ** (-0.4 * np.asarray(v, dtype=float))[..., None] * shape


# ----------------------------------------------------------------------------- point sources


def equirectangular_solid_angles(height: int) -> np.ndarray:
    """Solid angle (sr) of one pixel in each row of an equirectangular image ``2 height`` wide."""
    edges = np.radians(np.arange(height + 1) * (180.0 / height))
    return (np.cos(edges[:-1]) - np.cos(edges[1:])) * (2.0 * np.pi / (2 * height))


def splat_stars(image, elevation_deg, azimuth_deg, irradiance, *, center_azimuth_deg: float = 90.0,
                transmittance=None, below_horizon: bool = False) -> np.ndarray:
    """Add point sources to an equirectangular radiance image, conserving their irradiance.

    ``image``: (H, 2H, n_wl) radiance, W m^-2 sr^-1 nm^-1 (added to in place and returned).
    ``elevation_deg``, ``azimuth_deg``: (n,) where the sources are. ``irradiance``: (n, n_wl)
    above the atmosphere, W m^-2 nm^-1. ``transmittance``: None, or a function
    ``f(zenith_deg (n,)) -> (n, n_wl)`` (or ``(n,)``) by which each source is dimmed, such as
    the direct-beam transmittance of the atmosphere along the line of sight.
    ``below_horizon``: False (default) leaves out sources below the horizon (elevation < 0).

    Each source lands on the four pixels around its position with bilinear weights (columns
    wrap around in azimuth; above the first or below the last row's centre the weight stays
    on that row): pixel i gets ``E w_i / Omega_i``, so ``sum(L * Omega)`` grows by exactly
    ``sum(E * T)``.
    """
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[1] != 2 * img.shape[0]:
        raise SkymodelInputError("image", f"an array of shape {img.shape}", "(H, 2H, n_wavelengths)")
    h, w, n_wl = img.shape
    el = np.atleast_1d(check_array_range("elevation_deg", elevation_deg, -90.0, 90.0, "degrees"))
    az = np.atleast_1d(check_array_range("azimuth_deg", azimuth_deg, -360.0, 720.0, "degrees"))
    e = np.asarray(irradiance, dtype=float)
    if e.shape != (el.size, n_wl) or az.shape != el.shape:
        raise SkymodelInputError("irradiance", f"shape {e.shape}", f"({el.size}, {n_wl}) matching the positions and the image")
    if not np.all(np.isfinite(e)) or np.any(e < 0):
        raise SkymodelInputError("irradiance", "negative or non-finite values", "finite values >= 0")
    c = float(check_array_range("center_azimuth_deg", center_azimuth_deg, -360.0, 360.0, "degrees"))
    keep = np.ones(el.shape, bool) if below_horizon else el >= 0.0
    el, az, e = el[keep], az[keep], e[keep]
    zen = 90.0 - el
    if transmittance is not None and el.size:
        tr = np.asarray(transmittance(zen), dtype=float)
        if tr.ndim == 1:
            tr = tr[:, None]
        e = e * tr
    # continuous pixel coordinates, centres at integers (as EquirectangularCamera.project)
    x = np.mod((az - c) / 360.0 + 0.5, 1.0) * w - 0.5
    y = zen * (h / 180.0) - 0.5
    x0 = np.floor(x)
    fx = x - x0
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y = np.clip(y, 0.0, h - 1.0)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 1)
    fy = y - y0
    y1 = np.minimum(y0 + 1, h - 1)
    omega = equirectangular_solid_angles(h)
    for yy, xx, wt in ((y0, x0, (1 - fx) * (1 - fy)), (y0, x1, fx * (1 - fy)),
                       (y1, x0, (1 - fx) * fy), (y1, x1, fx * fy)):
        np.add.at(img, (yy, xx), e * (wt / omega[yy])[:, None])
    return img
