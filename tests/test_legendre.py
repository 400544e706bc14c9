"""Legendre moments of phase functions (skymodel.optics.legendre) and the plane-parallel layers
built from them (skymodel.validation.plane_parallel): the input of discrete-ordinates solvers."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.errors import SkymodelInputError
from skymodel.optics.legendre import (henyey_greenstein, henyey_greenstein_moments, legendre_polynomials,
                               phase_from_moments, rayleigh_moments, tabulated_moments)
from skymodel.optics.phase_fit import asymmetry
from skymodel.validation.plane_parallel import plane_parallel_layers

WL = [400.0, 550.0, 700.0]
FINE_DEG = np.linspace(0.0, 180.0, 3601)


@pytest.fixture(scope="module")
def rural():
    return Atmosphere(location="rural", month=6, aod550=0.3).optical_profile(WL)


def test_polynomials_match_numpy():
    mu = np.linspace(-1.0, 1.0, 57)
    p = legendre_polynomials(40, mu)
    for n in (0, 1, 2, 7, 40):
        c = np.zeros(n + 1)
        c[n] = 1.0
        np.testing.assert_allclose(p[n], np.polynomial.legendre.legval(mu, c), atol=1e-12)


def test_rayleigh_closed_form_is_the_renderers_phase_function(rural):
    # numerical moments of the renderer's depolarised Rayleigh phase function...
    table = rural.rayleigh_phase(np.cos(np.radians(FINE_DEG)))  # (A, W)
    numeric = tabulated_moments(FINE_DEG, table, 6, normalize=False)
    closed = rayleigh_moments(rural.rayleigh_depolarization, 6)
    np.testing.assert_allclose(numeric, closed, atol=2e-6)
    # ...and the three-term series is that phase function exactly
    mu = np.linspace(-1, 1, 21)
    np.testing.assert_allclose(phase_from_moments(closed, mu), rural.rayleigh_phase(mu), rtol=1e-12)
    assert rayleigh_moments(0.0, 2)[2] == pytest.approx(0.1)  # no depolarisation: chi_2 = 1/10


@pytest.mark.parametrize("g", [-0.4, 0.3, 0.85])
def test_henyey_greenstein_moments(g):
    table = henyey_greenstein(np.cos(np.radians(FINE_DEG)), g)
    numeric = tabulated_moments(FINE_DEG, table, 30)
    np.testing.assert_allclose(numeric, henyey_greenstein_moments(g, 30), atol=2e-4)
    # the series converges like g^l: enough terms rebuild the function
    n = int(np.ceil(np.log(1e-9) / np.log(abs(g))))
    mu = np.cos(np.radians([0.0, 10.0, 45.0, 90.0, 170.0]))
    np.testing.assert_allclose(phase_from_moments(henyey_greenstein_moments(g, n), mu), henyey_greenstein(mu, g),
                               rtol=1e-6)


def test_aerosol_table_moments_rebuild_the_table(rural):
    ang = rural.aerosol_phase_angles_deg
    tab = np.moveaxis(rural.aerosol_phase, 1, 0)  # (A, R, W)
    chi = tabulated_moments(ang, tab, 1024, normalize=False)
    np.testing.assert_allclose(chi[0], 1.0, atol=2e-3)  # the tables are normalised over 4 pi
    # chi_1 is the asymmetry parameter (computed here by an independent trapezoid rule)
    np.testing.assert_allclose(chi[1] / chi[0], asymmetry(ang, tab), atol=2e-3)
    assert np.all(np.abs(chi[1:] / chi[0]) <= 1.0 + 1e-9)
    sel = (ang >= 5.0) & (ang <= 120.0)
    rebuilt = phase_from_moments(chi / chi[0], np.cos(np.radians(ang[sel])))
    assert np.max(np.abs(rebuilt / tab[sel] - 1.0)) < 0.01
    # too few moments cannot follow the forward peak: the check above has teeth
    few = tabulated_moments(ang, tab, 64)
    assert np.max(np.abs(phase_from_moments(few, np.cos(np.radians(ang[sel]))) / tab[sel] - 1.0)) > 0.05


def test_plane_parallel_layers_keep_the_column(rural):
    lay = plane_parallel_layers(rural, n_layers=40, n_moments=64)
    assert lay.n_layers == 40
    assert lay.edges_m[0] == pytest.approx(rural.top_altitude_m) and lay.edges_m[-1] == pytest.approx(0.0)
    np.testing.assert_allclose(lay.total_optical_depth, rural.vertical_optical_depth(rural.extinction), rtol=1e-9)
    assert np.all((lay.single_scattering_albedo >= 0.0) & (lay.single_scattering_albedo <= 1.0))
    np.testing.assert_allclose(lay.moments[:, 0], 1.0)
    # mixed asymmetry of the layer at the ground = scattering-weighted asymmetries of its species
    bottom = rural.layered(edges_m=lay.edges_m[::-1])
    ray = bottom.rayleigh_scattering[0]
    aer = bottom.aerosol_scattering_by_regime[:, 0]  # (R, W)
    g_aer = asymmetry(rural.aerosol_phase_angles_deg, np.moveaxis(rural.aerosol_phase, 1, 0))  # (R, W)
    expect = (aer * g_aer).sum(axis=0) / (ray + aer.sum(axis=0))
    np.testing.assert_allclose(lay.moments[-1, 1], expect, atol=2e-3)
    # aerosol sits low: the bottom layer's phase function is more forward-peaked than the top's
    assert np.all(lay.moments[-1, 1] > lay.moments[0, 1] + 0.1)


def test_layered_profile_input_is_used_as_it_is(rural):
    a = plane_parallel_layers(rural, n_layers=12, n_moments=32)
    b = plane_parallel_layers(rural.layered(n_layers=12), n_moments=32)
    np.testing.assert_allclose(b.optical_depth, a.optical_depth, rtol=1e-12)
    np.testing.assert_allclose(b.moments, a.moments, rtol=1e-12, atol=1e-15)
    with pytest.raises(TypeError):
        plane_parallel_layers(rural.extinction)


def test_rayleigh_only_layers_have_rayleigh_moments():
    prof = Atmosphere(location="rural", month=6, aerosol="none", stratospheric="none").optical_profile(WL)
    lay = plane_parallel_layers(prof, n_layers=10, n_moments=8)
    np.testing.assert_allclose(lay.moments, np.broadcast_to(rayleigh_moments(prof.rayleigh_depolarization, 8),
                                                            lay.moments.shape), atol=1e-15)
    assert np.all(lay.single_scattering_albedo < 1.0)  # ozone absorbs


@pytest.mark.parametrize("call", [
    lambda: legendre_polynomials(-1, 0.5),
    lambda: rayleigh_moments(1.2, 4),
    lambda: henyey_greenstein_moments(1.0, 4),
    lambda: tabulated_moments([0.0, 90.0], [1.0, 1.0], 4),  # does not reach 180 degrees
    lambda: tabulated_moments([0.0, 180.0], [1.0, -1.0], 4),  # negative phase function
    lambda: tabulated_moments([0.0, 180.0], [1.0, 1.0], 10**9),
])
def test_bad_input_names_the_parameter(call):
    with pytest.raises(SkymodelInputError):
        call()
