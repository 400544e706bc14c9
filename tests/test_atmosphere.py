"""The Atmosphere API and the optical profile: validation, column integrals, layering."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.errors import SkymodelInputError
from skymodel.geometry import altitude_grid
from skymodel.numerics import trapezoid


@pytest.fixture(scope="module")
def urban():
    return Atmosphere(location="urban", month=6).optical_profile([400.0, 550.0, 700.0])


def test_profile_shapes_units_and_finiteness(urban):
    p = urban
    n_alt, n_wl = p.altitudes_m.size, 3
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_absorption"):
        a = getattr(p, name)
        assert a.shape == (n_alt, n_wl) and np.all(np.isfinite(a)) and np.all(a >= 0)
    assert p.aerosol_scattering_by_regime.shape == (2, n_alt, n_wl)
    assert p.aerosol_phase.shape[0] == 2 and p.aerosol_phase.shape[2] == n_wl
    # sea-level Rayleigh coefficient at 550 nm ~ 1.16e-5 per metre
    assert p.rayleigh_scattering[0, 1] == pytest.approx(1.16e-5, rel=0.02)


def test_default_altitude_grid_converges_column_integrals():
    wl = [400.0, 550.0, 700.0]
    coarse = Atmosphere(location="rural", month=3).optical_profile(wl)
    fine = Atmosphere(location="rural", month=3, n_altitudes=4001).optical_profile(wl)
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_scattering", "aerosol_absorption"):
        a = coarse.vertical_optical_depth(getattr(coarse, name))
        b = fine.vertical_optical_depth(getattr(fine, name))
        np.testing.assert_allclose(a, b, rtol=1e-3, err_msg=name)


def test_ozone_override_and_report():
    p = Atmosphere(location="rural", month=1, ozone_du=280.0).optical_profile([600.0])
    assert p.metadata["ozone_du"] == pytest.approx(280.0, rel=5e-3)


def test_aod_override_reaches_the_column():
    p = Atmosphere(location="desert", month=7, aod550=0.6, stratospheric="none").optical_profile([550.0])
    tau = p.vertical_optical_depth(p.aerosol_scattering + p.aerosol_absorption)[0]
    assert tau == pytest.approx(0.6, rel=5e-3)


def test_january_and_november_ozone_differ_as_the_data_says():
    jan = Atmosphere(location="continental", month=1).optical_profile([600.0]).metadata["ozone_du"]
    nov = Atmosphere(location="continental", month=11).optical_profile([600.0]).metadata["ozone_du"]
    assert jan > nov + 20  # the northern mid-latitude column falls from winter to its autumn minimum


def test_layered_profile_preserves_column_optical_depth(urban):
    lay = urban.layered(n_layers=8)
    assert lay.n_layers == 8 and lay.edges_m[0] == 0 and lay.edges_m[-1] == pytest.approx(100_000.0)
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_scattering", "aerosol_absorption"):
        np.testing.assert_allclose(lay.vertical_optical_depth(getattr(lay, name)),
                                   urban.vertical_optical_depth(getattr(urban, name)), rtol=1e-6, err_msg=name)
    assert np.all(np.diff(lay.edges_m) > 0)


def test_latitude_longitude_with_explicit_aerosol():
    a = Atmosphere(location=None, latitude=-33.9, longitude=18.4, aerosol="maritime_clean", month=12)
    assert a.aerosol == "maritime_clean" and a.latitude == pytest.approx(-33.9)
    a.optical_profile([550.0])


def test_no_aerosol_is_rayleigh_and_ozone_only():
    p = Atmosphere(location="rural", aerosol="none", stratospheric="none").optical_profile([550.0])
    assert not np.any(p.aerosol_scattering_by_regime) and not np.any(p.aerosol_absorption)


@pytest.mark.parametrize("kwargs, parameter", [
    ({"month": 13}, "month"),
    ({"month": 0}, "month"),
    ({"month": 6.5}, "month"),
    ({"location": "atlantis"}, "location"),
    ({"latitude": 95.0}, "latitude"),
    ({"longitude": -200.0}, "longitude"),
    ({"aerosol": "smog"}, "aerosol"),
    ({"aod550": -0.1}, "aod550"),
    ({"aod550": 0.2, "turbidity": 3.0}, "aod550"),
    ({"turbidity": 0.5}, "turbidity"),
    ({"ozone_du": 0.0}, "ozone_du"),
    ({"albedo": 1.5}, "albedo"),
    ({"stratospheric": "ash"}, "stratospheric"),
    ({"location": None, "latitude": 10.0}, "location"),  # a custom place needs both coordinates
])
def test_bad_input_names_the_parameter(kwargs, parameter):
    base = {"location": "rural", "month": 6}
    base.update(kwargs)
    with pytest.raises(SkymodelInputError) as info:
        Atmosphere(**base)
    assert info.value.parameter == parameter
    assert parameter in str(info.value)


def test_unknown_names_list_the_known_ones():
    with pytest.raises(SkymodelInputError, match="urban"):
        Atmosphere(location="atlantis")
    with pytest.raises(SkymodelInputError, match="desert"):
        Atmosphere(aerosol="smog")


@pytest.mark.parametrize("wl", [[300.0], [550.0, 900.0], [float("nan")], []])
def test_wavelengths_outside_the_tables_are_refused(wl):
    with pytest.raises(SkymodelInputError, match="wavelengths"):
        Atmosphere(location="rural").optical_profile(wl)


def test_every_location_and_type_builds_without_nan():
    from skymodel.optics import aerosols
    from skymodel.optics.atmosphere import locations

    for name in locations():
        prof = Atmosphere(location=name, month=4).optical_profile([380.0, 550.0, 780.0])
        assert np.isfinite(prof.metadata["aod550"]) and np.isfinite(prof.metadata["angstrom_exponent"])
    for t in aerosols.aerosol_types():
        Atmosphere(location="rural", aerosol=t, month=9, stratospheric="volcanic").optical_profile([450.0, 650.0])


def test_altitude_grid_is_increasing_and_spans_the_atmosphere():
    h = altitude_grid()
    assert h[0] == 0 and h[-1] == pytest.approx(100_000.0) and np.all(np.diff(h) > 0) and h.size == 401
    assert trapezoid(np.ones_like(h), h) == pytest.approx(100_000.0)
