"""The Monte Carlo tracer's ``"proxy"`` estimator (skymodel.validation.montecarlo): the
``"sunlit"`` line integrals with their sampling densities built from a table of optical
depths (:class:`_DepthTable`) and the exact integrand over them. It must keep the
expectation of next-event estimation: checked against NEE at and below the horizon, with
and without the sun guide, on the synthetic profile of tests/test_montecarlo.py (fast, no
timing); and it must be reproducible."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.errors import SkymodelInputError
from skymodel.render.rays import direction_from_angles, sun_direction
from skymodel.validation.montecarlo import _DepthTable, _Line, _Medium, _ProxyLine, trace_radiance

from test_montecarlo import _assert_estimators_agree, coarse_guide, synthetic_profile  # noqa: F401 (a fixture)


@pytest.fixture(scope="module")
def profile():
    return synthetic_profile()


def test_depth_table_is_close_to_the_exact_optical_depths(profile):
    """The proxy's table of optical depths to the top: the same rays blocked by the ground
    (exactly: the same geometric test), optical depths close to the exact ones where they
    shape a density (tau < 50) on climbing, grazing and descending rays (a descending ray
    is the chord through its tangent point less the mirrored climb), zero from the top,
    and each wavelength slot its own column."""
    med = _Medium(profile, np.array([0, 2]))
    tab = _DepthTable(med)
    assert tab.up.shape == (med.n_pieces + 1, 256, 2)  # 121 levels: every edge
    rng = np.random.default_rng(1)
    n = 6000
    h = np.concatenate([rng.uniform(0.0, 3000.0, n // 2), rng.uniform(0.0, med.top, n // 2)])
    p = np.column_stack([np.zeros(n), np.zeros(n), med.R + h])
    zen = np.concatenate([rng.uniform(0.0, 100.0, n // 2), rng.uniform(88.0, 92.0, n // 2)])
    d = direction_from_angles(zen, rng.uniform(0.0, 360.0, n))
    w = rng.integers(0, 2, n)
    t_ex, b_ex = med.optical_depth_to_top(p, d, w)
    t_tb, b_tb = tab.optical_depth_to_top(p, d, w)
    assert np.array_equal(b_ex, b_tb) and b_ex.any() and np.all(np.isinf(t_tb[b_tb]))
    ok = ~b_ex & (t_ex < 50.0)
    down = ok & (np.einsum("ij,ij->i", p, d) < 0.0)
    assert down.sum() > 500
    err = np.abs(t_tb[ok] - t_ex[ok])  # measured here: max 0.015, median 1e-4
    assert err.max() < 0.05
    top = np.array([[0.0, 0.0, med.R + med.top]])
    assert tab.optical_depth_to_top(top, np.array([0.0, 0.0, 1.0]), np.array([1]))[0][0] == 0.0


def test_proxy_line_returns_the_exact_integrand(profile):
    """A proxy line's sample is the exact integrand (that of a plain line at the same point)
    over the proxy's density: f / pdf times pdf gives back the exact value."""
    med = _Medium(profile, np.array([0, 2]))
    px = _DepthTable(med)
    sun = sun_direction(-2.0, 180.0).reshape(3)
    p = np.tile([[0.0, 0.0, med.R + 1000.0]], (2, 1))
    d = direction_from_angles([30.0, 80.0], [180.0, 180.0])
    w = np.array([0, 1])
    t_end = np.array([150_000.0, 600_000.0])
    a = _ProxyLine(med, p, d, w, sun, t_end, "sun", proxy=px)
    b = _Line(med, p, d, w, sun, t_end, "sun")
    rows = np.repeat([0, 1], 50)
    u, f = a.sample(rows, np.random.default_rng(2))
    assert np.allclose(f * a._pdf(rows, u), b.integrand(rows, u), rtol=1e-12, atol=0.0)
    with pytest.raises(RuntimeError):
        _ProxyLine(med, p, d, w, sun, t_end, "sun", proxy=px, exact=False).sample(rows, np.random.default_rng(2))


@pytest.mark.parametrize("sun_el", [0.0, -2.0])
def test_proxy_estimator_agrees_with_nee_at_and_below_the_horizon(profile, coarse_guide, sun_el):
    """Sun on the horizon (no direction guide; the first vertex a forced collision) and 2
    degrees down (guide, balance heuristic, importance-sampled first collision)."""
    dirs = direction_from_angles([0.0, 60.0, 85.0], [0.0, 180.0, 0.0])
    a = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=12000, seed=31)
    b = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=400, seed=32, estimator="proxy")
    _assert_estimators_agree(a, b)


@pytest.mark.parametrize("sun_el", [0.0, -2.0])
def test_sun_guided_proxy_estimator_agrees_with_nee(profile, coarse_guide, sun_el):
    """sun_guide with the proxy estimator (directions partly drawn around the sun at air
    collisions and ground bounces, exact mixture weights; below the horizon the balance
    heuristic with the direction guide then uses the mixture's density): the same
    radiances as NEE. (This case does not catch the physical density used there instead:
    the direction guide dominates the sums here; the desert at sun -4 showed it.)"""
    dirs = direction_from_angles([0.0, 70.0, 85.0, 60.0], [0.0, 180.0, 0.0, 90.0])
    a = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=12000, seed=33)
    b = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=400, seed=34, estimator="proxy", sun_guide=0.3)
    _assert_estimators_agree(a, b)


def test_proxy_estimator_is_reproducible(profile, coarse_guide):
    dirs = direction_from_angles([0.0, 85.0], [0.0, 180.0])

    def run(seed, **kw):
        return trace_radiance(profile, dirs, -2.0, 180.0, n_paths=64, seed=seed, estimator="proxy", **kw)

    a, b, c = run(5), run(5), run(6)
    assert np.array_equal(a.radiance, b.radiance) and np.array_equal(a.stderr, b.stderr)
    assert not np.array_equal(a.radiance, c.radiance)
    assert np.all(np.isfinite(a.radiance)) and np.all(a.radiance > 0.0)
    g1, g2 = run(5, sun_guide=0.2), run(5, sun_guide=0.2)
    assert np.array_equal(g1.radiance, g2.radiance)


def test_proxy_estimator_bad_input(profile):
    with pytest.raises(SkymodelInputError, match="estimator"):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 0.0, 0.0, estimator="proxie")
    with pytest.raises(SkymodelInputError, match="sun_guide"):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 0.0, 0.0, estimator="proxy", sun_guide=1.0)


def test_roulette_does_not_promote_a_small_weight_heading_into_the_forward_peak(profile, coarse_guide):
    """_roulette keeps every weight's expectation; with the sun guide a path heading toward
    the sun (where the next vertex's score ~ the aerosol phase function there) survives in
    proportion to weight x 4 pi x the guide's density and comes out at about 1 / that
    factor instead of 1, while a path heading away is rouletted on its weight alone."""
    from skymodel.validation.montecarlo import _guide_pdf, _roulette

    med = _Medium(profile, np.array([1]))
    sun = sun_direction(-2.0, 180.0).reshape(3)
    m = 400_000
    away = direction_from_angles(60.0, 0.0).reshape(3)
    toward = np.arange(m) < m // 2
    D = np.where(toward[:, None], sun[None, :], away[None, :])
    Wl = np.zeros(m, dtype=int)
    beta0 = np.full(m, 1e-2)
    factor = 4.0 * np.pi * _guide_pdf(med, D[:1], Wl[:1], sun)[0]
    assert factor > 10.0  # the synthetic aerosol's forward peak (about 19)
    for guide in (0.0, 0.3):
        beta, keep = _roulette(med, beta0.copy(), D, Wl, sun, guide, np.ones(m, dtype=bool), np.random.default_rng(4))
        for part in (toward, ~toward):  # unbiased: the mean weight is kept
            b = beta[part]
            assert abs(b.mean() - 1e-2) < 4.0 * b.std() / np.sqrt(b.size)
        assert np.array_equal(keep, beta > 0.0)
        assert np.all(beta[~toward & keep] == 1.0)  # away from the sun: promoted to 1 as before
        if guide == 0.0:
            assert np.all(beta[toward & keep] == 1.0)
        else:  # toward the sun: weight x 4 pi g is 1, not the factor
            assert np.allclose(beta[toward & keep] * factor, 1.0)
            assert abs(keep[toward].mean() - 1e-2 * factor) < 0.01
    kept = np.zeros(m, dtype=bool)  # paths not kept stay out, whatever their weight
    beta, keep = _roulette(med, np.ones(m), D, Wl, sun, 0.3, kept, np.random.default_rng(5))
    assert not keep.any()


def test_the_sunlit_loop_roulettes_with_the_sun_guide(profile, coarse_guide, monkeypatch):
    """The proxy estimator's paths are rouletted as the guided NEE's are (the desert at sun
    -4 deg: without it a rare survivor heading into the dust's peak scored ~1e4 times a
    typical path, notebooks/proxy_tail)."""
    import skymodel.validation.montecarlo as mcm

    seen = []
    real = mcm._roulette

    def spy(med, beta, D, Wl, sun, sun_guide, keep, rng):
        seen.append(sun_guide)
        return real(med, beta, D, Wl, sun, sun_guide, keep, rng)

    monkeypatch.setattr(mcm, "_roulette", spy)
    dirs = direction_from_angles([0.0, 85.0], [0.0, 180.0])
    trace_radiance(profile, dirs, -2.0, 180.0, n_paths=200, seed=7, estimator="proxy", sun_guide=0.2)
    assert seen and set(seen) == {0.2}
