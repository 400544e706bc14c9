"""Rayleigh scattering: optical depth against Bodhaine et al. (1999), cross section and
depolarisation against published values, phase function normalisation."""

import numpy as np
import pytest

from skymodel.optics import rayleigh


def bodhaine_eq30(wl_nm):
    """Bodhaine et al. 1999 (J. Atmos. Oceanic Technol. 16, 1854), Eq. 30: the fitted
    Rayleigh optical depth for 1013.25 hPa, 45 degrees latitude, 360 ppm CO2 — a
    published formula independent of our cross-section code."""
    lam = np.asarray(wl_nm) / 1000.0
    return 0.0021520 * (1.0455996 - 341.29061 * lam**-2 - 0.90230850 * lam**2) / (
        1.0 + 0.0027059889 * lam**-2 - 85.968563 * lam**2)


@pytest.mark.parametrize("wl", [400.0, 550.0, 700.0])
def test_vertical_optical_depth_within_1_percent_of_bodhaine(wl):
    tau = rayleigh.optical_depth([wl])[0]
    assert tau == pytest.approx(bodhaine_eq30(wl), rel=0.01)


def test_published_point_values():
    # Bodhaine et al. 1999, Table 3 (360 ppm CO2): sigma(550 nm) = 4.512e-27 cm^2 (to 4 digits)
    # compare ratios: pytest.approx's default absolute tolerance (1e-12) would swallow 1e-27 values
    assert rayleigh.cross_section([550.0])[0] * 1e4 / 4.512e-27 == pytest.approx(1.0, rel=2e-3)
    # Bates 1984 / Bodhaine: King factor of air at 550 nm ~1.0489, depolarisation ~0.0283
    assert rayleigh.king_factor(550.0) == pytest.approx(1.0489, abs=5e-4)
    assert rayleigh.depolarization_factor(550.0) == pytest.approx(0.0283, abs=3e-4)


def test_lambda_minus_four_roughly():
    s = rayleigh.cross_section([400.0, 800.0 - 20.0])
    slope = np.log(s[0] / s[1]) / np.log(780.0 / 400.0)
    assert 4.0 < slope < 4.2  # dispersion of n and F_K steepen the lambda^-4 law


def test_phase_function_normalised():
    from skymodel.optics.profile import _MediumBase

    m = _MediumBase(
        wavelengths_nm=np.array([400.0, 700.0]), rayleigh_depolarization=rayleigh.depolarization_factor([400.0, 700.0]),
        aerosol_phase_angles_deg=np.array([0.0, 180.0]), aerosol_phase=np.ones((1, 2, 2)) / (4 * np.pi),
        ground_albedo=np.zeros(2), solar_irradiance=np.ones(2),
    )
    mu, w = np.polynomial.legendre.leggauss(32)
    integral = 2 * np.pi * (m.rayleigh_phase(mu) * w[:, None]).sum(0)
    np.testing.assert_allclose(integral, 1.0, rtol=1e-12)
