"""Interpolation of the multiple-scattering field along the sun angle
(MultipleScatteringField.source_at): a cubic spline in log J between the sun nodes."""

from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.render.marcher import MarchSettings, SkyMarcher
from skymodel.render import multiple_scattering as ms
from skymodel.render.multiple_scattering import _log_slopes, _sun_interp, _sun_interp_cubic, sun_elevation_nodes


def test_cubic_in_log_follows_a_receding_sunlit_layer():
    """Below the horizon the sunlit air recedes upward as the square of the sun's depth,
    so the source falls like exp(-c depth^2): log J bends down between nodes, which the
    geometric (log-linear) form misses and the cubic in log follows."""
    nodes = np.sin(np.radians(sun_elevation_nodes(24)))
    truth = lambda mu: np.exp(-400.0 * np.minimum(mu, 0.0) ** 2 + 2.0 * mu)  # noqa: E731
    x = np.sin(np.radians(np.linspace(-10.0, -0.5, 200)))
    i = np.searchsorted(nodes, x, side="right") - 1
    f = (x - nodes[i]) / (nodes[i + 1] - nodes[i])
    v = truth(nodes)
    s = _log_slopes(nodes, v)
    cubic = _sun_interp_cubic(v[i], v[i + 1], s[i], s[i + 1], nodes[i + 1] - nodes[i], f, nodes[i + 1] <= 0)
    geometric = _sun_interp(v[i], v[i + 1], f, nodes[i + 1] <= 0)
    err_c = np.abs(cubic / truth(x) - 1).max()
    err_g = np.abs(geometric / truth(x) - 1).max()
    assert err_c < 0.01 < err_g
    # exact at the nodes, and the fallback where a value is 0
    np.testing.assert_allclose(_sun_interp_cubic(v[:-1], v[1:], s[:-1], s[1:], np.diff(nodes), 0.0, False), v[:-1])
    z = v.copy()
    z[3] = 0.0
    sz = _log_slopes(nodes, z)
    assert np.all(np.isnan(sz))
    out = _sun_interp_cubic(z[2], z[3], sz[2], sz[3], nodes[3] - nodes[2], 0.5, True)
    assert out == pytest.approx(0.5 * z[2])


def test_twilight_field_between_sun_nodes():
    """Rayleigh sky, sun at -4 degrees: the field read between its 24 sun nodes agrees with
    one solved on 96 nodes (measured at these small tables, sun -6..3 degrees, the
    lowest four altitude nodes, 88 degrees zenith toward the sun: within 0.8 % with the
    cubic in log; the geometric form was up to 6.0 % off)."""
    prof = Atmosphere(location="rural", month=6, aerosol="none", stratospheric_aod550=0.0).optical_profile((450.0,))
    small = MarchSettings(exact=True, table_altitudes=12, table_mu=16, table_phi=6, table_steps=32, view_steps=32)
    f24 = SkyMarcher(prof, -4.0, 180.0, 0.0, small).field
    f96 = SkyMarcher(prof, -4.0, 180.0, 0.0, replace(small, table_mus=96)).field
    mu_s = np.sin(np.radians(np.linspace(-6.0, 3.0, 37)))
    h, mu = f24.h_nodes[:4], np.cos(np.radians(88.0))
    hh, ms = np.meshgrid(h, mu_s, indexing="ij")
    a = f24.source_at(hh, mu, 0.0, ms)
    b = f96.source_at(hh, mu, 0.0, ms)
    assert np.abs(a / b - 1).max() < 0.02


def test_field_read_in_blocks_is_the_same(monkeypatch):
    """source_at works through its points in blocks (to bound its memory) and builds its
    interpolation table one zenith node at a time; neither changes a value."""
    from skymodel.render import multiple_scattering as msm

    prof = Atmosphere(location="desert", month=6).optical_profile((450.0, 650.0))
    small = MarchSettings(exact=True, table_altitudes=8, table_mu=8, table_phi=4, table_steps=16, view_steps=16)
    field = SkyMarcher(prof, 3.0, 180.0, 0.0, small).field
    rng = np.random.default_rng(3)
    pts = (rng.uniform(0, 40e3, (7, 11)), rng.uniform(-1, 1, (7, 11)), rng.uniform(0, np.pi, (7, 11)),
           rng.uniform(-0.3, 1, (7, 11)))
    whole = field.source_at(*pts)
    assert whole.shape == (7, 11, 2)
    monkeypatch.setattr(msm, "_SOURCE_BLOCK", 5)
    np.testing.assert_array_equal(field.source_at(*pts), whole)
    # the table's J column is the solved source over the scattering coefficient at its
    # altitude node (read linearly in altitude, times sigma_s at the point: source_at)
    tab = field._interp_table()
    assert field.h_scale is not None and not np.shares_memory(field.source, tab)
    src = np.moveaxis(field.source, 0, -1)
    np.testing.assert_allclose(tab[1:-1, 1:-1, ..., 0, :] * field.h_scale[None, None, :, None, :].astype(np.float32), src,
                               rtol=1e-6, atol=0)
    # at a node the point reads the node's J
    h, mu, phi, mus = field.h_nodes[3], field.mu_nodes[2], field.phi_nodes[1], field.mus_nodes[5]
    np.testing.assert_allclose(field.source_at(h, mu, phi, mus), field.source[:, 2, 1, 3, 5], rtol=1e-5)
    # without h_scale (fields solved before, source_by_scattering=False) ``source`` is a view of the table
    lin = SkyMarcher(prof, 3.0, 180.0, 0.0, replace(small, source_by_scattering=False)).field
    lin_tab = lin._interp_table()
    assert lin.h_scale is None and np.shares_memory(lin.source, lin_tab)
    src = np.moveaxis(field.source / field.h_scale.T[:, None, None, :, None].astype(np.float32), 0, -1)
    # the table is float32 (the solver's precision): slopes computed in float64, then rounded
    assert tab.dtype == np.float32
    np.testing.assert_allclose(tab[1:-1, 1:-1, ..., 1, :], msm._log_slopes(field.mus_nodes, src.astype(float), axis=3),
                               rtol=1e-6, atol=0)
    # the pole rows (mu = -1, +1): the azimuthal mean of the nearest ring, the same at every azimuth
    # (the azimuth edge columns, phi = 0 and pi, included: tests/test_azimuth_edges.py)
    ring = (src.shape[1] + 2,) + src[0].shape[1:]
    np.testing.assert_allclose(tab[0, ..., 0, :], np.broadcast_to(src[0].mean(axis=0), ring), rtol=1e-6)
    np.testing.assert_allclose(tab[-1, ..., 0, :], np.broadcast_to(src[-1].mean(axis=0), ring), rtol=1e-6)
    # a scalar point gives (n_wl,)
    assert field.source_at(1000.0, 0.5, 1.0, 0.2).shape == (2,)


def test_threads_reading_a_fresh_field_build_its_table_once(monkeypatch):
    """The marcher's threads read a new field at once: one builds the interpolation table
    while the others wait, and every thread reads the same values (CI caught a thread that
    saw the table published before its zenith nodes)."""
    import threading
    import time

    from skymodel.render import multiple_scattering as msm

    prof = Atmosphere(location="rural", month=6).optical_profile((550.0,))
    small = MarchSettings(exact=True, table_altitudes=8, table_mu=8, table_phi=4, table_steps=16, view_steps=16)
    field = SkyMarcher(prof, 10.0, 180.0, 0.0, small).field
    pts = (np.linspace(0, 30e3, 50), np.linspace(-1, 1, 50), np.linspace(0, np.pi, 50), np.full(50, 0.3))
    expected = field.source_at(*pts)
    for name in ("_table_edges", "_mu_poles", "_phi_edges"):
        field.__dict__.pop(name, None)
    slopes, builds = msm._log_slopes, []
    build = msm.MultipleScatteringField._build_interp_table

    def slow_slopes(*a, **k):  # widen the window in which the other threads arrive
        time.sleep(0.01)
        return slopes(*a, **k)

    def counted(self):
        builds.append(1)
        return build(self)

    monkeypatch.setattr(msm, "_log_slopes", slow_slopes)
    monkeypatch.setattr(msm.MultipleScatteringField, "_build_interp_table", counted)
    start, out = threading.Barrier(4), [None] * 4

    def read(k):
        start.wait()
        out[k] = field.source_at(*pts)

    threads = [threading.Thread(target=read, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(builds) == 1
    for o in out:
        np.testing.assert_array_equal(o, expected)


def test_the_zenith_reads_the_azimuthal_mean_not_one_azimuth():
    """Above the top ring of zenith-cosine nodes (never at the pole: double Gauss-Legendre)
    the source is interpolated toward the ring's azimuthal mean at mu = 1: at the zenith
    it is the same for every azimuth (before: clamped to the ring, it read the ring at the
    view's own azimuth, 5.9 degrees toward or away from the sun at ``final``; issue 23)."""
    prof = Atmosphere(location="rural", month=6, aod550=0.2).optical_profile((450.0, 650.0))
    small = MarchSettings(exact=True, table_altitudes=8, table_mu=8, table_phi=4, table_steps=16, view_steps=16)
    field = SkyMarcher(prof, 20.0, 180.0, 0.0, small).field
    phi = np.linspace(0.0, np.pi, 9)
    at_zenith = field.source_at(2000.0, 1.0, phi, 0.34)
    # (rtol 1e-6: the float32 table; identical rows weighted differently round differently)
    np.testing.assert_allclose(at_zenith, np.broadcast_to(at_zenith[0], at_zenith.shape), rtol=1e-6)
    ring = field.source_at(2000.0, field.mu_nodes[-1], field.phi_nodes, 0.34)
    np.testing.assert_allclose(at_zenith[0], ring.mean(axis=0), rtol=1e-3)  # the mean of the ring, not one node
    assert np.ptp(ring[:, 0]) > 0.01 * ring[:, 0].mean()  # the ring itself varies with azimuth
    # between the ring and the pole: linear in mu
    mid = 0.5 * (field.mu_nodes[-1] + 1.0)
    np.testing.assert_allclose(field.source_at(2000.0, mid, field.phi_nodes[0], 0.34),
                               0.5 * (ring[0] + at_zenith[0]), rtol=1e-3)
    # the nadir likewise
    at_nadir = field.source_at(2000.0, -1.0, phi, 0.34)
    np.testing.assert_allclose(at_nadir, np.broadcast_to(at_nadir[0], at_nadir.shape), rtol=1e-6)


@pytest.mark.parametrize("nodes", [np.sin(np.radians(ms.sun_elevation_nodes(32))), np.sin(np.radians(ms.sun_elevation_nodes(24))),
                                   np.array([0.0, 1.0, 2.5, 3.0, 7.0]), np.array([0.0, 1.0, 2.0, 3.0]),
                                   np.array([-0.2, 0.1, 0.7]), np.array([0.0, 0.5])])
def test_spline_slope_matrix_equals_scipy(nodes):
    """The numpy slope matrix of the not-a-knot spline equals scipy's CubicSpline (the oracle)."""
    from scipy.interpolate import CubicSpline

    ref = CubicSpline(nodes, np.eye(nodes.size), axis=0)(nodes, 1)
    got = ms._spline_slope_matrix(tuple(nodes))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-14 * np.abs(ref).max())
