"""The solver's zenith nodes (skymodel.render.multiple_scattering.zenith_nodes): the plain
double Gauss-Legendre rule, and the composite rule that crowds nodes near the horizon."""
import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.render.marcher import MarchSettings
from skymodel.render.multiple_scattering import zenith_nodes


def test_plain_rule_is_double_gauss_legendre():
    mu, w = zenith_nodes(32)
    x, gw = np.polynomial.legendre.leggauss(16)
    np.testing.assert_array_equal(mu[16:], 0.5 * (x + 1.0))
    np.testing.assert_array_equal(w[16:], 0.5 * gw)
    np.testing.assert_array_equal(mu[:16], -mu[16:][::-1])


@pytest.mark.parametrize("n_mu,deg,k", [(40, 4.0, 6), (32, 4.0, 6), (16, 10.0, 3)])
def test_composite_rule_nodes_weights_and_exactness(n_mu, deg, k):
    mu, w = zenith_nodes(n_mu, deg, k)
    assert mu.size == n_mu and np.all(np.diff(mu) > 0)
    np.testing.assert_allclose(mu, -mu[::-1], atol=1e-15)
    np.testing.assert_allclose(w.sum(), 2.0, rtol=1e-14)
    up = mu[n_mu // 2:]
    a = np.sin(np.radians(deg))
    assert np.sum(up < a) == k and up[0] > 0.0  # k nodes in the band, none on the horizon
    # each panel is Gauss-Legendre: polynomials up to degree 2 min(k, rest) - 1 integrate
    # exactly over [0, 1]; odd ones vanish over [-1, 1]
    deg_exact = 2 * min(k, n_mu // 2 - k) - 1
    for p in range(deg_exact + 1):
        np.testing.assert_allclose(np.sum(w[n_mu // 2:] * up**p), 1.0 / (p + 1), rtol=1e-12)
        assert abs(np.sum(w * mu**p) - (2.0 / (p + 1) if p % 2 == 0 else 0.0)) < 1e-12


def test_composite_rule_resolves_a_horizon_glow():
    """The reason for the rule: a glow a degree or two high over the horizon (exp(-e / 1.5 deg)),
    read linearly between the nodes as the marcher reads the field, is 27-32 % off somewhere
    between 0.5 and 4 degrees with 16 or 20 plain nodes per hemisphere and about 5 % with 6 of
    them within 4 degrees. (Integrals of such a smooth glow are exact to 1e-9 with either rule:
    what the composite rule buys is the shape between the nodes.)"""
    ev = np.linspace(0.5, 4.0, 400)
    errs = {}
    for args in [(32,), (40,), (32, 4.0, 6), (40, 4.0, 6)]:
        e = np.degrees(np.arcsin(zenith_nodes(*args)[0]))
        errs[args] = np.abs(np.interp(ev, e, np.exp(-e / 1.5)) / np.exp(-ev / 1.5) - 1.0).max()
    assert min(errs[(32,)], errs[(40,)]) > 0.25 and max(errs[(32, 4.0, 6)], errs[(40, 4.0, 6)]) < 0.06, errs


@pytest.mark.parametrize("kw,name", [
    (dict(table_mu=32, table_mu_horizon_nodes=16), "table_mu_horizon_nodes"),
    (dict(table_mu=32, table_mu_horizon_nodes=-1), "table_mu_horizon_nodes"),
    (dict(table_mu=32, table_mu_horizon_nodes=6, table_mu_horizon_deg=0.0), "table_mu_horizon_deg"),
    (dict(table_mu=32, table_mu_horizon_nodes=6, table_mu_horizon_deg=90.0), "table_mu_horizon_deg"),
])
def test_bad_composite_settings_are_refused_before_any_work(kw, name):
    with pytest.raises(SkymodelInputError, match=name):
        MarchSettings(**kw)


def test_bad_arguments_of_zenith_nodes():
    with pytest.raises(ValueError, match="even"):
        zenith_nodes(31)
    with pytest.raises(ValueError, match="horizon_nodes"):
        zenith_nodes(32, 4.0, 16)
