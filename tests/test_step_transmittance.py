"""The view-ray quadrature's step transmittance (skymodel.render.medium.step_transmittance):
exact for a source constant over each step, so grazing rays through the boundary layer
(optical depths of 0.3-1 per step) are not biased low as with the midpoint value."""

import numpy as np
from skymodel.validation.synthetic import synthetic_profile

from skymodel.render.marcher import MarchSettings, SkyMarcher
from skymodel.render.medium import step_transmittance
from skymodel.render.rays import direction_from_angles


def test_gathers_exactly_one_minus_the_end_transmittance():
    rng = np.random.default_rng(5)
    tau = rng.exponential(0.4, size=(7, 33, 3))  # (rays, steps, wavelengths), thick and thin steps
    tau[:, :4] = 0.0  # empty steps
    got = (step_transmittance(tau) * tau).sum(axis=1)
    np.testing.assert_allclose(got, -np.expm1(-tau.sum(axis=1)), rtol=1e-12, atol=1e-15)


def test_exact_for_a_homogeneous_medium_at_any_step_count():
    # integral_0^L exp(-k t) dt = (1 - exp(-k L)) / k, with 1, 3 and 40 steps alike
    k, length = 0.7, 5.0
    exact = -np.expm1(-k * length) / k
    for n in (1, 3, 40):
        dt = np.full((1, n), length / n)
        got = (step_transmittance(k * dt) * dt).sum()
        assert abs(got / exact - 1) < 1e-12, n


def test_thin_steps_are_the_midpoint_value():
    tau = np.full((1, 5, 1), 1e-10)
    mid = np.exp(-(np.cumsum(tau, axis=1) - 0.5 * tau))
    np.testing.assert_allclose(step_transmittance(tau), mid, rtol=1e-12)


def test_grazing_single_scattering_does_not_depend_on_the_view_steps():
    # single scattering (orders=1) one degree above the horizon: the steps near the
    # observer are optically thick; 64 steps must agree with 512 (the midpoint value was
    # ~1 % low at rural AOD 0.2 against the Monte Carlo tracer)
    prof = synthetic_profile((450.0, 650.0))
    d = direction_from_angles(np.array([89.0, 89.0, 85.0]), np.array([0.0, 180.0, 90.0]))
    r = [SkyMarcher(prof, 60.0, 180.0, 0.0, MarchSettings(orders=1, exact=True, view_steps=n)).radiance(d).radiance
         for n in (64, 512)]
    assert np.max(np.abs(r[0] / r[1] - 1)) < 2e-3
