"""Lorentz–Mie theory (skymodel.optics.mie) against miepython, analytic limits and identities.

miepython is a test-only oracle. It uses m = n - ik (we use BH's m = n + ik, k >= 0), so
every call passes ``np.conj(m)``; its amplitudes S1, S2 are then the complex conjugates of
ours (its coefficients a_n, b_n are returned in BH's convention and equal ours).
"""

import warnings

import numpy as np
import pytest

from skymodel.optics import mie
from skymodel.errors import SkymodelInputError
from skymodel.numerics import trapezoid

miepython = pytest.importorskip("miepython")


def _rel(ours, ref):
    return np.abs(np.asarray(ours) - ref) / np.abs(ref)


# --------------------------------------------------------------------------------------
# the oracle
# --------------------------------------------------------------------------------------


def _oracle_from_coefficients(m, x):
    """Q_ext, Q_sca, g from miepython's exact series coefficients (BH Eqs. 4.61, 4.62, 4.92).

    miepython's ``efficiencies_mx`` switches to Wiscombe's small-sphere expansion when
    |m| x < 0.1. That expansion is truncated: against a 60-digit mpmath Mie series (and
    against skymodel.optics.mie, which agrees with it to ~1e-15) it is off by up to 1.6e-6 in
    Q_ext and 8e-7 in g for 0.03 < |m| x < 0.1 — above this test's 1e-6 tolerance. In that
    regime we therefore sum miepython's own exact coefficients (``miepython.coefficients``,
    the same series its large-sphere path uses). For real m, Q_ext = Q_sca exactly
    (Re a_n = |a_n|^2); summing Re(a_n) instead would only measure the rounding of the
    O(x^6) real part of an O(x^3) complex number.
    """
    a, b = miepython.coefficients(np.conj(m), x)
    n = np.arange(1, a.size + 1)
    s_sca = np.sum((2 * n + 1) * (np.abs(a) ** 2 + np.abs(b) ** 2))
    s_ext = np.sum((2 * n + 1) * (a + b).real)
    s_g = (np.sum(n[:-1] * (n[:-1] + 2) / (n[:-1] + 1) * (a[:-1] * np.conj(a[1:]) + b[:-1] * np.conj(b[1:])).real)
           + np.sum((2 * n + 1) / (n * (n + 1)) * (a * np.conj(b)).real))
    qsca = 2 * s_sca / x**2
    qext = qsca if m.imag == 0 else 2 * s_ext / x**2
    return qext, qsca, 2 * s_g / s_sca


def _oracle(m, x):
    if abs(m) * x < 0.1:
        return _oracle_from_coefficients(m, x)
    qext, qsca, _qback, g = miepython.efficiencies_mx(np.conj(m), x)
    return qext, qsca, g


def _random_cases(n_cases=64, seed=20240611):
    """x log-uniform on [1e-3, 1e4]; n uniform on [1.01, 2]; k cycling through exactly 0,
    'tiny' (log-uniform 1e-8..1e-6), log-uniform 1e-5..1, and exactly 1."""
    rng = np.random.default_rng(seed)
    x = 10.0 ** rng.uniform(-3.0, 4.0, n_cases)
    n = rng.uniform(1.01, 2.0, n_cases)
    kinds = np.arange(n_cases) % 4
    k = np.select([kinds == 0, kinds == 1, kinds == 2, kinds == 3],
                  [0.0, 10.0 ** rng.uniform(-8, -6, n_cases), 10.0 ** rng.uniform(-5, 0, n_cases), 1.0])
    # make sure both ends of the x range are exercised whatever the draw
    x[:4] = [1e-3, 1.1e-3, 1e4, 9.5e3]
    return n + 1j * k, x


# --------------------------------------------------------------------------------------
# efficiencies against the oracle
# --------------------------------------------------------------------------------------


def test_efficiencies_match_miepython_random_cases():
    m, x = _random_cases()
    ours = mie.efficiencies(m, x)  # one vectorised call for all cases
    ref = np.array([_oracle(mi, xi) for mi, xi in zip(m, x)])
    # Relative error everywhere, no absolute floor: Q_sca at x = 1e-3 is ~1e-13 and g ~1e-7,
    # but both codes keep full *relative* accuracy there (our sums have no cancellation;
    # the oracle's a_1 loses only ~eps/x^2 ~ 2e-10), so a relative test is meaningful and
    # an absolute floor of 1e-12 would hide every error in the Rayleigh regime.
    for j, name in enumerate(("qext", "qsca", "g")):
        err = _rel(getattr(ours, name), ref[:, j])
        worst = int(np.argmax(err))
        assert err[worst] <= 1e-6, f"{name}: rel err {err[worst]:.2e} at m={m[worst]}, x={x[worst]:.4g}"


def test_small_sphere_branch_of_miepython_is_only_approximately_right():
    """Documents why the oracle above avoids miepython's small-sphere expansion near |m|x = 0.1."""
    for m, x in [(1.05 + 5e-8j, 0.09), (1.2 + 0j, 0.08), (1.5 + 1j, 0.05)]:
        e = mie.efficiencies(m, x)
        qext, qsca, _, g = miepython.efficiencies_mx(np.conj(m), x)
        exact = _oracle_from_coefficients(m, x)
        assert _rel(e.qext, exact[0]) < 1e-9 and _rel(e.g, exact[2]) < 1e-9
        assert _rel(e.qext, qext) < 1e-5 and _rel(e.g, g) < 1e-5  # the expansion's own accuracy


def test_coefficients_match_miepython():
    for m, x in [(1.5 + 0.02j, 3.0), (1.33 + 0j, 50.0), (2.0 + 1.0j, 200.0), (1.01 + 1e-6j, 0.5)]:
        a, b = mie.mie_coefficients(m, x)
        ra, rb = miepython.coefficients(np.conj(m), x)
        nn = min(a.size, ra.size)  # miepython truncates at int(...), we at ceil(...)
        scale = np.abs(ra).max()
        np.testing.assert_allclose(a[:nn], ra[:nn], rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(b[:nn], rb[:nn], rtol=0, atol=1e-10 * scale)


def test_mie_coefficients_n_max_and_padding():
    a, b = mie.mie_coefficients([1.5 + 0.01j, 1.5 + 0.01j], [0.5, 20.0])
    n_small, n_big = mie.wiscombe_nstop([0.5, 20.0])
    assert a.shape == (2, n_big)
    assert np.all(a[0, n_small:] == 0) and np.all(a[0, :n_small] != 0)
    a400, _ = mie.mie_coefficients(1.5 + 0.01j, 0.5, n_max=400)
    assert a400.shape == (400,) and np.all(np.isfinite(a400))
    np.testing.assert_allclose(a400[:n_small], a[0, :n_small], rtol=1e-13)
    assert np.all(np.abs(a400[n_small:]) < 1e-12 * np.abs(a400[0]))


# --------------------------------------------------------------------------------------
# amplitudes and phase function
# --------------------------------------------------------------------------------------

PHASE_CASES = [(1.5 + 0j, 0.1), (1.33 + 0.01j, 1.0), (1.5 + 1j, 10.0), (1.5 + 0.001j, 100.0), (1.33 + 0j, 300.0)]


@pytest.mark.parametrize("m, x", PHASE_CASES)
def test_phase_function_and_amplitudes_match_miepython(m, x):
    mu = np.cos(np.radians(np.linspace(0.0, 180.0, 721)))
    p = mie.phase_function(m, x, mu)
    # miepython's norm='one' is (|S1|^2+|S2|^2)/2 / (pi x^2 Q_sca): integrates to 1 over 4 pi, like ours
    ref = miepython.i_unpolarized(np.conj(m), x, mu, norm="one")
    np.testing.assert_allclose(p, ref, rtol=1e-6, atol=0)
    s1, s2 = mie.scattering_amplitudes(m, x, mu)
    r1, r2 = miepython.S1_S2(np.conj(m), x, mu, norm="wiscombe")  # unnormalised BH amplitudes, conjugated
    # relative to the unpolarised amplitude at each angle (S2 itself vanishes near 90 deg for small x)
    amp = np.sqrt((np.abs(r1) ** 2 + np.abs(r2) ** 2) / 2)
    assert np.max(np.abs(s1 - np.conj(r1)) / amp) < 1e-6
    assert np.max(np.abs(s2 - np.conj(r2)) / amp) < 1e-6


@pytest.mark.parametrize("m", [1.5 + 0j, 1.33 + 0.01j, 1.55 + 0.5j])
@pytest.mark.parametrize("x", [0.01, 1.0, 30.0, 1000.0])
def test_phase_function_normalised_gauss_legendre(m, x):
    # |S1|^2 + |S2|^2 is a polynomial of degree 2 nstop in mu: Gauss–Legendre with
    # nstop + 2 nodes integrates it exactly, so this tests the normalisation, not the grid.
    nodes, weights = np.polynomial.legendre.leggauss(int(mie.wiscombe_nstop(x)) + 2)
    integral = 2 * np.pi * np.dot(weights, mie.phase_function(m, x, nodes))
    assert abs(integral - 1.0) < 1e-4
    assert abs(integral - 1.0) < 1e-7  # in fact it holds to rounding


@pytest.mark.parametrize("x", [5.0, 200.0, 1000.0])
def test_phase_function_normalised_on_angle_grid(x):
    """Independent of the polynomial argument: trapezoid rule in theta with spacing 0.02/x
    over the forward peak (theta < 50/x; the peak has width ~1/x) and 0.3/x beyond, where
    p is smaller by ~x^-3 (trapezoid error ~3e-5 at these spacings)."""
    a = min(50.0 / x, np.pi)
    theta = np.unique(np.concatenate([np.arange(0.0, a, 0.02 / x),
                                      np.linspace(a, np.pi, max(2, int((np.pi - a) / (0.3 / x)) + 2))]))
    p = mie.phase_function(1.33 + 1e-4j, x, np.cos(theta))
    integral = 2 * np.pi * trapezoid(p * np.sin(theta), theta)
    assert abs(integral - 1.0) < 1e-4


def test_phase_function_shape_and_forward_peak():
    p = mie.phase_function(1.33 + 0j, 100.0, np.array([1.0, 0.9, 0.0, -1.0]))
    assert np.all(p > 0) and p[0] > 100 * p[1]


# --------------------------------------------------------------------------------------
# physical limits and identities
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("m", [1.5 + 0j, 1.33 + 0.01j, 2.0 + 1.0j, 1.0001 + 0j, 1.7 + 1e-7j])
def test_rayleigh_limit(m):
    x = 1e-3
    e = mie.efficiencies(m, x)
    alpha = (m * m - 1) / (m * m + 2)
    # BH Eq. 5.8/5.11: relative corrections are O(x^2) = 1e-6 (times factors of order |m|^2)
    assert float(e.qsca) == pytest.approx(8.0 / 3.0 * x**4 * abs(alpha) ** 2, rel=1e-5)
    if m.imag > 0:
        # absorption: Q_abs = 4 x Im(alpha) (1 + O(x^2)) as long as it dominates the x^3 term
        assert float(e.qabs) == pytest.approx(4 * x * alpha.imag, rel=1e-4)
    mu = np.linspace(-1, 1, 11)
    np.testing.assert_allclose(mie.phase_function(m, x, mu), 3 / (16 * np.pi) * (1 + mu**2), rtol=1e-5)
    assert abs(float(e.g)) < 1e-5


@pytest.mark.parametrize("m", [1.33 + 0j, 1.5 + 0.01j, 2.0 + 1.0j, 1.1 + 0j])
def test_extinction_paradox(m):
    assert abs(float(mie.efficiencies(m, 1e4).qext) - 2.0) < 1e-2


def test_non_absorbing_sphere_does_not_absorb():
    x = np.geomspace(0.1, 1000.0, 25)
    e = mie.efficiencies(1.45 + 0j, x)
    assert np.all(np.abs(e.qabs) <= 1e-10)
    # independent of how qabs is formed: Re a_n = |a_n|^2 for every order (optical theorem per term)
    a, b = mie.mie_coefficients(1.45 + 0j, x)
    n = np.arange(1, a.shape[-1] + 1)
    qabs_series = 2 / x**2 * np.sum((2 * n + 1) * (a.real - np.abs(a) ** 2 + b.real - np.abs(b) ** 2), axis=-1)
    assert np.all(np.abs(qabs_series) <= 1e-10)


def test_optical_theorem_and_backscatter_identities():
    m = np.array([1.5 + 0.01j, 1.33 + 0j, 2.0 + 1.0j])[:, None]
    x = np.array([0.3, 7.0, 150.0])[None, :]
    e = mie.efficiencies(m, x)
    s1, s2 = mie.scattering_amplitudes(m, x, np.array([1.0, -1.0]))
    np.testing.assert_allclose(e.qext, 4 / x**2 * s1[..., 0].real, rtol=1e-10)
    np.testing.assert_allclose(s1[..., 0], s2[..., 0], rtol=1e-12)
    np.testing.assert_allclose(s1[..., 1], -s2[..., 1], rtol=1e-12)
    np.testing.assert_allclose(e.qback, 4 * np.pi * e.qsca * mie.phase_function(m, x, -1.0), rtol=1e-10)
    # Q_ext = Q_sca + Q_abs, and the efficiencies agree with the coefficient sums
    np.testing.assert_allclose(e.qext, e.qsca + e.qabs, rtol=1e-14)
    assert np.all(e.qabs[[0, 2]] > 0) and np.all(e.qabs[1] == 0)


def test_energy_bounds_on_random_inputs():
    rng = np.random.default_rng(7)
    m = rng.uniform(0.2, 3.0, 300) + 1j * 10.0 ** rng.uniform(-9, 1, 300)
    x = 10.0 ** rng.uniform(-4, 2.5, 300)
    e = mie.efficiencies(m, x)
    assert np.all(e.qsca > 0) and np.all(e.qabs >= 0) and np.all(e.qback >= 0)
    assert np.all(np.abs(e.g) <= 1)
    np.testing.assert_allclose(e.qext, e.qsca + e.qabs, rtol=1e-14)


# --------------------------------------------------------------------------------------
# robustness, numerics and bookkeeping
# --------------------------------------------------------------------------------------


def test_extreme_inputs_are_finite():
    m = np.array([1.0001 + 0j, 1.5 + 0j, 1.5 + 10j, 1.33 + 1e-9j, 0.5 + 0j, 3.0 + 0.1j])[:, None]
    x = np.array([1e-6, 1e-3, 1.0, 1e3, 2e4])[None, :]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning (overflow, invalid) may escape either
        e = mie.efficiencies(m, x)
        p = mie.phase_function(m, x[:, :3], np.linspace(-1, 1, 9))
    for name in e._fields:
        v = getattr(e, name)
        assert v.shape == (6, 5)
        assert np.all(np.isfinite(v)), name
    assert np.all(e.qsca > 0)
    # x = 2e4, strongly absorbing: reflection + diffraction, Q_ext still ~2
    assert abs(float(e.qext[2, -1]) - 2) < 1e-2
    assert np.all(np.isfinite(p)) and np.all(p > 0)


def test_downward_recurrence_start_is_converged():
    """Results do not change when the downward recurrence starts 600 + 16 |z|^(1/3) orders
    above max(nstop, |mx|) — BH's max(nstop, |mx|) + 15 fails this at the 1e-3 level."""
    m = np.array([2.0 + 0j, 1.33 + 1e-3j, 1.5 + 1.0j, 1.0001 + 0j])[:, None]
    x = np.array([3.0, 300.0, 5000.0])[None, :]
    ours = mie.efficiencies(m, x)
    orig = mie._start_order
    try:
        mie._start_order = lambda nstop, z: (np.maximum(nstop, np.abs(z)) + 600 + 16 * np.cbrt(np.abs(z))).astype(
            np.int64) + 1
        far = mie.efficiencies(m, x)
    finally:
        mie._start_order = orig
    for name in ("qext", "qsca", "qback", "g"):
        np.testing.assert_allclose(getattr(ours, name), getattr(far, name), rtol=1e-12)


def test_chunking_does_not_change_results(monkeypatch):
    rng = np.random.default_rng(11)
    m = rng.uniform(1.01, 2.0, 40) + 1j * rng.choice([0.0, 1e-3, 0.5], 40)
    x = 10.0 ** rng.uniform(-3, 2.7, 40)
    mu = np.linspace(-1, 1, 13)
    big = mie.efficiencies(m, x)
    p_big = mie.phase_function(m, x, mu)
    monkeypatch.setattr(mie, "_WORK_ELEMENTS", 300)
    monkeypatch.setattr(mie, "_BLOCK_ELEMENTS", 7)
    monkeypatch.setattr(mie, "_ANGLE_ELEMENTS", 5)
    small = mie.efficiencies(m, x)
    for name in big._fields:
        np.testing.assert_allclose(getattr(small, name), getattr(big, name), rtol=1e-13)
    np.testing.assert_allclose(mie.phase_function(m, x, mu), p_big, rtol=1e-12)
    # and each particle alone gives the same as in the batch
    for i in (0, 17, 39):
        single = mie.efficiencies(m[i], x[i])
        assert float(single.qext) == pytest.approx(float(big.qext[i]), rel=1e-13)


def test_shapes_and_broadcasting():
    m = np.array([1.5 + 0j, 1.33 + 0.1j, 2.0 + 0j])[:, None]
    x = np.array([0.1, 1.0, 10.0, 100.0])
    mu = np.linspace(-1, 1, 10).reshape(5, 2)
    e = mie.efficiencies(m, x)
    assert all(getattr(e, f).shape == (3, 4) for f in e._fields)
    s1, s2 = mie.scattering_amplitudes(m, x, mu)
    assert s1.shape == s2.shape == (3, 4, 5, 2) and np.iscomplexobj(s1)
    assert mie.phase_function(m, x, mu).shape == (3, 4, 5, 2)
    scalar = mie.efficiencies(1.5, 2.0)
    assert scalar.qext.shape == () and float(scalar.qext) == float(mie.efficiencies(1.5, [2.0]).qext[0])
    assert mie.phase_function(1.5, 2.0, 0.3).shape == ()


@pytest.mark.parametrize("kwargs", [
    dict(m=1.5 - 0.01j, x=1.0),          # miepython's sign convention
    dict(m=1.5, x=0.0),
    dict(m=1.5, x=-1.0),
    dict(m=1.5, x=np.inf),
    dict(m=0.0, x=1.0),
    dict(m=complex(np.nan, 0), x=1.0),
])
def test_bad_inputs_raise(kwargs):
    with pytest.raises(SkymodelInputError):
        mie.efficiencies(**kwargs)


def test_bad_mu_and_non_scattering_sphere_raise():
    with pytest.raises(SkymodelInputError):
        mie.phase_function(1.5, 1.0, [0.0, 1.5])
    with pytest.raises(SkymodelInputError):
        mie.phase_function(1.0, 1.0, [0.0])
    e = mie.efficiencies(1.0, 5.0)  # index-matched sphere: no scattering, no NaN
    assert float(e.qext) == 0 and float(e.g) == 0
