"""The sun: where it is, how large it looks, how its disc darkens to the limb, and its spectrum.

Position
    :func:`solar_position` follows the low-precision solar coordinates of J. Meeus,
    *Astronomical Algorithms* (2nd ed., 1998), as in the NOAA solar calculator: the geometric
    mean longitude and anomaly and the equation of centre (ch. 25), nutation from the four
    largest terms (ch. 22), aberration -20.4898"/R, the IAU 1980 mean obliquity (Meeus eq.
    22.2), Greenwich apparent sidereal time (eq. 12.4 plus the equation of the equinoxes), and
    the sun's horizontal parallax 8.794"/R for a spherical Earth. The sun's ecliptic longitude
    is good to about 0.01 degrees (Meeus ch. 25). Against NREL's SPA (Reda & Andreas 2004, as
    ``pvlib.solarposition.spa_python``) over random places and times 1950-2050 the largest
    differences found were 0.008 degrees in elevation and 0.009 degrees in direction
    (``tests/test_sun.py``); the Earth-sun distance agrees to 1e-4 AU.

    Time scale: the sidereal rotation uses UT1 ~ UTC (the input), as it should; the sun's
    coordinates are evaluated at UT as well instead of at TT = UT + delta-T. The sun moves
    0.041 degrees per hour along the ecliptic, so neglecting delta-T (about +30 to +70 s over
    1950-2050) costs at most 0.0008 degrees. UTC-UT1 (< 0.9 s) is neglected too (< 0.004 degrees).

    Angles in degrees at the interface. Azimuth is measured clockwise from geographic north
    (east = 90). With the sun at the zenith, or an observer at a pole, the azimuth is the limit
    of the formula (at the zenith: 0; at a pole: measured from the meridian of the given
    longitude), since no direction is singled out there.

Disc
    :data:`SUN_ANGULAR_RADIUS_DEG` is computed from the IAU 2015 nominal solar radius
    (Resolution B3: 695,700 km) and the astronomical unit (IAU 2012: 149,597,870.7 km).

Limb darkening
    :func:`limb_darkening` uses Neckel & Labs (1994, Solar Physics 153, 91): I(mu)/I(1) =
    sum_k a_k mu^k (k = 0..5) at 30 continuum wavelengths (``skymodel/data/sources/sun/limb_darkening.csv``),
    coefficients interpolated linearly in wavelength.

Spectrum
    :func:`solar_irradiance` reads the ASTM G173-03 extraterrestrial spectrum
    (``skymodel/data/generated/solar_spectrum_astm_g173.csv``, extracted by
    ``skymodel/data/generated/make_solar_spectrum.py``) and returns band means: the value at each output
    wavelength is the mean of the native (0.5-1 nm) table over a band centred on it, whose width
    is the local spacing of the output grid unless given, so a coarse grid carries the averaged
    spectrum rather than samples of single Fraunhofer lines.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from datetime import date, datetime, timezone

import numpy as np

from skymodel.data import csv_columns
from skymodel.errors import SkymodelInputError, check_array_range
from skymodel.wavelengths import as_wavelengths

# ----------------------------------------------------------------------------- constants

#: IAU 2015 Resolution B3 nominal solar radius, km.
SOLAR_RADIUS_KM = 695_700.0
#: IAU 2012 Resolution B2 astronomical unit, km.
ASTRONOMICAL_UNIT_KM = 149_597_870.7
#: Angular radius of the solar disc seen from 1 AU, degrees (0.26645).
SUN_ANGULAR_RADIUS_DEG = math.degrees(math.asin(SOLAR_RADIUS_KM / ASTRONOMICAL_UNIT_KM))

#: Years (UTC) accepted by :func:`solar_position`; checked against SPA over 1900-2100.
SUPPORTED_YEARS = (1900, 2100)
#: Earth-sun distances accepted (AU): the orbit spans 0.983-1.017.
DISTANCE_RANGE_AU = (0.9, 1.1)

#: Refraction is applied only at and above this true elevation (degrees): the sun's upper limb
#: on the apparent horizon, -(0.26667 + 0.5667), the convention of SPA (Reda & Andreas 2004).
REFRACTION_CUTOFF_DEG = -(0.26667 + 0.5667)
#: Default surface pressure (hPa) and temperature (degC) for refraction: the ISA sea level.
STANDARD_PRESSURE_HPA = 1013.25
STANDARD_TEMPERATURE_C = 15.0

#: Widest band (nm) that :func:`solar_irradiance` averages over; the shipped table spans
#: 330-830 nm, so any band up to this width centred in 380-780 nm lies inside it.
MAX_BANDWIDTH_NM = 100.0

_SOLAR_SPECTRUM_CSV = "generated/solar_spectrum_astm_g173.csv"
_LIMB_DARKENING_CSV = "sources/sun/limb_darkening.csv"

_J2000_UT = np.datetime64("2000-01-01T12:00:00", "us")
_US_PER_DAY = 86_400e6
_TIME_ALLOWED = (f"a datetime, numpy datetime64 or ISO 8601 string (naive means UTC), "
                 f"years {SUPPORTED_YEARS[0]}-{SUPPORTED_YEARS[1]}")


# ----------------------------------------------------------------------------- input checks


def _one_time(value) -> np.datetime64:
    """One time value -> naive UTC datetime64[us]; raises SkymodelInputError."""
    if isinstance(value, np.datetime64):
        t = value.astype("datetime64[us]")
    else:
        try:
            if isinstance(value, str):
                dt = datetime.fromisoformat(value.strip())
            elif isinstance(value, datetime):
                dt = value
            elif isinstance(value, date):
                dt = datetime(value.year, value.month, value.day)
            else:
                raise TypeError
            if dt.tzinfo is not None and dt.utcoffset() is not None:
                dt = dt.astimezone(timezone.utc)
            # rebuild a plain datetime (drops tzinfo; also for datetime subclasses such as pandas')
            dt = datetime(dt.year, dt.month, dt.day, dt.hour, dt.minute, dt.second, dt.microsecond)
            t = np.datetime64(dt, "us")
        except (TypeError, ValueError, OverflowError, AttributeError):
            raise SkymodelInputError("time_utc", value, _TIME_ALLOWED) from None
    if np.isnat(t):
        raise SkymodelInputError("time_utc", value, _TIME_ALLOWED)
    return t


def as_utc_datetime64(time_utc) -> np.ndarray:
    """Times as a naive-UTC ``datetime64[us]`` array of the input's shape.

    Accepts a :class:`datetime.datetime` (naive: UTC; aware: converted), a
    :class:`datetime.date` (midnight UTC), a numpy ``datetime64`` scalar or array (taken as
    UTC), an ISO 8601 string (``"2026-06-21T12:00:00Z"``, ``"2026-06-21 14:00+02:00"``), or a
    list/array of these. Years must lie in :data:`SUPPORTED_YEARS`.
    """
    try:
        arr = np.asarray(time_utc)
    except Exception:
        raise SkymodelInputError("time_utc", time_utc, _TIME_ALLOWED) from None
    if arr.dtype.kind == "M":
        t = arr.astype("datetime64[us]")
        if np.any(np.isnat(t)):
            raise SkymodelInputError("time_utc", "NaT", _TIME_ALLOWED)
    elif arr.dtype.kind in "OUS":
        t = np.empty(arr.shape, dtype="datetime64[us]")
        for idx, v in np.ndenumerate(arr):
            t[idx] = _one_time(v)
    else:  # bare numbers are ambiguous (seconds? days? Julian days?)
        raise SkymodelInputError("time_utc", time_utc, _TIME_ALLOWED)
    years = t.astype("datetime64[Y]").astype(np.int64) + 1970
    bad = (years < SUPPORTED_YEARS[0]) | (years > SUPPORTED_YEARS[1])
    if np.any(bad):
        raise SkymodelInputError("time_utc", str(np.atleast_1d(t)[np.atleast_1d(bad)][0]), _TIME_ALLOWED)
    return t


# ----------------------------------------------------------------------------- position


@dataclass(frozen=True)
class SolarPosition:
    """Position of the sun for an observer at sea level; arrays broadcast over the inputs.

    Angles in degrees. ``elevation_deg`` is the topocentric elevation of the disc centre,
    geometric (unrefracted) unless :func:`solar_position` was called with ``refraction=True``,
    in which case it is the apparent elevation (``true_elevation_deg + refraction_deg``).
    """

    time_utc: np.ndarray  #: the times, naive UTC datetime64[us]
    elevation_deg: np.ndarray  #: topocentric elevation (apparent if refraction was asked for)
    zenith_deg: np.ndarray  #: 90 - elevation_deg
    azimuth_deg: np.ndarray  #: clockwise from north, [0, 360)
    true_elevation_deg: np.ndarray  #: topocentric geometric elevation, no refraction
    refraction_deg: np.ndarray  #: refraction added to the elevation (0 when not asked for)
    declination_deg: np.ndarray  #: geocentric apparent declination
    right_ascension_deg: np.ndarray  #: geocentric apparent right ascension, [0, 360)
    hour_angle_deg: np.ndarray  #: local hour angle, [-180, 180), positive after noon
    equation_of_time_min: np.ndarray  #: apparent minus mean solar time, minutes
    earth_sun_distance_au: np.ndarray  #: AU
    julian_day: np.ndarray  #: Julian day (UT)

    @property
    def angular_radius_deg(self):
        """Angular radius of the solar disc at this date, degrees."""
        return np.degrees(np.arcsin(SOLAR_RADIUS_KM / (ASTRONOMICAL_UNIT_KM * np.asarray(self.earth_sun_distance_au))))

    def direction_enu(self) -> np.ndarray:
        """Unit vector towards the sun (east, north, up), shape ``(..., 3)``, from
        ``elevation_deg`` and ``azimuth_deg``."""
        el = np.radians(self.elevation_deg)
        az = np.radians(self.azimuth_deg)
        return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


def nutation(T):
    """Nutation in longitude and in obliquity and the true obliquity of the ecliptic, degrees,
    at ``T`` Julian centuries (TT) since J2000.0: Meeus ch. 22, the four largest terms
    (arcseconds) and the mean obliquity of eq. 22.2."""
    omega = np.radians(125.04452 - 1934.136261 * T)
    l_sun = np.radians(280.4665 + 36000.7698 * T)
    l_moon = np.radians(218.3165 + 481267.8813 * T)
    dpsi = (-17.20 * np.sin(omega) - 1.32 * np.sin(2 * l_sun) - 0.23 * np.sin(2 * l_moon)
            + 0.21 * np.sin(2 * omega)) / 3600.0
    deps = (9.20 * np.cos(omega) + 0.57 * np.cos(2 * l_sun) + 0.10 * np.cos(2 * l_moon)
            - 0.09 * np.cos(2 * omega)) / 3600.0
    eps0 = 23.0 + 26.0 / 60.0 + (21.448 - T * (46.8150 + T * (0.00059 - 0.001813 * T))) / 3600.0
    return dpsi, deps, eps0 + deps


def mean_sidereal_time_deg(days_ut):
    """Greenwich mean sidereal time, degrees (not wrapped), ``days_ut`` days of UT since
    J2000.0 (Meeus eq. 12.4)."""
    Tu = days_ut / 36525.0
    return 280.46061837 + 360.98564736629 * days_ut + Tu * Tu * (0.000387933 - Tu / 38710000.0)


def _sun_equatorial(days):
    """Apparent geocentric sun for ``days`` since J2000.0 (2000-01-01 12:00).

    Returns (right ascension deg, declination deg, distance AU, apparent sidereal time at
    Greenwich deg, equation of time deg)."""
    T = days / 36525.0
    # Meeus ch. 25 (low precision): geometric mean longitude, mean anomaly, eccentricity
    L0 = 280.46646 + T * (36000.76983 + 0.0003032 * T)
    M = 357.52911 + T * (35999.05029 - 0.0001537 * T)
    ecc = 0.016708634 - T * (0.000042037 + 0.0000001267 * T)
    Mr = np.radians(M)
    centre = ((1.914602 - T * (0.004817 + 0.000014 * T)) * np.sin(Mr)
              + (0.019993 - 0.000101 * T) * np.sin(2.0 * Mr) + 0.000289 * np.sin(3.0 * Mr))
    true_longitude = L0 + centre
    true_anomaly = np.radians(M + centre)
    distance = 1.000001018 * (1.0 - ecc * ecc) / (1.0 + ecc * np.cos(true_anomaly))
    dpsi, _, eps_deg = nutation(T)
    eps = np.radians(eps_deg)
    # apparent longitude: nutation and annual aberration
    lam = np.radians(true_longitude + dpsi - 20.4898 / 3600.0 / distance)
    ra = np.degrees(np.arctan2(np.cos(eps) * np.sin(lam), np.cos(lam))) % 360.0
    dec = np.degrees(np.arcsin(np.sin(eps) * np.sin(lam)))
    # Greenwich mean sidereal time + equation of the equinoxes
    gast = (mean_sidereal_time_deg(days) + dpsi * np.cos(eps)) % 360.0
    # equation of time (Meeus eq. 28.1), wrapped to [-180, 180)
    eot = (L0 - 0.0057183 - ra + dpsi * np.cos(eps) + 180.0) % 360.0 - 180.0
    return ra, dec, distance, gast, eot


def refraction_correction(true_elevation_deg, pressure_hpa: float = STANDARD_PRESSURE_HPA,
                          temperature_c: float = STANDARD_TEMPERATURE_C) -> np.ndarray:
    """Atmospheric refraction (degrees) to add to a true elevation.

    Saemundsson's (1986) formula, as given by Meeus (eq. 16.4) and used by SPA:
    R = (P / 1010 hPa) (283 K / T) * 1.02' / tan(h + 10.3 / (h + 5.11)), h in degrees. Applied
    at and above :data:`REFRACTION_CUTOFF_DEG`; 0 below, where the disc is wholly under the
    apparent horizon and the formula no longer holds. Never negative.
    """
    p = check_array_range("pressure_hpa", pressure_hpa, 0.0, 1100.0, "hPa")
    t = check_array_range("temperature_c", temperature_c, -90.0, 60.0, "degC")
    h = np.asarray(true_elevation_deg, dtype=float)
    ok = h >= REFRACTION_CUTOFF_DEG
    hs = np.where(ok, h, 0.0)
    r = (p / 1010.0) * (283.0 / (273.0 + t)) * 1.02 / (60.0 * np.tan(np.radians(hs + 10.3 / (hs + 5.11))))
    return np.where(ok, np.maximum(r, 0.0), 0.0)


def solar_position(latitude_deg, longitude_deg, time_utc, *, refraction: bool = False,
                   pressure_hpa: float = STANDARD_PRESSURE_HPA,
                   temperature_c: float = STANDARD_TEMPERATURE_C) -> SolarPosition:
    """Position of the sun seen from ``(latitude_deg, longitude_deg)`` at ``time_utc``.

    Parameters
    ----------
    latitude_deg : geodetic latitude, degrees north, in [-90, 90]; scalar or array.
    longitude_deg : degrees east, in [-180, 180]; scalar or array.
    time_utc : datetime (naive = UTC, aware = converted), numpy datetime64 (UTC), ISO 8601
        string (``"2026-06-21T12:00:00Z"``), or an array/list of these; years 1900-2100.
    refraction : if True, ``elevation_deg`` (and ``zenith_deg``) include atmospheric refraction
        for ``pressure_hpa`` and ``temperature_c`` (:func:`refraction_correction`).

    The three inputs broadcast against each other; every field of the result has the
    broadcast shape (numpy scalars when all inputs are scalars).

    Raises :class:`SkymodelInputError` naming the parameter for out-of-range or unparseable input.
    """
    lat = check_array_range("latitude_deg", latitude_deg, -90.0, 90.0, "degrees")
    lon = check_array_range("longitude_deg", longitude_deg, -180.0, 180.0, "degrees")
    t = as_utc_datetime64(time_utc)
    try:
        lat, lon, t = np.broadcast_arrays(lat, lon, t)
    except ValueError:
        allowed = f"a shape that broadcasts with latitude {lat.shape} and longitude {lon.shape}"
        raise SkymodelInputError("time_utc", f"shape {t.shape}", allowed) from None
    if refraction:  # check before the work
        check_array_range("pressure_hpa", pressure_hpa, 0.0, 1100.0, "hPa")
        check_array_range("temperature_c", temperature_c, -90.0, 60.0, "degC")

    days = (t - _J2000_UT).astype("timedelta64[us]").astype(np.int64) / _US_PER_DAY
    ra, dec, distance, gast, eot = _sun_equatorial(days)
    hour_angle = (gast + lon - ra + 180.0) % 360.0 - 180.0

    phi = np.radians(lat)
    H = np.radians(hour_angle)
    d = np.radians(dec)
    east = -np.cos(d) * np.sin(H)
    north = np.sin(d) * np.cos(phi) - np.cos(d) * np.cos(H) * np.sin(phi)
    up = np.sin(d) * np.sin(phi) + np.cos(d) * np.cos(H) * np.cos(phi)
    horizontal = np.hypot(east, north)
    azimuth = np.degrees(np.arctan2(east, north)) % 360.0
    azimuth = np.where(azimuth >= 360.0, azimuth - 360.0, azimuth)
    # topocentric elevation, spherical Earth: parallax sin(pi) = 8.794143" / R
    sin_parallax = math.sin(math.radians(8.794143 / 3600.0)) / distance
    true_elevation = np.degrees(np.arctan2(up - sin_parallax, horizontal))

    if refraction:
        refr = refraction_correction(true_elevation, pressure_hpa, temperature_c)
    else:
        refr = np.zeros_like(true_elevation)
    elevation = np.minimum(true_elevation + refr, 90.0)

    def out(a):
        return np.asarray(a)[()]

    return SolarPosition(
        time_utc=out(t),
        elevation_deg=out(elevation),
        zenith_deg=out(90.0 - elevation),
        azimuth_deg=out(azimuth),
        true_elevation_deg=out(true_elevation),
        refraction_deg=out(refr),
        declination_deg=out(dec),
        right_ascension_deg=out(ra),
        hour_angle_deg=out(hour_angle),
        equation_of_time_min=out(4.0 * eot),
        earth_sun_distance_au=out(distance),
        julian_day=out(days + 2451545.0),
    )


# ----------------------------------------------------------------------------- disc


def sun_angular_radius_deg(distance_au=1.0):
    """Angular radius (degrees) of the solar disc seen from ``distance_au`` (0.9-1.1 AU)."""
    d = check_array_range("distance_au", distance_au, *DISTANCE_RANGE_AU, "AU")
    return np.degrees(np.arcsin(SOLAR_RADIUS_KM / (ASTRONOMICAL_UNIT_KM * d)))[()]


@functools.lru_cache(maxsize=None)
def _limb_table():
    cols = csv_columns(_LIMB_DARKENING_CSV)
    coeffs = np.stack([cols[f"a{k}"] for k in range(6)], axis=1)
    return cols["wavelength_nm"], coeffs


def limb_darkening_coefficients(wavelengths_nm=None) -> np.ndarray:
    """Neckel & Labs (1994) polynomial coefficients a_0..a_5 at each wavelength, shape (n, 6).

    Interpolated linearly in wavelength between the tabulated continuum windows, then divided by
    their sum so that I(mu=1)/I(centre) is exactly 1 (the printed rows sum to 1 within 2e-5).
    """
    wl = as_wavelengths(wavelengths_nm)
    table_wl, table = _limb_table()
    a = np.stack([np.interp(wl, table_wl, table[:, k]) for k in range(6)], axis=1)
    return a / a.sum(axis=1, keepdims=True)


def limb_darkening(wavelengths_nm, mu) -> np.ndarray:
    """Intensity across the solar disc relative to the centre, I(mu)/I(1).

    ``mu`` is the cosine of the heliocentric angle: 1 at the disc centre, 0 at the limb; for a
    point at fraction ``r`` of the disc's angular radius, mu = sqrt(1 - r^2). Any shape, values
    in [0, 1]. Returns shape ``mu.shape + (n_wavelengths,)``.
    """
    a = limb_darkening_coefficients(wavelengths_nm)
    m = check_array_range("mu", mu, 0.0, 1.0, "(cosine of the heliocentric angle)")[..., None]
    p = a[:, 5] * np.ones_like(m)
    for k in range(4, -1, -1):
        p = a[:, k] + m * p
    return p


def disc_mean_to_centre_ratio(wavelengths_nm=None) -> np.ndarray:
    """Disc-averaged over central intensity, 2 * integral_0^1 I(mu)/I(1) mu dmu = sum_k 2 a_k/(k+2).

    The irradiance from the disc is E = I(centre) * ratio * pi sin^2(angular radius)."""
    a = limb_darkening_coefficients(wavelengths_nm)
    return a @ (2.0 / (np.arange(6) + 2.0))


# ----------------------------------------------------------------------------- spectrum


@functools.lru_cache(maxsize=None)
def _spectrum_table():
    cols = csv_columns(_SOLAR_SPECTRUM_CSV)
    wl = cols["wavelength_nm"]
    e = cols["irradiance_W_m2_nm"]
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(wl))])
    return wl, e, cumulative


def native_solar_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """The shipped ASTM G173-03 extraterrestrial table (wavelength nm, W m^-2 nm^-1), 330-830 nm."""
    wl, e, _ = _spectrum_table()
    return wl.copy(), e.copy()


def _integral_to(x):
    """Exact integral of the native table (piecewise linear) from its first wavelength to x."""
    wl, e, cumulative = _spectrum_table()
    k = np.clip(np.searchsorted(wl, x, side="right") - 1, 0, wl.size - 2)
    dx = x - wl[k]
    slope = (e[k + 1] - e[k]) / (wl[k + 1] - wl[k])
    return cumulative[k] + e[k] * dx + 0.5 * slope * dx * dx


def default_bandwidths(wavelengths_nm) -> np.ndarray:
    """Band widths (nm) :func:`solar_irradiance` uses when none is given: the local grid
    spacing, i.e. the mean of the gaps to the two neighbouring wavelengths (the one gap at the
    ends); 1 nm for a single wavelength; at most :data:`MAX_BANDWIDTH_NM`."""
    wl = as_wavelengths(wavelengths_nm)
    u = np.unique(wl)
    if u.size == 1:
        widths = np.array([1.0])
    else:
        gaps = np.diff(u)
        widths = np.empty_like(u)
        widths[0], widths[-1] = gaps[0], gaps[-1]
        widths[1:-1] = 0.5 * (gaps[:-1] + gaps[1:])
    return np.minimum(widths[np.searchsorted(u, wl)], MAX_BANDWIDTH_NM)


def solar_irradiance(wavelengths_nm=None, distance_au=1.0, bandwidth_nm=None) -> np.ndarray:
    """Extraterrestrial solar spectral irradiance, W m^-2 nm^-1, on a surface facing the sun.

    The ASTM G173-03 extraterrestrial spectrum (1 AU) averaged over a band centred on each
    wavelength, scaled by 1 / distance_au^2.

    Parameters
    ----------
    wavelengths_nm : grid in nm within 380-780 (default: 380-780 every 5 nm).
    distance_au : Earth-sun distance, AU (scalar or array; 0.9-1.1), e.g.
        ``solar_position(...).earth_sun_distance_au``. An array adds leading axes:
        the result has shape ``distance.shape + (n_wavelengths,)``.
    bandwidth_nm : full width (nm) of the band averaged at each wavelength, scalar or one per
        wavelength, 0-100. ``None`` (default): the local grid spacing (:func:`default_bandwidths`),
        so a 5 nm grid carries 5 nm means and integrating the result over the grid reproduces
        the integral of the native table; a single wavelength gets 1 nm. ``0``: the native
        table interpolated linearly at the wavelength (no averaging).

    The band mean is the exact integral of the piecewise-linear native table over
    [lambda - w/2, lambda + w/2] divided by w (the trapezoid rule on the native points).
    """
    wl = as_wavelengths(wavelengths_nm)
    d = check_array_range("distance_au", distance_au, *DISTANCE_RANGE_AU, "AU")
    if bandwidth_nm is None:
        width = default_bandwidths(wl)
    else:
        width = check_array_range("bandwidth_nm", bandwidth_nm, 0.0, MAX_BANDWIDTH_NM, "nm")
        try:
            width = np.broadcast_to(width, wl.shape).astype(float)
        except ValueError:
            raise SkymodelInputError("bandwidth_nm", f"shape {width.shape}",
                                     f"a scalar or one width per wavelength ({wl.size})") from None
    table_wl, table_e, _ = _spectrum_table()
    point = np.interp(wl, table_wl, table_e)
    positive = width > 0.0
    safe = np.where(positive, width, 1.0)
    band = (_integral_to(wl + 0.5 * safe) - _integral_to(wl - 0.5 * safe)) / safe
    e = np.where(positive, band, point)
    return e / (d[..., None] ** 2)


def sun_disc_radiance(wavelengths_nm=None, mu=1.0, bandwidth_nm=None) -> np.ndarray:
    """Spectral radiance of the solar disc above the atmosphere, W m^-2 sr^-1 nm^-1.

    I(mu) = E / (pi sin^2(angular radius) * mean-to-centre ratio) * I(mu)/I(1), with E from
    :func:`solar_irradiance` at 1 AU; radiance does not depend on the distance (irradiance and
    solid angle both scale as 1/d^2). ``mu`` as in :func:`limb_darkening`; the result has shape
    ``mu.shape + (n_wavelengths,)``.
    """
    wl = as_wavelengths(wavelengths_nm)
    e = solar_irradiance(wl, 1.0, bandwidth_nm)
    disc = math.pi * (SOLAR_RADIUS_KM / ASTRONOMICAL_UNIT_KM) ** 2
    centre = e / (disc * disc_mean_to_centre_ratio(wl))
    return centre * limb_darkening(wl, mu)
