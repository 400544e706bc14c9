"""The moon: where it is for an observer, how large it looks, and how much of it is lit.

Position
    :func:`moon_position` follows J. Meeus, *Astronomical Algorithms* (2nd ed., 1998),
    chapter 47: the mean elements of the moon (eqs. 47.1-47.6), the 60 + 60 periodic terms
    of Tables 47.A and 47.B (a truncation of ELP-2000/82, carried in
    ``skymodel/data/sources/moon/meeus_table_47.csv``) and the additive terms of
    Venus, Jupiter and the Earth's flattening, giving the geocentric ecliptic longitude,
    latitude and distance referred to the mean equinox of the date (Meeus: about 10" in
    longitude and 4" in latitude). Then nutation in longitude and obliquity (the four
    largest terms of Meeus ch. 22, as :mod:`skymodel.sun` uses), the IAU 1980 mean obliquity,
    geocentric apparent right ascension and declination, Greenwich apparent sidereal time
    (Meeus eq. 12.4 plus the equation of the equinoxes) and the *topocentric* place: the
    observer's geocentric position on the WGS84 ellipsoid (at ``altitude_m``) is subtracted
    from the moon's geocentric vector, which moves the moon by up to its horizontal parallax
    (0.9-1.0 degrees at the horizon).

    Time scales: the lunar theory is evaluated at TT = UTC + delta-T (the moon moves 0.55"
    per second; delta-T is 64 s in 2000 and 69 s in 2026) with delta-T from the polynomials
    of Espenak & Meeus (2006, NASA's *Five Millennium Canon of Solar Eclipses*, the ones for
    1900-2150; :func:`delta_t_seconds`), and the Earth's rotation at UT1 ~ UTC.

    Measured against JPL DE421 (skyfield 1.55 with the ``skyfield-data`` ephemeris, an
    independent numerical integration) over random places and times 1950-2050, and against
    PyEphem 4.2.1 (libastro's own lunar theory): see ``tests/test_astro_moon.py`` for the
    bounds asserted and ``docs/night.md`` for the figures.

Disc and phase
    Angular radius ``asin(R / d)`` with the IAU mean lunar radius R = 1737.4 km and the
    topocentric distance d (0.245-0.279 degrees). Phase angle: the angle sun-moon-observer,
    from the topocentric moon vector and the sun's geocentric vector
    (:func:`skymodel.sun.solar_position`, which is good to 0.01 degrees); 0 at full moon,
    180 at new moon. Illuminated fraction ``k = (1 + cos(phase angle)) / 2`` (Meeus eq.
    48.1). The moon waxes while its apparent ecliptic longitude runs 0-180 degrees ahead of
    the sun's.

    The selenographic longitude of the sun (needed by the ROLO lunar irradiance model) is
    approximated by ``+phase angle`` for a waxing moon and ``-phase angle`` for a waning one:
    the sub-solar point for a moon seen from its mean sub-observer point (libration ignored;
    libration moves the true value by up to about 8 degrees). A lunar eclipse is not modelled:
    at full moon the moon is lit whatever the Earth's shadow does.

All angles in degrees at the interface; azimuth clockwise from north (east = 90), as in
:mod:`skymodel.sun`. Inputs broadcast like :func:`skymodel.sun.solar_position`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from skymodel.data import csv_columns
from skymodel.errors import SkymodelInputError, check_array_range
from skymodel.sun import (
    ASTRONOMICAL_UNIT_KM,
    STANDARD_PRESSURE_HPA,
    STANDARD_TEMPERATURE_C,
    as_utc_datetime64,
    mean_sidereal_time_deg,
    nutation,
    refraction_correction,
    solar_position,
)

#: IAU mean radius of the moon, km (Archinal et al. 2018, IAU WGCCRE report).
MOON_RADIUS_KM = 1737.4
#: WGS84 equatorial radius (km) and flattening.
EARTH_EQUATORIAL_RADIUS_KM = 6378.137
EARTH_FLATTENING = 1.0 / 298.257223563
#: Observer altitudes accepted, metres above the ellipsoid.
ALTITUDE_RANGE_M = (-500.0, 10_000.0)
#: Mean Earth-moon distance that :data:`MEAN_DISC_SOLID_ANGLE_SR` refers to, km (Kieffer &
#: Stone 2005 normalise the ROLO model to it).
MEAN_MOON_DISTANCE_KM = 384_400.0
#: Solid angle of the lunar disc at :data:`MEAN_MOON_DISTANCE_KM`, sr (Kieffer & Stone 2005: 6.4177e-5).
MEAN_DISC_SOLID_ANGLE_SR = 6.4177e-5

_MEEUS_CSV = "sources/moon/meeus_table_47.csv"
_J2000 = np.datetime64("2000-01-01T12:00:00", "us")
_US_PER_DAY = 86_400e6


# ----------------------------------------------------------------------------- time


def delta_t_seconds(decimal_year) -> np.ndarray:
    """TT - UT in seconds for a decimal year in 1900-2150.

    The polynomials of Espenak & Meeus (2006), "Polynomial expressions for delta T", in NASA's
    *Five Millennium Canon of Solar Eclipses* (NASA/TP-2006-214141), for the intervals
    1900-1920, 1920-1941, 1941-1961, 1961-1986, 1986-2005, 2005-2050 and 2050-2150 (the last
    two are extrapolations; the observed value in 2025 is 69 s against 69.3 s here)."""
    y = np.asarray(decimal_year, dtype=float)
    out = np.empty_like(y)
    t = y - 1900.0
    m = y < 1920
    out[m] = (-2.79 + 1.494119 * t - 0.0598939 * t**2 + 0.0061966 * t**3 - 0.000197 * t**4)[m]
    t = y - 1920.0
    m = (y >= 1920) & (y < 1941)
    out[m] = (21.20 + 0.84493 * t - 0.076100 * t**2 + 0.0020936 * t**3)[m]
    t = y - 1950.0
    m = (y >= 1941) & (y < 1961)
    out[m] = (29.07 + 0.407 * t - t**2 / 233.0 + t**3 / 2547.0)[m]
    t = y - 1975.0
    m = (y >= 1961) & (y < 1986)
    out[m] = (45.45 + 1.067 * t - t**2 / 260.0 - t**3 / 718.0)[m]
    t = y - 2000.0
    m = (y >= 1986) & (y < 2005)
    out[m] = (63.86 + 0.3345 * t - 0.060374 * t**2 + 0.0017275 * t**3 + 0.000651814 * t**4
              + 0.00002373599 * t**5)[m]
    m = (y >= 2005) & (y < 2050)
    out[m] = (62.92 + 0.32217 * t + 0.005589 * t**2)[m]
    m = y >= 2050
    out[m] = (-20.0 + 32.0 * ((y - 1820.0) / 100.0) ** 2 - 0.5628 * (2150.0 - y))[m]
    return out[()]


def _days_since_j2000(t_utc: np.ndarray) -> np.ndarray:
    return (t_utc - _J2000).astype("timedelta64[us]").astype(np.int64) / _US_PER_DAY


# ----------------------------------------------------------------------------- geocentric moon


@functools.lru_cache(maxsize=1)
def _meeus_tables():
    c = csv_columns(_MEEUS_CSV)
    a = c["table_is_B"] == 0
    b = ~a
    mult = np.stack([c["D"], c["M"], c["Mp"], c["F"]], axis=1)
    return (mult[a], c["sine_1e6deg"][a], c["cosine_m"][a]), (mult[b], c["sine_1e6deg"][b])


def geocentric_ecliptic(days_tt) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geocentric ecliptic longitude and latitude (degrees, mean equinox of date) and the
    distance between the centres of the Earth and the moon (km), Meeus ch. 47, for
    ``days_tt`` days of TT since J2000.0. Meeus's example 47.a (1992-04-12 0h TT) gives
    133.162655, -3.229126, 368409.7 km."""
    T = np.asarray(days_tt, dtype=float) / 36525.0
    Lp = 218.3164477 + T * (481267.88123421 + T * (-0.0015786 + T * (1.0 / 538841.0 - T / 65194000.0)))
    D = 297.8501921 + T * (445267.1114034 + T * (-0.0018819 + T * (1.0 / 545868.0 - T / 113065000.0)))
    M = 357.5291092 + T * (35999.0502909 + T * (-0.0001536 + T / 24490000.0))
    Mp = 134.9633964 + T * (477198.8675055 + T * (0.0087414 + T * (1.0 / 69699.0 - T / 14712000.0)))
    F = 93.2720950 + T * (483202.0175233 + T * (-0.0036539 + T * (-1.0 / 3526000.0 + T / 863310000.0)))
    A1 = np.radians(119.75 + 131.849 * T)
    A2 = np.radians(53.09 + 479264.290 * T)
    A3 = np.radians(313.45 + 481266.484 * T)
    E = 1.0 - T * (0.002516 + 0.0000074 * T)
    args = np.radians(np.stack([D, M, Mp, F], axis=-1) % 360.0)  # (..., 4)
    (mult_a, sl, sr), (mult_b, sb) = _meeus_tables()

    def e_factor(m_mult):
        k = np.abs(m_mult)
        return np.where(k == 1, E[..., None], np.where(k == 2, (E * E)[..., None], 1.0))

    arg_a = args @ mult_a.T  # (..., 60)
    fa = e_factor(mult_a[:, 1])
    sigma_l = np.sum(sl * fa * np.sin(arg_a), axis=-1)
    sigma_r = np.sum(sr * fa * np.cos(arg_a), axis=-1)
    arg_b = args @ mult_b.T
    sigma_b = np.sum(sb * e_factor(mult_b[:, 1]) * np.sin(arg_b), axis=-1)
    Lpr, Mpr, Fr = np.radians(Lp), np.radians(Mp), np.radians(F)
    sigma_l = sigma_l + 3958.0 * np.sin(A1) + 1962.0 * np.sin(Lpr - Fr) + 318.0 * np.sin(A2)
    sigma_b = (sigma_b - 2235.0 * np.sin(Lpr) + 382.0 * np.sin(A3) + 175.0 * np.sin(A1 - Fr)
               + 175.0 * np.sin(A1 + Fr) + 127.0 * np.sin(Lpr - Mpr) - 115.0 * np.sin(Lpr + Mpr))
    lam = (Lp + sigma_l / 1e6) % 360.0
    beta = sigma_b / 1e6
    distance = 385000.56 + sigma_r / 1000.0
    return lam, beta, distance


# ----------------------------------------------------------------------------- result


@dataclass(frozen=True)
class MoonPosition:
    """The moon seen by an observer; arrays broadcast over the inputs, angles in degrees."""

    time_utc: np.ndarray  #: the times, naive UTC datetime64[us]
    elevation_deg: np.ndarray  #: topocentric elevation of the disc centre (apparent if refraction was asked for)
    azimuth_deg: np.ndarray  #: clockwise from north, [0, 360)
    true_elevation_deg: np.ndarray  #: topocentric geometric elevation
    refraction_deg: np.ndarray  #: refraction added to the elevation (0 unless asked for)
    distance_km: np.ndarray  #: observer-moon centre distance
    geocentric_distance_km: np.ndarray  #: Earth centre-moon centre distance
    right_ascension_deg: np.ndarray  #: geocentric apparent right ascension, [0, 360)
    declination_deg: np.ndarray  #: geocentric apparent declination
    ecliptic_longitude_deg: np.ndarray  #: geocentric apparent ecliptic longitude (true equinox of date)
    ecliptic_latitude_deg: np.ndarray  #: geocentric ecliptic latitude
    angular_radius_deg: np.ndarray  #: topocentric angular radius of the disc
    phase_angle_deg: np.ndarray  #: sun-moon-observer angle, 0 full, 180 new
    illuminated_fraction: np.ndarray  #: lit fraction of the disc, (1 + cos(phase angle)) / 2
    elongation_deg: np.ndarray  #: topocentric sun-observer-moon angle
    waxing: np.ndarray  #: True while the moon is 0-180 degrees east of the sun in longitude
    sun_selenographic_longitude_deg: np.ndarray  #: +phase angle waxing, -phase angle waning (libration ignored)
    sun_moon_distance_au: np.ndarray  #: sun-moon distance, AU

    @property
    def solid_angle_sr(self):
        """Solid angle of the disc, sr: 2 pi (1 - cos(angular radius))."""
        return 2.0 * np.pi * (1.0 - np.cos(np.radians(self.angular_radius_deg)))

    def direction_enu(self) -> np.ndarray:
        """Unit vector towards the moon (east, north, up), shape ``(..., 3)``."""
        el = np.radians(self.elevation_deg)
        az = np.radians(self.azimuth_deg)
        return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


def _equatorial_unit(ra_deg, dec_deg):
    a, d = np.radians(ra_deg), np.radians(dec_deg)
    return np.stack([np.cos(d) * np.cos(a), np.cos(d) * np.sin(a), np.sin(d)], axis=-1)


def moon_position(latitude_deg, longitude_deg, time_utc, *, altitude_m=0.0, refraction: bool = False,
                  pressure_hpa: float = STANDARD_PRESSURE_HPA,
                  temperature_c: float = STANDARD_TEMPERATURE_C) -> MoonPosition:
    """Topocentric place, disc size and phase of the moon for ``(latitude_deg, longitude_deg)``
    at ``time_utc`` (same conventions and input checks as :func:`skymodel.sun.solar_position`:
    latitude -90..90, longitude -180..180, years 1900-2100), ``altitude_m`` above the WGS84
    ellipsoid (-500..10000 m). ``refraction=True`` adds Saemundsson's refraction
    (:func:`skymodel.sun.refraction_correction`) to ``elevation_deg``.

    Raises :class:`SkymodelInputError` naming the parameter for bad input, before any work.
    """
    lat = check_array_range("latitude_deg", latitude_deg, -90.0, 90.0, "degrees")
    lon = check_array_range("longitude_deg", longitude_deg, -180.0, 180.0, "degrees")
    alt = check_array_range("altitude_m", altitude_m, *ALTITUDE_RANGE_M, "m")
    t = as_utc_datetime64(time_utc)
    try:
        lat, lon, alt, t = np.broadcast_arrays(lat, lon, alt, t)
    except ValueError:
        raise SkymodelInputError("time_utc", f"shape {t.shape}",
                                 f"a shape that broadcasts with latitude {lat.shape} and longitude {lon.shape}") from None
    if refraction:
        check_array_range("pressure_hpa", pressure_hpa, 0.0, 1100.0, "hPa")
        check_array_range("temperature_c", temperature_c, -90.0, 60.0, "degC")

    days_ut = _days_since_j2000(t)
    year = 2000.0 + days_ut / 365.25
    days_tt = days_ut + delta_t_seconds(year) / 86400.0
    lam, beta, dist = geocentric_ecliptic(days_tt)
    T = days_tt / 36525.0
    dpsi, _, eps = nutation(T)
    lam_app = (lam + dpsi) % 360.0
    lr, br, er = np.radians(lam_app), np.radians(beta), np.radians(eps)
    ra = np.degrees(np.arctan2(np.sin(lr) * np.cos(er) - np.tan(br) * np.sin(er), np.cos(lr))) % 360.0
    dec = np.degrees(np.arcsin(np.sin(br) * np.cos(er) + np.cos(br) * np.sin(er) * np.sin(lr)))

    # sidereal time (UT) and the observer's geocentric position, equatorial frame of date
    lst = np.radians((mean_sidereal_time_deg(days_ut) + dpsi * np.cos(er) + lon) % 360.0)
    phi = np.radians(lat)
    a = EARTH_EQUATORIAL_RADIUS_KM
    e2 = EARTH_FLATTENING * (2.0 - EARTH_FLATTENING)
    n = a / np.sqrt(1.0 - e2 * np.sin(phi) ** 2)
    h = alt / 1000.0
    rho_cos = (n + h) * np.cos(phi)
    rho_sin = (n * (1.0 - e2) + h) * np.sin(phi)
    obs = np.stack([rho_cos * np.cos(lst), rho_cos * np.sin(lst), rho_sin], axis=-1)
    moon_geo = dist[..., None] * _equatorial_unit(ra, dec)
    topo = moon_geo - obs
    d_topo = np.linalg.norm(topo, axis=-1)
    u = topo / d_topo[..., None]
    # local frame: east, north, up at geodetic latitude phi and local sidereal time lst
    east = np.stack([-np.sin(lst), np.cos(lst), np.zeros_like(lst)], axis=-1)
    north = np.stack([-np.sin(phi) * np.cos(lst), -np.sin(phi) * np.sin(lst), np.cos(phi)], axis=-1)
    up = np.stack([np.cos(phi) * np.cos(lst), np.cos(phi) * np.sin(lst), np.sin(phi)], axis=-1)
    ue, un, uu = (np.sum(u * east, -1), np.sum(u * north, -1), np.sum(u * up, -1))
    azimuth = np.degrees(np.arctan2(ue, un)) % 360.0
    azimuth = np.where(azimuth >= 360.0, azimuth - 360.0, azimuth)
    true_el = np.degrees(np.arcsin(np.clip(uu, -1.0, 1.0)))
    if refraction:
        refr = refraction_correction(true_el, pressure_hpa, temperature_c)
    else:
        refr = np.zeros_like(true_el)
    elevation = np.minimum(true_el + refr, 90.0)

    # the sun (geocentric apparent; its parallax, 8.8", is negligible here)
    sp = solar_position(0.0, 0.0, t)
    sun_vec = (np.asarray(sp.earth_sun_distance_au) * ASTRONOMICAL_UNIT_KM)[..., None] * _equatorial_unit(
        sp.right_ascension_deg, sp.declination_deg)
    to_sun = sun_vec - topo
    to_obs = -topo
    cos_i = np.sum(to_sun * to_obs, -1) / (np.linalg.norm(to_sun, axis=-1) * d_topo)
    phase = np.degrees(np.arccos(np.clip(cos_i, -1.0, 1.0)))
    cos_elong = np.sum(sun_vec * topo, -1) / (np.linalg.norm(sun_vec, axis=-1) * d_topo)
    elong = np.degrees(np.arccos(np.clip(cos_elong, -1.0, 1.0)))
    # the sun's apparent ecliptic longitude, from its apparent RA/Dec and the true obliquity
    sa, sd = np.radians(sp.right_ascension_deg), np.radians(sp.declination_deg)
    sun_lam = np.degrees(np.arctan2(np.sin(sa) * np.cos(er) + np.tan(sd) * np.sin(er), np.cos(sa)))
    waxing = ((lam_app - sun_lam) % 360.0) < 180.0
    sun_moon_au = np.linalg.norm(sun_vec - moon_geo, axis=-1) / ASTRONOMICAL_UNIT_KM

    def out(x):
        return np.asarray(x)[()]

    return MoonPosition(
        time_utc=out(t),
        elevation_deg=out(elevation),
        azimuth_deg=out(azimuth),
        true_elevation_deg=out(true_el),
        refraction_deg=out(refr),
        distance_km=out(d_topo),
        geocentric_distance_km=out(dist),
        right_ascension_deg=out(ra),
        declination_deg=out(dec),
        ecliptic_longitude_deg=out(lam_app),
        ecliptic_latitude_deg=out(beta),
        angular_radius_deg=out(np.degrees(np.arcsin(MOON_RADIUS_KM / d_topo))),
        phase_angle_deg=out(phase),
        illuminated_fraction=out(0.5 * (1.0 + np.cos(np.radians(phase)))),
        elongation_deg=out(elong),
        waxing=out(waxing),
        sun_selenographic_longitude_deg=out(np.where(waxing, phase, -phase)),
        sun_moon_distance_au=out(sun_moon_au),
    )


def disc_solid_angle_sr(distance_km) -> np.ndarray:
    """Solid angle (sr) of the lunar disc seen from ``distance_km`` (300000-420000 km)."""
    d = check_array_range("distance_km", distance_km, 300_000.0, 420_000.0, "km")
    return (2.0 * math.pi * (1.0 - np.cos(np.arcsin(MOON_RADIUS_KM / d))))[()]
