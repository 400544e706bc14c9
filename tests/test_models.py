"""The alternative sky models (skymodel.models) and `skymodel compare`.

Reference numbers are recomputed here from the papers' printed formulas and constants
(typed in again, independently of skymodel/data/sources/models/*.toml), so a transcription error in a
table or a formula makes a test fail."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.colorimetry import spectral_to_rgb, spectral_to_xyz
from skymodel.errors import SkymodelInputError
from skymodel.models import SkyScene, get_model, model_names, parse_model_list
from skymodel.models import cie, openspace, preetham
from skymodel.render.rays import direction_from_angles

WL = np.arange(380.0, 781.0, 20.0)
HAS_BPY = importlib.util.find_spec("bpy") is not None


# ------------------------------------------------------------------ Preetham et al. 1999
# Appendix A.2 of the paper, (slope, intercept) in T for the luminance Y
PAPER_Y = {"A": (0.1787, -1.4630), "B": (-0.3554, 0.4275), "C": (-0.0227, 5.3251),
           "D": (0.1206, -2.5771), "E": (-0.0670, 0.3703)}
PAPER_X = {"A": (-0.0193, -0.2592), "B": (-0.0665, 0.0008), "C": (-0.0004, 0.2125),
           "D": (-0.0641, -0.8989), "E": (-0.0033, 0.0452)}
PAPER_YC = {"A": (-0.0167, -0.2608), "B": (-0.0950, 0.0092), "C": (-0.0079, 0.2102),
            "D": (-0.0441, -1.6537), "E": (-0.0109, 0.0529)}


def _perez(theta, gamma, c):
    return (1 + c["A"] * math.exp(c["B"] / math.cos(theta))) * (1 + c["C"] * math.exp(c["D"] * gamma)
                                                                + c["E"] * math.cos(gamma) ** 2)


@pytest.mark.parametrize("T", [2.0, 3.0, 6.0])
def test_preetham_perez_coefficients_match_the_paper(T):
    co = preetham.perez_coefficients(T)
    for key, tab in (("Y", PAPER_Y), ("x", PAPER_X), ("y", PAPER_YC)):
        expect = [tab[k][0] * T + tab[k][1] for k in "ABCDE"]
        np.testing.assert_allclose(co[key], expect, rtol=0, atol=1e-12)


@pytest.mark.parametrize("T, sun_zenith_deg", [(2.0, 30.0), (3.0, 60.0), (5.0, 80.0)])
def test_preetham_zenith_luminance_and_distribution(T, sun_zenith_deg):
    ts = math.radians(sun_zenith_deg)
    chi = (4.0 / 9.0 - T / 120.0) * (math.pi - 2.0 * ts)
    yz = (4.0453 * T - 4.9710) * math.tan(chi) - 0.2155 * T + 2.4192
    assert preetham.zenith_luminance_kcd(T, ts) == pytest.approx(yz, rel=1e-12)
    # the Perez ratio at a few (theta, gamma), and exactly Y_z at the zenith
    c = {k: PAPER_Y[k][0] * T + PAPER_Y[k][1] for k in "ABCDE"}
    for theta_deg, gamma_deg in ((0.0, sun_zenith_deg), (45.0, 20.0), (70.0, 120.0), (85.0, 95.0)):
        th, ga = math.radians(theta_deg), math.radians(gamma_deg)
        x, y, Y = preetham.sky_xyY(T, ts, np.array([th]), np.array([ga]))
        assert Y[0] == pytest.approx(yz * _perez(th, ga, c) / _perez(0.0, ts, c), rel=1e-9)


def test_preetham_zenith_chromaticity_matches_the_paper():
    # x_z = [T^2 T 1] M_x [t^3 t^2 t 1]^T with the paper's printed matrices
    mx = [[0.00166, -0.00375, 0.00209, 0.0], [-0.02903, 0.06377, -0.03202, 0.00394],
          [0.11693, -0.21196, 0.06052, 0.25886]]
    my = [[0.00275, -0.00610, 0.00317, 0.0], [-0.04214, 0.08970, -0.04153, 0.00516],
          [0.15346, -0.26756, 0.06670, 0.26688]]
    for T, tsd in ((2.0, 10.0), (4.0, 50.0), (8.0, 75.0)):
        t = math.radians(tsd)
        tv, sv = [T * T, T, 1.0], [t**3, t**2, t, 1.0]
        ex = sum(tv[i] * mx[i][j] * sv[j] for i in range(3) for j in range(4))
        ey = sum(tv[i] * my[i][j] * sv[j] for i in range(3) for j in range(4))
        assert preetham.zenith_chromaticity(T, t) == pytest.approx((ex, ey), abs=1e-12)
        # a clear zenith is bluish white: on the blue side of D65
        if T <= 4.0:
            assert ex < 0.3127 and ey < 0.3290


@pytest.mark.parametrize("xy", [(0.3127, 0.3290), (0.3457, 0.3585), (0.2800, 0.2900)])
def test_daylight_basis_spectrum_has_the_asked_luminance_and_colour(xy):
    L = preetham.spectral_radiance_from_xyY(xy[0], xy[1], 2.5, WL)
    xyz = spectral_to_xyz(L, WL)
    assert 683.002 * xyz[1] == pytest.approx(2500.0, rel=1e-9)
    # the daylight basis reproduces chromaticities on (and near) the daylight locus
    assert xyz[0] / xyz.sum() == pytest.approx(xy[0], abs=3e-3)
    assert xyz[1] / xyz.sum() == pytest.approx(xy[1], abs=3e-3)


def test_preetham_sun_transmittance():
    # Kasten's air mass: ~1 overhead, finite (~36-38) at the horizon
    assert preetham.relative_optical_mass(0.0) == pytest.approx(1.0, abs=1e-3)
    assert 35.0 < float(preetham.relative_optical_mass(math.pi / 2)) < 39.0
    total, parts = preetham.sun_transmittance(2.0, 0.0, [500.0, 600.0], components=True)
    m = float(preetham.relative_optical_mass(0.0))
    assert parts["rayleigh"][0] == pytest.approx(math.exp(-0.008735 * 0.5**-4.08 * m), rel=1e-12)
    beta = 0.04608365822050 * 2.0 - 0.04586025928522
    assert parts["aerosol"][1] == pytest.approx(math.exp(-beta * 0.6**-1.3 * m), rel=1e-12)
    assert parts["ozone"][1] == pytest.approx(math.exp(-0.125 * 0.35 * m), rel=1e-12)  # k_o(600) = 0.125 /cm
    # a lower sun and a hazier sky both dim and redden the beam
    high = preetham.sun_transmittance(2.0, 0.0, [450.0, 650.0])
    low = preetham.sun_transmittance(2.0, math.radians(80.0), [450.0, 650.0])
    hazy = preetham.sun_transmittance(6.0, 0.0, [450.0, 650.0])
    for t in (low, hazy):
        assert np.all(t < high) and t[0] / t[1] < high[0] / high[1]


def test_preetham_turbidity_from_aod_and_range():
    assert preetham.turbidity_from_aod(0.1007) == pytest.approx(2.0, abs=0.01)
    with pytest.raises(SkymodelInputError, match="sun_elevation"):
        get_model("preetham")(SkyScene(Atmosphere(location="rural"), -2.0, wavelengths_nm=WL), [[0, 0, 1]])


def test_preetham_aerial_perspective_limits():
    f0, l0 = preetham.aerial_perspective(0.0, 90.0, 90.0, 3.0, WL, 40.0)
    np.testing.assert_allclose(f0, 1.0)
    np.testing.assert_allclose(l0, 0.0, atol=1e-30)
    f1, l1 = preetham.aerial_perspective(20000.0, 90.0, 90.0, 3.0, WL, 40.0)
    assert np.all(np.diff(f1) > 0)  # blue is lost first
    assert np.all(l1 > 0)


# ------------------------------------------------------------------ CIE standard general sky
def test_cie_type12_parameters_and_formula():
    a, b, c, d, e = cie.sky_type_parameters(12)
    assert (a, b, c, d, e) == (-1.0, -0.32, 10.0, -3.0, 0.45)
    zs = math.radians(40.0)
    for z_deg, chi_deg in ((30.0, 10.0), (60.0, 90.0), (80.0, 150.0), (45.0, 40.0)):
        z, chi = math.radians(z_deg), math.radians(chi_deg)
        f = lambda x: 1 + 10.0 * (math.exp(-3.0 * x) - math.exp(-3.0 * math.pi / 2)) + 0.45 * math.cos(x) ** 2
        phi = lambda x: 1 - math.exp(-0.32 / math.cos(x))
        expect = f(chi) * phi(z) / (f(zs) * phi(0.0))
        assert float(cie.relative_luminance(z, chi, zs, 12)) == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("sun_elev", [5.0, 30.0, 75.0])
def test_cie_zenith_is_one_and_horizon_gradation(sun_elev):
    scene = SkyScene(Atmosphere(location="rural"), sun_elev, wavelengths_nm=WL)
    d = direction_from_angles([0.0, 90.0 - 1e-9, 60.0], [0.0, 0.0, 180.0])
    r = get_model("cie12")(scene, d)
    assert r.kind == "relative" and not r.is_absolute
    assert r.luminance()[0] == pytest.approx(1.0, rel=1e-12)
    # overcast type 1 (Moon & Spencer): zenith 3x brighter than the horizon
    r1 = get_model("cie1")(scene, d)
    assert r1.luminance()[0] / r1.luminance()[1] == pytest.approx(3.0, rel=0.02)


def test_cie_rejects_unknown_types_and_names():
    with pytest.raises(SkymodelInputError, match="sky_type"):
        cie.sky_type_parameters(16)
    with pytest.raises(SkymodelInputError, match="models"):
        parse_model_list("ours,nonsense")


# ------------------------------------------------------------------ OpenSpace (Costa et al.)
def test_penndorf_phase_is_rayleigh_with_depolarisation_0035():
    prof = openspace.openspace_profile("earth", [550.0], n_altitudes=32)
    mu = np.linspace(-1, 1, 9)
    np.testing.assert_allclose(prof.rayleigh_phase(mu)[:, 0], openspace.penndorf_phase(mu), rtol=2e-4)
    # both phase functions integrate to 1 over the sphere
    from skymodel.numerics import trapezoid

    m = np.linspace(-1, 1, 20001)
    assert 2 * np.pi * trapezoid(openspace.penndorf_phase(m), m) == pytest.approx(1.0, abs=2e-4)
    assert 2 * np.pi * trapezoid(openspace.double_hg(m, 0.67, 0.094, 0.743), m) == pytest.approx(1.0, abs=2e-3)


def test_openspace_profiles():
    e = openspace.openspace_profile("earth", WL, aod550=0.1, ozone_du=300.0)
    mars = openspace.openspace_profile("mars", WL)
    assert e.planet_radius_m == 6_377_000.0 and e.top_altitude_m == pytest.approx(70_000.0)
    assert mars.planet_radius_m == 3_386_190.0 and mars.top_altitude_m == pytest.approx(76_984.95, abs=0.1)
    # Earth's Rayleigh at sea level within 3 % of our Bucholtz cross section x standard air
    from skymodel.optics import rayleigh

    ours = rayleigh.scattering_coefficient(np.array([0.0]), WL)[0]
    np.testing.assert_allclose(e.rayleigh_scattering[0], ours, rtol=0.03)
    # optical depths: the asked AOD and ozone column; Mars' thin CO2 sky
    j = int(np.argmin(abs(WL - 540)))
    tau = e.vertical_optical_depth(e.aerosol_scattering + e.aerosol_absorption)
    assert float(np.interp(550, WL, tau)) == pytest.approx(0.1, rel=2e-3)
    assert e.metadata["ozone_du"] == 300.0
    assert np.argmax(e.vertical_optical_depth(e.ozone_absorption)) in range(j - 3, j + 4)  # Chappuis band
    tau_r_mars = float(np.interp(550, WL, mars.vertical_optical_depth(mars.rayleigh_scattering)))
    assert 0.001 < tau_r_mars < 0.01
    assert mars.solar_irradiance[10] == pytest.approx(e.solar_irradiance[10] / 1.5237**2, rel=1e-12)
    with pytest.raises(SkymodelInputError, match="planet"):
        openspace.openspace_profile("venus", WL)


def _xy(xyz):
    return xyz[:, 0] / xyz.sum(axis=1), xyz[:, 1] / xyz.sum(axis=1)


def test_openspace_earth_blue_zenith_mars_butterscotch_day_blue_sunset():
    atm = Atmosphere(location="rural", month=6)
    # Earth, sun 30 degrees: a blue zenith
    day = SkyScene(atm, 30.0, wavelengths_nm=WL)
    d = direction_from_angles([0.0, 60.0], [0.0, 0.0])  # zenith; 60 deg from the zenith, opposite the sun
    e = get_model("openspace_earth")(day, d)
    x, y = _xy(e.xyz())
    assert x[0] < 0.29 and y[0] < 0.30
    rgb = spectral_to_rgb(e.values, WL)
    assert rgb[0, 2] > rgb[0, 1] > rgb[0, 0]
    # Mars by day: the sky away from the sun is butterscotch (red > green > blue, x > 0.33)
    m = get_model("openspace_mars")(day, d)
    x, y = _xy(m.xyz())
    rgb = spectral_to_rgb(m.values, WL)
    assert np.all(x > 0.33) and np.all(rgb[:, 0] > rgb[:, 1]) and np.all(rgb[:, 1] > rgb[:, 2])
    # Mars at sunset: blue around the sun (the dust's forward lobe is strongest in blue),
    # much less so 90 deg away at the same height
    dusk = SkyScene(atm, 2.0, wavelengths_nm=WL)
    d2 = direction_from_angles([84.0, 84.0], [180.0, 90.0])  # 6 deg up: toward the sun, 90 deg off
    m2 = get_model("openspace_mars")(dusk, d2)
    x2, _ = _xy(m2.xyz())
    rgb2 = spectral_to_rgb(m2.values, WL)
    assert rgb2[0, 2] > 2.0 * rgb2[0, 0]
    assert rgb2[0, 2] / rgb2[0, 0] > 2.0 * rgb2[1, 2] / rgb2[1, 0]
    assert x2[0] < 0.25 and x2[0] < x2[1]


def test_openspace_mars_observer_outside_the_atmosphere():
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.sky import quality_settings

    prof = openspace.openspace_profile("mars", WL)
    m = SkyMarcher(prof, 30.0, 180.0, 100_000.0, quality_settings("preview"))  # 23 km above the top
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    r = m.radiance(d)
    assert np.all(r.radiance[0] == 0.0)  # space above
    assert np.all(r.radiance[1] > 0.0)  # lit dusty ground and air below
    np.testing.assert_allclose(r.sun_irradiance, prof.solar_irradiance)  # nothing between the sun and us


# ------------------------------------------------------------------ registry and compare
def test_registry_names():
    names = model_names()
    for n in ("ours", "ours_single", "preetham", "openspace_earth", "openspace_mars", "cie12", "blender_multiple"):
        assert n in names
    with pytest.raises(SkymodelInputError, match="model"):
        get_model("hosek_2012")


def test_compare_command_tiny(tmp_path, capsys):
    from skymodel.cli import main
    import json

    out = tmp_path / "cmp.png"
    rc = main(["compare", "--location", "rural", "--month", "6", "--sun-elevation", "30", "--models",
               "ours,preetham,cie12,blender_hosek" if not HAS_BPY else "ours,preetham,cie12",
               "--size", "24", "--wavelength-step", "20", "--out", str(out), "--json", "--quiet"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert out.exists() and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert res["models"] == ["ours", "preetham", "cie12"]
    if not HAS_BPY:
        assert "bpy" in res["skipped"]["blender_hosek"]
    met = res["metrics"]
    assert met["ours"]["vs_ours_abs"]["max_abs"] == 0.0 and met["cie12"]["vs_cie12_rel"]["max_abs"] == 0.0
    # Preetham's luminance distribution is closer to the CIE clear sky than to a uniform sky
    assert met["preetham"]["vs_cie12_rel"]["rms"] < 1.0
    # every sample direction stays >= 10 degrees from the sun; the zenith is first
    assert res["sample_directions"]["view_zenith_deg"][0] == 0.0
    from skymodel.render.rays import sun_direction

    z = np.asarray(res["sample_directions"]["view_zenith_deg"][1:])
    a = np.asarray(res["sample_directions"]["relative_azimuth_deg"][1:])
    d = direction_from_angles(z, 180.0 + a)
    assert np.all(np.degrees(np.arccos(d @ sun_direction(30.0, 180.0))) >= 10.0)
    # the panels share ours' exposure even when ours is not drawn
    from skymodel.models.comparison import compare

    cmp = compare(Atmosphere(location="rural", month=6), 30.0, models="cie12,preetham", size=16,
                  wavelength_step_nm=20.0)
    assert cmp.models == ["cie12", "preetham"] and cmp.image.shape[1] == 2 * 16 + 2
    assert set(cmp.metrics) == {"cie12", "preetham", "ours"}
    # bad input names the parameter
    assert main(["compare", "--models", "ours,foo", "--out", str(tmp_path / "x.png"), "--quiet"]) == 2
    assert not (tmp_path / "x.png").exists()


@pytest.mark.skipif(not HAS_BPY, reason="needs bpy (Blender as a Python module)")
def test_blender_multiple_scattering_sky_tiny():
    from skymodel.models import blender_sky

    old = blender_sky.PANORAMA_WIDTH
    blender_sky.PANORAMA_WIDTH = 48
    try:
        scene = SkyScene(Atmosphere(location="rural", month=6), 30.0, wavelengths_nm=WL)
        d = direction_from_angles([0.0, 70.0, 70.0], [0.0, 160.0, 20.0])  # zenith, near the sun, away from it
        r = get_model("blender_multiple")(scene, d)
    finally:
        blender_sky.PANORAMA_WIDTH = old
    assert r.kind == "xyz" and r.info["panorama"] == (24, 48)
    x, y = _xy(r.xyz())
    assert x[0] < 0.30 and y[0] < 0.31  # a blue zenith
    L = r.luminance()
    assert L[1] > L[2]  # the sun is where we put it (brighter toward the sun)
    # same order of magnitude as ours at the zenith (matched air, aerosol and ozone)
    ours = get_model("ours")(scene, d[:1]).luminance()[0]
    assert 0.5 < L[0] / ours < 2.0


@pytest.mark.skipif(not HAS_BPY, reason="needs bpy (Blender as a Python module)")
@pytest.mark.parametrize("sky_type", ["PREETHAM", "HOSEK_WILKIE"])
def test_blender_legacy_skies_put_the_sun_in_the_middle_column(sky_type):
    from skymodel.models import blender_sky

    img = blender_sky.render_equirectangular(sky_type, 20.0, 32, turbidity=3.0)
    row = img[6].sum(axis=1)  # 22-34 degrees above the horizon (rows are 11.25 degrees)
    assert abs(int(np.argmax(row)) - 15.5) <= 1
    assert row.max() > 1.3 * row[0]  # a real circumsolar brightening, not noise
