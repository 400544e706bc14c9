import numpy as np
import pytest

from skymodel.numerics import trapezoid
from skymodel.optics.phase_fit import asymmetry, fit_phase, hg

ANG = np.concatenate([np.linspace(0, 5, 201), np.linspace(5.1, 180, 1750)])
MU = np.cos(np.radians(ANG))


def test_hg_normalised_and_asymmetry():
    for g in (-0.5, 0.0, 0.7, 0.9):
        p = hg(MU, g)
        assert -2 * np.pi * trapezoid(p, MU) == pytest.approx(1.0, abs=2e-3)
        assert asymmetry(ANG, p) == pytest.approx(g, abs=2e-3)


def test_double_hg_recovers_known_lobes():
    tab = np.stack([0.8 * hg(MU, 0.85) + 0.2 * hg(MU, -0.4), hg(MU, 0.6)], axis=1)
    f = fit_phase(ANG, tab)
    assert f.dhg_w[0] == pytest.approx(0.8, abs=0.01)
    assert f.dhg_g1[0] == pytest.approx(0.85, abs=0.01)
    assert f.dhg_g2[0] == pytest.approx(-0.4, abs=0.02)
    assert f.dhg_error[0] < 0.01 < f.hg_error[0]  # one lobe cannot match a two-lobe function
    assert f.hg_error[1] < 1e-3  # a pure HG table is fitted by HG
    np.testing.assert_allclose(asymmetry(ANG, f.dhg_table(ANG)), asymmetry(ANG, tab), atol=3e-3)


def test_double_hg_keeps_the_asymmetry_of_the_aerosol_tables():
    """Every regime and wavelength of a real profile: the DHG fit's first moment equals the
    table's (it is a constraint of the fit, not a result of the optimiser), and its weight
    is a proper mixture weight."""
    from skymodel import Atmosphere

    prof = Atmosphere(location="rural", month=6).optical_profile([380, 450, 550, 650, 780])
    for r in range(prof.aerosol_phase.shape[0]):
        tab = prof.aerosol_phase[r]
        f = fit_phase(prof.aerosol_phase_angles_deg, tab)
        assert np.all((f.dhg_w > 0) & (f.dhg_w <= 1))
        np.testing.assert_allclose(f.dhg_w * f.dhg_g1 + (1 - f.dhg_w) * f.dhg_g2, f.g, atol=1e-9)
        assert np.all(f.dhg_error <= f.hg_error + 1e-9)  # two lobes never fit worse than one
