"""The table of optical depth toward the sun (skymodel.render.sun_transmittance) against
the optical depth integrated directly along the sun ray."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.render.medium import factor_medium, march_samples
from skymodel.render.rays import altitude_along
from skymodel.render.sun_transmittance import SunTransmittance


@pytest.fixture(scope="module")
def rural():
    # the OPAC rural mixture (cut at 12 km) the slant depths below were measured with (issue 20)
    prof = Atmosphere(location="rural", month=6, aod550=0.2, aerosol_model="opac").optical_profile((450.0, 650.0))
    return prof, factor_medium(prof)


def _direct_optical_depth(med, R, top, h, mu, n=20000):
    p = np.stack([np.zeros_like(h), np.zeros_like(h), R + h], axis=-1)
    d = np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], axis=-1)
    r = R + h
    dist = -r * mu + np.sqrt(r * r * (mu * mu - 1) + (R + top) ** 2)
    t, dt = march_samples(p, d, np.zeros_like(h), dist, n, R)
    return np.einsum("psw,ps->pw", med.extinction.at(altitude_along(p, d, t, R)), dt)


def test_low_sun_near_the_ground(rural):
    """Sun at 5 degrees, points in the lowest kilometres (where a view ray toward the
    horizon runs). The horizon distance grows as sqrt(h) above the ground, so the table
    is spaced and interpolated in rho = sqrt(r^2 - R^2); interpolated in altitude on a
    stretched grid it missed 0.08 of an optical depth of 5.1 at 35 m (450 nm)."""
    prof, med = rural
    R, top = prof.planet_radius_m, prof.top_altitude_m
    h = np.array([0.0, 10.0, 35.0, 105.0, 357.0, 1118.0, 2376.0, 4273.0, 10111.0])
    mu = np.full_like(h, np.sin(np.radians(5.0)))
    exact = _direct_optical_depth(med, R, top, h, mu)
    table = SunTransmittance([med.extinction], R, top, 96, 192, 160)  # MarchSettings' defaults
    got = table.optical_depth(h, mu)
    assert np.all(exact[:5, 0] > 4.0)  # a slant path through the aerosol layer
    np.testing.assert_allclose(got, exact, atol=0.015)


def test_sun_near_the_local_horizon(rural):
    """Grazing sun rays (twilight) from 0 to 40 km: transmittance within 1 % of the
    direct integration wherever at least 1 % of the light gets through."""
    prof, med = rural
    R, top = prof.planet_radius_m, prof.top_altitude_m
    h = np.repeat([0.0, 500.0, 3000.0, 12000.0, 25000.0, 40000.0], 4)
    mu_h = -np.sqrt(1 - (R / (R + h)) ** 2)
    mu = mu_h + np.tile([0.002, 0.01, 0.03, 0.1], 6)
    exact = np.exp(-_direct_optical_depth(med, R, top, h, mu))
    got = np.exp(-SunTransmittance([med.extinction], R, top, 128, 256, 256).optical_depth(h, mu))
    lit = exact > 0.01
    assert lit.sum() >= 15
    np.testing.assert_allclose(got[lit], exact[lit], rtol=0.01)


def test_low_sun_between_the_lowest_altitude_nodes(rural):
    """Sun at 5 degrees, points every 5 m in the lowest 400 m. Between two altitude nodes
    the table is linear in rho, so a depth that falls linearly with the altitude h =
    rho^2 / 2R is read too small by (rho - rho_i)(rho_i+1 - rho) / 2R times its slope:
    with the nodes evenly in rho (96 of them, 11.9 km apart) that is 2.8 m of altitude
    in the middle of every interval, 0.012 of an optical depth of 5 at 450 nm (1.2 %
    too much sunlight). Evenly in sqrt(rho) the lowest intervals are 95^2 times narrower
    and the step grows to twice the even one at the top: 0.0025 (the even rule: 0.0125)."""
    prof, med = rural
    R, top = prof.planet_radius_m, prof.top_altitude_m
    h = np.arange(0.0, 400.0, 5.0)
    mu = np.full_like(h, np.sin(np.radians(5.0)))
    exact = _direct_optical_depth(med, R, top, h, mu)
    got = SunTransmittance([med.extinction], R, top, 96, 192, 160).optical_depth(h, mu)  # final's table
    assert np.abs(got - exact).max() < 0.004


def test_a_table_pickled_before_the_node_rule_reads_its_own_nodes(rural):
    """Solutions cached on disk (skymodel.render.sequence.SolutionCache) keep their sun
    table: one pickled before the nodes moved to sqrt(rho) has no ``_rho_power`` and its
    nodes evenly in rho; it must read them as such (the same depths as that rule built now)."""
    import skymodel.render.sun_transmittance as stm

    prof, med = rural
    R, top = prof.planet_radius_m, prof.top_altitude_m
    old_power = stm._RHO_POWER
    try:
        stm._RHO_POWER = 1.0
        even = SunTransmittance([med.extinction], R, top, 32, 48, 48)
    finally:
        stm._RHO_POWER = old_power
    h = np.array([0.0, 20.0, 333.0, 5000.0, 40000.0])
    mu = np.full_like(h, np.sin(np.radians(5.0)))
    want = even.optical_depth(h, mu)
    del even.__dict__["_rho_power"]  # as unpickled from before
    np.testing.assert_array_equal(even.optical_depth(h, mu), want)
