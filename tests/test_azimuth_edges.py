"""The multiple-scattering source read in the principal plane (MultipleScatteringField.source_at):
the azimuth nodes are midpoints, so phi = 0 (toward the sun) and phi = pi lie outside them;
edge columns there hold the even quadratic in log J through the two nearest nodes."""

from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.render.marcher import MarchSettings, SkyMarcher
from skymodel.render.multiple_scattering import MultipleScatteringField


def _field(n_phi: int, log_j_of_phi) -> MultipleScatteringField:
    """A field whose source depends on the azimuth only (log J = log_j_of_phi(phi))."""
    phi = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    h, mu, mus = np.array([0.0, 1e4, 1e5]), np.array([-0.5, 0.1, 0.5]), np.array([-0.2, 0.3, 1.0])
    j = np.exp(log_j_of_phi(phi)).astype(np.float32)
    src = np.broadcast_to(j[None, None, :, None, None], (2, mu.size, n_phi, h.size, mus.size)).copy()
    return MultipleScatteringField(np.array([450.0, 550.0]), h, mu, phi, mus, src, np.ones((mus.size, 2)), 3, [])


@pytest.mark.parametrize("n_phi", [8, 12])
def test_edges_follow_a_source_peaked_toward_the_sun(n_phi):
    """log J = b cos(phi), b = 3 (a forward-peaked diffuse field): read at phi = 0 and pi, the
    edge is within 2e-3 of the truth (8 nodes: 1.6e-3, 12: 3.3e-4); the nearest node (what a
    flat read gives) is 2.6-5.6 % off."""
    b = 3.0
    f = _field(n_phi, lambda p: b * np.cos(p))
    for phi, truth in ((0.0, np.exp(b)), (np.pi, np.exp(-b))):
        got = f.source_at(5e3, 0.1, phi, 0.3)
        np.testing.assert_allclose(got, truth, rtol=2e-3)
        nearest = f.source_at(5e3, 0.1, f.phi_nodes[0] if phi == 0 else f.phi_nodes[-1], 0.3)
        assert np.all(np.abs(nearest / truth - 1) > 0.01)
    # exact for a Gaussian in phi; the nodes themselves read as before
    g = _field(n_phi, lambda p: 1.0 - 2.0 * p ** 2)
    np.testing.assert_allclose(g.source_at(5e3, 0.1, 0.0, 0.3), np.e, rtol=1e-5)
    np.testing.assert_allclose(g.source_at(5e3, 0.1, g.phi_nodes[1], 0.3),
                               np.exp(1.0 - 2.0 * g.phi_nodes[1] ** 2), rtol=1e-6)


def test_poles_keep_the_rings_mean_and_one_node_works():
    f = _field(12, lambda p: 3.0 * np.cos(p))
    ring = np.exp(3.0 * np.cos(f.phi_nodes)).mean()
    np.testing.assert_allclose(f.source_at(5e3, 1.0, 0.0, 0.3), ring, rtol=1e-6)
    np.testing.assert_allclose(f.source_at(5e3, -1.0, np.pi, 0.3), ring, rtol=1e-6)
    one = _field(1, lambda p: 0.0 * p)
    np.testing.assert_allclose(one.source_at(5e3, 0.1, [0.0, 1.0, np.pi], 0.3), 1.0, rtol=1e-6)


def test_twilight_toward_the_sun_is_closer_to_a_finer_azimuth_grid():
    """Rural aerosol at 450 nm, sun at -4 degrees, 88 degrees from the zenith toward the sun,
    the lowest altitude nodes: the source of a 6-azimuth field read at phi = 0 is closer to a
    24-azimuth field's than the value at its first node (the flat read before the edges)."""
    prof = Atmosphere(location="rural", month=6, aod550=0.2).optical_profile((450.0,))
    # the 12-degree cone in both (the 6-degree one of a mild peak needs 12 azimuth nodes:
    # tests/test_delta_m_cone.py)
    small = MarchSettings(exact=True, table_altitudes=12, table_mu=16, table_phi=6, table_steps=32, view_steps=32,
                          delta_m_mild_cutoff_deg=0.0)
    f6 = SkyMarcher(prof, -4.0, 180.0, 0.0, small).field
    f24 = SkyMarcher(prof, -4.0, 180.0, 0.0, replace(small, table_phi=24)).field
    h, mu, mu_s = f6.h_nodes[:4], np.cos(np.radians(88.0)), np.sin(np.radians(-4.0))
    fine = f24.source_at(h, mu, 0.0, mu_s)
    edge = np.abs(f6.source_at(h, mu, 0.0, mu_s) / fine - 1)
    flat = np.abs(f6.source_at(h, mu, f6.phi_nodes[0], mu_s) / fine - 1)
    assert np.all(edge < flat), (edge, flat)
