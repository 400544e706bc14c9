"""U.S. Standard Atmosphere 1976 against an independent implementation (ambiance) and the
standard's own tabulated values above 86 km."""

import numpy as np
import pytest

from skymodel.optics import standard_atmosphere as usa


def test_against_ambiance_0_to_80_km():
    ambiance = pytest.importorskip("ambiance")
    z = np.linspace(0.0, 80_000.0, 161)
    ref = ambiance.Atmosphere(z)
    np.testing.assert_allclose(usa.temperature(z), ref.temperature, rtol=2e-5)
    np.testing.assert_allclose(usa.pressure(z), ref.pressure, rtol=1e-4)
    np.testing.assert_allclose(usa.number_density(z), ref.number_density, rtol=2e-4)


@pytest.mark.parametrize(
    "z_m, p_pa, n_m3",
    [
        # U.S. Standard Atmosphere 1976, Table I (geometric altitude)
        (86_000.0, 3.7338e-1, 1.4456e20),
        (90_000.0, 1.8359e-1, 7.1160e19),
        (95_000.0, 7.5966e-2, 2.9246e19),
        (100_000.0, 3.2011e-2, 1.1898e19),
    ],
)
def test_upper_atmosphere_matches_table(z_m, p_pa, n_m3):
    assert usa.pressure(z_m) == pytest.approx(p_pa, rel=0.01)
    assert usa.number_density(z_m) == pytest.approx(n_m3, rel=0.01)


def test_sea_level_and_layer_bases():
    assert usa.temperature(0.0) == pytest.approx(288.15)
    assert usa.pressure(0.0) == pytest.approx(101_325.0)
    assert usa.number_density(0.0) == pytest.approx(2.5470e25, rel=1e-4)
    # tropopause base pressure (standard: 22632.06 Pa at 11 km geopotential)
    assert usa.pressure(usa.R0 * 11_000.0 / (usa.R0 - 11_000.0)) == pytest.approx(22632.06, rel=1e-6)


def test_monotone_and_finite():
    z = np.linspace(0, 100_000, 2001)
    n = usa.number_density(z)
    assert np.all(np.isfinite(n)) and np.all(np.diff(n) < 0)


def test_bad_altitude_named():
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError, match="altitude_m"):
        usa.number_density([0.0, 500_000.0])
