"""The sun: position against NREL's SPA (pvlib, a test-only oracle), the disc, limb darkening
(Neckel & Labs 1994) and the ASTM G173-03 extraterrestrial spectrum against its source file."""

import datetime as dt
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skymodel import sun
from skymodel.errors import SkymodelInputError
from skymodel.data import DATA_DIR, csv_columns
from skymodel.wavelengths import default_wavelengths

try:  # test-only oracle; the limb-darkening tests run without it
    import pandas as pd
    import pvlib
    from pvlib import solarposition
except ImportError:  # pragma: no cover
    pd = pvlib = solarposition = None

needs_pvlib = pytest.mark.skipif(pvlib is None, reason="pvlib (test oracle) is not installed")

_trapz = np.trapz if hasattr(np, "trapz") else np.trapezoid

TOLERANCE_DEG = 0.05


# ----------------------------------------------------------------------------- helpers


def random_points(seed, n, first_year, last_year):
    rng = np.random.default_rng(seed)
    lat = rng.uniform(-90.0, 90.0, n)
    lon = rng.uniform(-180.0, 180.0, n)
    t0 = np.datetime64(f"{first_year}-01-01T00:00:00", "s")
    t1 = np.datetime64(f"{last_year}-12-31T23:59:59", "s")
    span = (t1 - t0).astype(np.int64)
    times = t0 + (rng.uniform(0.0, 1.0, n) * span).astype(np.int64).astype("timedelta64[s]")
    return lat, lon, times


def spa(lat, lon, times, **kw):
    """pvlib SPA, one row per (lat, lon, time) point. delta_t=None: pvlib's own delta-T model
    for each year (SPA evaluates the sun at TT = UT + delta-T)."""
    index = pd.DatetimeIndex(np.atleast_1d(times), tz="UTC")
    return solarposition.spa_python(index, lat, lon, delta_t=None, **kw)


def angular_errors(pos, ref):
    """|d elevation|, |d azimuth| * cos(elevation), and the angle between the two directions.

    The azimuth difference is weighted by cos(elevation), the great-circle length of an
    azimuth step: near the zenith the azimuth is ill-defined (any azimuth is the same
    direction), and a raw azimuth difference there would measure nothing physical."""
    el_ref = ref["elevation"].to_numpy()
    az_ref = ref["azimuth"].to_numpy()
    d_el = np.abs(pos.elevation_deg - el_ref)
    d_az = np.abs((pos.azimuth_deg - az_ref + 180.0) % 360.0 - 180.0) * np.cos(np.radians(el_ref))
    a1, e1 = np.radians(pos.azimuth_deg), np.radians(pos.elevation_deg)
    a2, e2 = np.radians(az_ref), np.radians(el_ref)
    cos_sep = np.sin(e1) * np.sin(e2) + np.cos(e1) * np.cos(e2) * np.cos(a1 - a2)
    sep = np.degrees(np.arccos(np.clip(cos_sep, -1.0, 1.0)))
    return d_el, d_az, sep


# ----------------------------------------------------------------------------- position


@needs_pvlib
def test_vectorised_spa_oracle_matches_pointwise_calls():
    # the oracle is called once with arrays of latitude/longitude (one per time); make sure
    # that equals calling spa_python point by point as documented
    lat, lon, times = random_points(7, 5, 1950, 2050)
    whole = spa(lat, lon, times)
    for i in range(5):
        one = spa(lat[i], lon[i], times[i : i + 1])
        assert one["elevation"].iloc[0] == pytest.approx(whole["elevation"].iloc[i], abs=1e-12)
        assert one["azimuth"].iloc[0] == pytest.approx(whole["azimuth"].iloc[i], abs=1e-12)


@needs_pvlib
@pytest.mark.parametrize("first_year, last_year, n", [(1950, 2050, 2000), (1900, 2100, 500)])
def test_random_points_against_spa(first_year, last_year, n):
    lat, lon, times = random_points(20260621 + first_year, n, first_year, last_year)
    pos = sun.solar_position(lat, lon, times)
    ref = spa(lat, lon, times)
    d_el, d_az, sep = angular_errors(pos, ref)
    print(f"{first_year}-{last_year}, {n} points: max |d el| {d_el.max():.4f} deg, "
          f"max |d az| cos(el) {d_az.max():.4f} deg, max separation {sep.max():.4f} deg")
    assert d_el.max() < TOLERANCE_DEG
    assert d_az.max() < TOLERANCE_DEG
    assert sep.max() < TOLERANCE_DEG
    # away from the zenith the raw azimuth is well defined and close too
    low = ref["elevation"].to_numpy() < 80.0
    d_az_raw = np.abs((pos.azimuth_deg - ref["azimuth"].to_numpy() + 180.0) % 360.0 - 180.0)
    assert d_az_raw[low].max() < 5 * TOLERANCE_DEG


@needs_pvlib
def test_zaragoza_midsummer_noon():
    pos = sun.solar_position(41.65, -0.88, "2026-06-21T12:00:00Z")
    ref = spa(41.65, -0.88, np.datetime64("2026-06-21T12:00:00"))
    assert pos.elevation_deg == pytest.approx(ref["elevation"].iloc[0], abs=TOLERANCE_DEG)
    assert pos.elevation_deg == pytest.approx(71.7, abs=0.1)  # the figure quoted in the brief
    assert pos.azimuth_deg == pytest.approx(ref["azimuth"].iloc[0], abs=TOLERANCE_DEG / np.cos(np.radians(71.7)))
    assert 170.0 < pos.azimuth_deg < 185.0  # due south, just before local noon (12:04 UTC there)


@needs_pvlib
def test_poles_and_zenith_sun():
    times = np.arange("2024-01-01", "2024-12-31", 7, dtype="datetime64[D]").astype("datetime64[s]")
    for lat, lon in [(90.0, 0.0), (-90.0, 123.0)]:
        pos = sun.solar_position(lat, lon, times)
        d_el, d_az, sep = angular_errors(pos, spa(lat, lon, times))
        assert max(d_el.max(), d_az.max(), sep.max()) < TOLERANCE_DEG
    # the sun overhead: put the observer at the sub-solar point
    t = np.datetime64("2025-03-01T10:00:00")
    p0 = sun.solar_position(0.0, 0.0, t)
    lon = -p0.hour_angle_deg  # local hour angle 0 there
    overhead = sun.solar_position(p0.declination_deg, lon, t)
    assert overhead.true_elevation_deg > 89.99
    ref = spa(p0.declination_deg, lon, t)
    _, _, sep = angular_errors(overhead, ref)
    assert sep.max() < TOLERANCE_DEG


@needs_pvlib
def test_refraction_against_spa_apparent_elevation():
    lat, lon, times = random_points(99, 2000, 1950, 2050)
    pressure_hpa, temperature_c = 1000.0, 5.0
    pos = sun.solar_position(lat, lon, times, refraction=True, pressure_hpa=pressure_hpa, temperature_c=temperature_c)
    ref = spa(lat, lon, times, pressure=pressure_hpa * 100.0, temperature=temperature_c)
    true_el = ref["elevation"].to_numpy()
    # above about -1 degree, away from the cut-off where the correction switches on (both
    # implementations apply it from the sun's upper limb on the apparent horizon, -0.833 deg)
    ok = (true_el > -1.0) & (np.abs(true_el - sun.REFRACTION_CUTOFF_DEG) > 0.05)
    assert ok.sum() > 800
    d = np.abs(pos.elevation_deg - ref["apparent_elevation"].to_numpy())[ok]
    print(f"apparent elevation: max |d| {d.max():.4f} deg over {ok.sum()} points")
    assert d.max() < TOLERANCE_DEG
    assert np.allclose(pos.zenith_deg, 90.0 - pos.elevation_deg)
    assert np.allclose(pos.elevation_deg, pos.true_elevation_deg + pos.refraction_deg)
    # Saemundsson's formula: about 0.48 deg (29') at the horizon for 1013 hPa and 15 degC, 1' at
    # 45 deg, nothing once the disc is wholly below the horizon
    assert sun.refraction_correction(0.0) == pytest.approx(0.48, abs=0.01)
    assert sun.refraction_correction(-3.0) == 0.0
    assert sun.refraction_correction(45.0) == pytest.approx(1.0 / 60.0, rel=0.1)


@needs_pvlib
def test_earth_sun_distance_and_equation_of_time_against_spa():
    times = pd.date_range("1950-01-01", "2050-12-31", periods=1500, tz="UTC")
    naive = times.tz_convert(None).to_numpy()
    pos = sun.solar_position(0.0, 0.0, naive)
    dist = solarposition.nrel_earthsun_distance(times, delta_t=None).to_numpy()
    assert np.abs(pos.earth_sun_distance_au - dist).max() < 2e-4  # low-precision orbit, no lunar term
    eot = solarposition.spa_python(times, 0.0, 0.0, delta_t=None)["equation_of_time"].to_numpy()
    assert np.abs(pos.equation_of_time_min - eot).max() < 0.1  # minutes


@needs_pvlib
def test_time_input_forms_agree():
    expected = sun.solar_position(10.0, 20.0, np.datetime64("2026-06-21T12:00:00"))
    forms = [
        "2026-06-21T12:00:00Z",
        "2026-06-21T14:00:00+02:00",
        "2026-06-21 12:00",
        dt.datetime(2026, 6, 21, 12, 0),  # naive: UTC
        dt.datetime(2026, 6, 21, 7, 0, tzinfo=dt.timezone(dt.timedelta(hours=-5))),
        pd.Timestamp("2026-06-21T12:00:00Z"),
        pd.Timestamp("2026-06-21T08:00:00", tz="America/New_York"),
    ]
    for form in forms:
        pos = sun.solar_position(10.0, 20.0, form)
        assert pos.elevation_deg == pytest.approx(expected.elevation_deg, abs=1e-9), form
        assert pos.azimuth_deg == pytest.approx(expected.azimuth_deg, abs=1e-9), form
        assert pos.time_utc == np.datetime64("2026-06-21T12:00:00")
    assert np.ndim(expected.elevation_deg) == 0
    # arrays and lists, broadcasting against array latitudes
    times = np.array(["2026-06-21T06:00", "2026-06-21T12:00", "2026-06-21T18:00"], dtype="datetime64[s]")
    as_list = ["2026-06-21T06:00:00Z", dt.datetime(2026, 6, 21, 12), np.datetime64("2026-06-21T18:00")]
    a = sun.solar_position(10.0, 20.0, times)
    b = sun.solar_position(10.0, 20.0, as_list)
    assert a.elevation_deg.shape == (3,)
    np.testing.assert_allclose(a.elevation_deg, b.elevation_deg, atol=1e-9)
    grid = sun.solar_position(np.array([-30.0, 0.0, 30.0])[:, None], 20.0, times[None, :])
    assert grid.elevation_deg.shape == (3, 3)
    np.testing.assert_allclose(grid.elevation_deg[1], sun.solar_position(0.0, 20.0, times).elevation_deg)
    tz_index = pd.DatetimeIndex(times).tz_localize("UTC").tz_convert("Asia/Tokyo")
    np.testing.assert_allclose(sun.solar_position(10.0, 20.0, tz_index).elevation_deg, a.elevation_deg, atol=1e-9)


def test_direction_and_disc_size():
    pos = sun.solar_position(41.65, -0.88, "2026-01-03T12:00:00Z")  # near perihelion
    v = pos.direction_enu()
    assert v.shape == (3,)
    assert np.linalg.norm(v) == pytest.approx(1.0)
    assert np.degrees(np.arcsin(v[2])) == pytest.approx(pos.elevation_deg)
    # 0.26645 deg from the IAU nominal radius (0.2666 is the older 696,000 km radius)
    assert sun.SUN_ANGULAR_RADIUS_DEG == pytest.approx(np.degrees(np.arcsin(695_700 / 149_597_870.7)))
    assert sun.SUN_ANGULAR_RADIUS_DEG == pytest.approx(0.2665, abs=2e-4)
    assert sun.sun_angular_radius_deg(1.0) == pytest.approx(sun.SUN_ANGULAR_RADIUS_DEG)
    assert pos.earth_sun_distance_au == pytest.approx(0.9833, abs=3e-4)
    assert pos.angular_radius_deg == pytest.approx(sun.sun_angular_radius_deg(pos.earth_sun_distance_au))
    assert pos.angular_radius_deg > sun.SUN_ANGULAR_RADIUS_DEG


T0 = "2026-01-01T00:00Z"


@pytest.mark.parametrize(
    "latitude, longitude, time, parameter, allowed",
    [
        (90.5, 0.0, T0, "latitude_deg", "[-90, 90]"),
        ([0.0, np.nan], 0.0, T0, "latitude_deg", "[-90, 90]"),
        (0.0, -180.5, T0, "longitude_deg", "[-180, 180]"),
        (0.0, "east", T0, "longitude_deg", "[-180, 180]"),
        (0.0, 0.0, "yesterday at noon", "time_utc", "ISO 8601"),
        (0.0, 0.0, "2026-13-01T00:00", "time_utc", "ISO 8601"),
        (0.0, 0.0, 1750000000.0, "time_utc", "datetime"),
        (0.0, 0.0, np.datetime64("NaT"), "time_utc", "datetime"),
        (0.0, 0.0, "1850-06-01T00:00Z", "time_utc", "1900-2100"),
        (0.0, 0.0, dt.datetime(2150, 1, 1), "time_utc", "1900-2100"),
        ([0.0, 1.0], 0.0, [T0] * 3, "time_utc", "broadcasts"),
    ],
)
def test_bad_position_input_names_the_parameter(latitude, longitude, time, parameter, allowed):
    with pytest.raises(SkymodelInputError) as err:
        sun.solar_position(latitude, longitude, time)
    assert err.value.parameter == parameter
    assert str(err.value).startswith(parameter)
    assert allowed in err.value.allowed


def test_bad_refraction_conditions():
    with pytest.raises(SkymodelInputError) as err:
        sun.solar_position(0.0, 0.0, "2026-01-01T00:00Z", refraction=True, pressure_hpa=-5.0)
    assert err.value.parameter == "pressure_hpa"


# ----------------------------------------------------------------------------- limb darkening


def test_limb_darkening_table_is_self_consistent():
    cols = csv_columns("sources/sun/limb_darkening.csv")
    a = np.stack([cols[f"a{k}"] for k in range(6)], axis=1)
    integral = a @ (2.0 / (np.arange(6) + 2.0))
    # the 365.875 nm row fails both checks (see the CSV header); it is outside 380-780 nm
    good = cols["wavelength_nm"] != 365.875
    assert np.abs(a.sum(axis=1) - 1.0)[good].max() < 3e-5
    assert np.abs(integral - cols["disc_mean_to_centre"])[good].max() < 1e-4
    # the function reproduces the tabulated ratio at the table's own wavelengths
    in_range = (cols["wavelength_nm"] >= 380.0) & (cols["wavelength_nm"] <= 780.0)
    wl = cols["wavelength_nm"][in_range]
    np.testing.assert_allclose(sun.disc_mean_to_centre_ratio(wl), cols["disc_mean_to_centre"][in_range], atol=1e-4)


def test_limb_darkening_shape_and_behaviour():
    wl = np.array([400.0, 550.0, 700.0])
    mu = np.linspace(0.0, 1.0, 101)
    ld = sun.limb_darkening(wl, mu)
    assert ld.shape == (101, 3)
    np.testing.assert_allclose(ld[-1], 1.0, atol=1e-12)
    assert np.all(np.diff(ld, axis=0) > 0)  # darker towards the limb at every wavelength
    assert np.all(ld[0] > 0.1) and np.all(ld[0] < 0.5)
    at_02 = sun.limb_darkening([400.0, 700.0], 0.2)
    assert at_02.shape == (2,)
    assert at_02[0] < at_02[1]  # stronger darkening in the blue
    ratio = sun.disc_mean_to_centre_ratio(wl)
    assert np.all(np.diff(ratio) > 0) and 0.7 < ratio[0] < ratio[-1] < 0.86
    # ratio = 2 * integral I(mu) mu dmu, numerically
    fine = np.linspace(0.0, 1.0, 2001)
    integral = 2.0 * _trapz(sun.limb_darkening(wl, fine) * fine[:, None], fine, axis=0)
    np.testing.assert_allclose(integral, ratio, rtol=1e-6)
    with pytest.raises(SkymodelInputError) as err:
        sun.limb_darkening(wl, 1.2)
    assert err.value.parameter == "mu"
    with pytest.raises(SkymodelInputError) as err:
        sun.limb_darkening([300.0], 0.5)
    assert err.value.parameter == "wavelengths"


def test_disc_radiance_integrates_back_to_irradiance():
    wl = default_wavelengths()
    alpha = np.radians(sun.SUN_ANGULAR_RADIUS_DEG)
    r = np.linspace(0.0, 1.0, 4001)  # fraction of the disc radius
    mu = np.sqrt(1.0 - r**2)
    radiance = sun.sun_disc_radiance(wl, mu)
    e = 2.0 * np.pi * alpha**2 * _trapz(radiance * r[:, None], r, axis=0)  # small-angle disc integral
    np.testing.assert_allclose(e, sun.solar_irradiance(wl), rtol=2e-3)


# ----------------------------------------------------------------------------- spectrum


def pvlib_astm_g173():
    path = Path(pvlib.__file__).parent / "data" / "ASTMG173.csv"
    data = np.genfromtxt(path, delimiter=",", skip_header=2)
    return data[:, 0], data[:, 1]


@needs_pvlib
def test_shipped_spectrum_equals_the_astm_table():
    src_wl, src_e = pvlib_astm_g173()
    wl, e = sun.native_solar_spectrum()
    assert wl[0] <= 350.0 and wl[-1] >= 800.0
    sel = (src_wl >= wl[0]) & (src_wl <= wl[-1])
    np.testing.assert_array_equal(wl, src_wl[sel])
    np.testing.assert_array_equal(e, src_e[sel])
    # native values at 500, 600, 700 nm, read from the source file (1.916, 1.770, 1.422)
    probe = np.array([500.0, 600.0, 700.0])
    expected = np.interp(probe, src_wl, src_e)
    np.testing.assert_allclose(sun.solar_irradiance(probe, bandwidth_nm=0.0), expected, rtol=1e-12)
    np.testing.assert_allclose(expected, [1.916, 1.770, 1.422], atol=5e-4)


@needs_pvlib
@pytest.mark.parametrize("step", [1.0, 5.0, 10.0, 20.0])
def test_band_means_conserve_the_380_780_integral(step):
    src_wl, src_e = pvlib_astm_g173()
    m = (src_wl >= 380.0) & (src_wl <= 780.0)
    native = _trapz(src_e[m], src_wl[m])
    wl = np.arange(380.0, 780.0 + 0.5 * step, step)
    coarse = _trapz(sun.solar_irradiance(wl), wl)
    assert coarse == pytest.approx(native, rel=5e-3)


@needs_pvlib
def test_band_mean_definition_and_scaling():
    src_wl, src_e = pvlib_astm_g173()
    wl = np.arange(380.0, 781.0, 5.0)
    e5 = sun.solar_irradiance(wl)
    # the value at 500 nm is the mean of the native table over 497.5-502.5 nm
    fine = np.linspace(497.5, 502.5, 5001)
    assert e5[wl == 500.0][0] == pytest.approx(_trapz(np.interp(fine, src_wl, src_e), fine) / 5.0, rel=1e-6)
    # smoother than the native samples: 5 nm means vary less from one sample to the next
    native_at_grid = sun.solar_irradiance(wl, bandwidth_nm=0.0)
    assert np.std(np.diff(e5)) < np.std(np.diff(native_at_grid))
    np.testing.assert_array_equal(sun.default_bandwidths(wl), 5.0)
    assert sun.default_bandwidths([550.0])[0] == 1.0
    np.testing.assert_allclose(sun.solar_irradiance(wl, bandwidth_nm=5.0), e5)
    # 1 / d^2, with array distances adding a leading axis
    e = sun.solar_irradiance(wl, distance_au=[0.9833, 1.0, 1.0167])
    assert e.shape == (3, wl.size)
    np.testing.assert_allclose(e[0], e5 / 0.9833**2)
    np.testing.assert_allclose(e[2], e5 / 1.0167**2)


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        (dict(wavelengths_nm=[300.0]), "wavelengths"),
        (dict(wavelengths_nm=[500.0], distance_au=1.5), "distance_au"),
        (dict(wavelengths_nm=[500.0], bandwidth_nm=-1.0), "bandwidth_nm"),
        (dict(wavelengths_nm=[500.0], bandwidth_nm=150.0), "bandwidth_nm"),
        (dict(wavelengths_nm=[500.0, 600.0], bandwidth_nm=[1.0, 2.0, 3.0]), "bandwidth_nm"),
    ],
)
def test_bad_spectrum_input_names_the_parameter(kwargs, parameter):
    with pytest.raises(SkymodelInputError) as err:
        sun.solar_irradiance(**kwargs)
    assert err.value.parameter == parameter


@needs_pvlib
def test_spectrum_csv_reproduces_from_the_extraction_script(tmp_path):
    script = DATA_DIR / "generated" / "make_solar_spectrum.py"
    out = tmp_path / "spectrum.csv"
    subprocess.run([sys.executable, str(script), "--output", str(out)], check=True, capture_output=True)
    assert out.read_bytes() == (DATA_DIR / "generated" / "solar_spectrum_astm_g173.csv").read_bytes()
