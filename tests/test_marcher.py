"""The deterministic marcher on synthetic media: geometry, limits and invariants."""

import numpy as np
import pytest
from skymodel.validation.synthetic import synthetic_profile

from skymodel.render.marcher import MarchSettings, SkyMarcher, profile_at_wavelengths
from skymodel.render.rays import direction_from_angles

FAST = MarchSettings(view_steps=48, table_altitudes=16, table_mu=16, table_phi=8, table_mus=16,
                     sun_table_altitudes=48, sun_table_x=96, sun_table_steps=96, ms_wavelength_step_nm=100,
                     grid_zenith=32, grid_zenith_ground=12, grid_azimuth=19)
WL = (450.0, 550.0, 650.0)


def dirs(zen, az):
    return direction_from_angles(np.asarray(zen, float), np.asarray(az, float))


@pytest.fixture(scope="module")
def prof():
    return synthetic_profile(WL)


def test_vertical_transmittance_matches_column_optical_depth(prof):
    m = SkyMarcher(prof, 90.0, 0.0, settings=FAST)
    tau = prof.vertical_optical_depth(prof.extinction)
    np.testing.assert_allclose(m.direct_sun_irradiance(), prof.solar_irradiance * np.exp(-tau), rtol=2e-3)


def test_finite_non_negative_everywhere(prof):
    d = dirs(np.linspace(0, 180, 37), np.linspace(0, 350, 37))
    for elev in (-12.0, -4.0, 0.0, 5.0, 60.0):
        for alt in (0.0, 10_000.0, 120_000.0):
            r = SkyMarcher(prof, elev, 180.0, alt, FAST).radiance(d)
            assert np.all(np.isfinite(r.radiance)) and np.all(r.radiance >= 0), (elev, alt)


def test_zero_albedo_reflects_nothing(prof):
    down = dirs([120.0, 150.0, 180.0], [0.0, 90.0, 180.0])
    black = SkyMarcher(prof.with_(ground_albedo=np.zeros(3)), 30.0, 180.0, 0.0, FAST).radiance(down)
    assert np.all(black.ground == 0)
    assert np.all(black.radiance == 0)  # observer on the ground sees the ground directly, no air between
    grey = SkyMarcher(prof, 30.0, 180.0, 0.0, FAST).radiance(down)
    assert np.all(grey.radiance > 0)


def test_linear_in_solar_spectrum(prof):
    d = dirs([0, 45, 85, 100], [0, 180, 90, 180])
    a = SkyMarcher(prof, 20.0, 180.0, 1000.0, FAST).radiance(d).radiance
    scale = np.array([0.5, 2.0, 3.0])
    b = SkyMarcher(prof.with_(solar_irradiance=prof.solar_irradiance * scale), 20.0, 180.0, 1000.0, FAST).radiance(d)
    np.testing.assert_allclose(b.radiance, a * scale, rtol=1e-5)


def test_sun_at_horizon_has_no_jump(prof):
    """Near sunset the sky dims by ~1-2 % per 0.02 degree of sun elevation toward the
    sun (physically: the sunlit part of the atmosphere shrinks), so the criterion is that
    the step across 0 (-0.01 -> +0.01) differs from the neighbouring equal steps by less
    than 1 % of the radiance: a discontinuity (a shadow test or table switching at the
    horizon) would show up there."""
    d = dirs([0, 30, 60, 85, 89], [0, 180, 180, 180, 0])
    lv = [SkyMarcher(prof, e, 180.0, 0.0, FAST).radiance(d).radiance for e in (-0.03, -0.01, 0.01, 0.03)]
    steps = [b - a for a, b in zip(lv, lv[1:])]
    jump = np.abs(steps[1] - 0.5 * (steps[0] + steps[2])) / lv[2]
    assert np.max(jump) < 0.01
    assert np.max(np.abs(lv[2] - lv[1]) / lv[2]) < 0.03


def test_twilight_is_dark_and_deep_night_darker(prof):
    zen = dirs([0.0], [0.0])
    day = SkyMarcher(prof, 5.0, 180.0, 0.0, FAST).radiance(zen).radiance
    dusk = SkyMarcher(prof, -4.0, 180.0, 0.0, FAST).radiance(zen).radiance
    night = SkyMarcher(prof, -12.0, 180.0, 0.0, FAST).radiance(zen).radiance
    assert np.all(dusk < 0.2 * day) and np.all(dusk > 0)
    assert np.all(night < 0.05 * dusk)


def test_aod_to_zero_tends_to_rayleigh_only():
    d = dirs([0, 45, 80], [0, 180, 90])
    clean = synthetic_profile(WL, aod550=0.0)
    ref = SkyMarcher(clean, 30.0, 180.0, 0.0, FAST).radiance(d).radiance
    tiny = SkyMarcher(synthetic_profile(WL, aod550=1e-6), 30.0, 180.0, 0.0, FAST).radiance(d).radiance
    np.testing.assert_allclose(tiny, ref, rtol=1e-4)


def test_grid_matches_exact_evaluation(prof):
    rng = np.random.default_rng(3)
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    grid = SkyMarcher(prof, 25.0, 140.0, 0.0, MarchSettings()).radiance(d).radiance
    exact = SkyMarcher(prof, 25.0, 140.0, 0.0, MarchSettings(exact=True)).radiance(d).radiance
    err = np.abs(grid - exact) / exact
    assert np.median(err) < 1e-3 and np.percentile(err, 95) < 5e-3


def test_multiple_scattering_orders_converge(prof):
    d = dirs([0, 60], [0, 0])  # zenith and the anti-sun side
    r1 = SkyMarcher(prof, 30.0, 180.0, 0.0, MarchSettings(orders=1, exact=True)).radiance(d)
    assert np.all(r1.multiple == 0)
    full = SkyMarcher(prof, 30.0, 180.0, 0.0, MarchSettings(exact=True))
    r = full.radiance(d)
    assert np.all(r.multiple > 0.1 * r.single)  # multiple scattering matters in the blue
    c = full.field.order_contributions
    assert all(b < a for a, b in zip(c, c[1:]))  # each order adds less than the previous


def test_layered_profile_renders(prof):
    lay = prof.layered(n_layers=12)
    d = dirs([0, 60, 89], [0, 180, 180])
    a = SkyMarcher(lay, 30.0, 180.0, 0.0, FAST).radiance(d).radiance
    b = SkyMarcher(prof, 30.0, 180.0, 0.0, FAST).radiance(d).radiance
    assert np.all(np.isfinite(a)) and np.max(np.abs(a - b) / b) < 0.2


def test_profile_at_wavelengths_is_identity_on_the_same_grid(prof):
    same = profile_at_wavelengths(prof, prof.wavelengths_nm)
    np.testing.assert_allclose(same.rayleigh_scattering, prof.rayleigh_scattering)
    np.testing.assert_allclose(same.aerosol_phase, prof.aerosol_phase)


def test_bad_observer_altitude_named(prof):
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError, match="observer_altitude"):
        SkyMarcher(prof, 30.0, 180.0, 500_000.0, FAST)


@pytest.mark.parametrize("aod, elev, bias", [(0.0, 30.0, 0.03), (0.2, 60.0, 0.06), (0.2, 20.0, 0.06)])
def test_agrees_with_monte_carlo(aod, elev, bias):
    """The deterministic marcher against the independent Monte Carlo tracer (low
    resolution; the full comparison is in benchmarks/). Measured with 40k paths: Rayleigh
    only within the MC noise (<= 2.3 %); with aerosols (HG g = 0.7, AOD 0.2) 0-5 %,
    worst near the horizon toward a low sun (the delta-M truncation of the forward peak
    inside the multiple-scattering solver): the allowance below is that bias plus 4 sigma."""
    from skymodel.validation.montecarlo import trace_radiance

    prof = synthetic_profile((450.0, 650.0), aod550=aod)
    d = dirs([0, 45, 70, 85, 60], [0, 0, 180, 0, 90])
    mc = trace_radiance(prof, d, elev, 180.0, n_paths=6000, seed=11)
    r = SkyMarcher(prof, elev, 180.0, 0.0, MarchSettings(exact=True)).radiance(d).radiance
    assert np.all(np.abs(r - mc.radiance) < 4 * mc.stderr + bias * mc.radiance)


#: views of the low-resolution comparison with real aerosols: zenith angle, azimuth from
#: the sun (degrees). Not the horizon toward the sun: with the default 12-degree delta-M
#: cone that is the peak aureole's small-angle approximation (docs/accuracy.md, "The
#: sunward horizon at sunset"); the benchmark's converged settings cover it.
REAL_VIEWS = ((0.0, 0.0), (45.0, 0.0), (45.0, 180.0), (80.0, 0.0), (80.0, 180.0), (88.0, 180.0))


@pytest.mark.slow
@pytest.mark.parametrize("elev", [60.0, 20.0, 5.0, 0.0, -4.0])
@pytest.mark.parametrize("aerosol, aod", [("rural", 0.2), ("desert", None)])
def test_agrees_with_monte_carlo_real_aerosols(aerosol, aod, elev):
    """Issue 3's comparison at low resolution: Mie aerosols of two types, the five sun
    elevations, default tables, 4k MC paths (60k at twilight). Every entry within 4
    standard errors + 1 %, and the mean over the entries within 4 of its standard errors
    + 1 %. Measured (revision 2d94d81): the entries lie at least 3.1 points inside that
    bound, the means at -0.3..+2.9 % (se 1.1-2.3 %). Without the spherical transport
    (columns) the twilight means fall to -12 % (rural) and -18 % (desert), entries up to 9
    points beyond the bound; without the peak aureole desert at 5 degrees has an entry
    5 points beyond it. The full comparison: benchmarks/validate_montecarlo.py."""
    from skymodel import Atmosphere
    from skymodel.validation.montecarlo import trace_radiance

    # the OPAC mixtures the figures above were measured with (issue 20 made the paper's model the
    # default; its desert, g 0.94, needs a reference with the diffraction peak cut:
    # tests/test_aerosols_paper.py::test_marcher_vs_monte_carlo_paper_desert)
    prof = Atmosphere(location=aerosol, month=6, aod550=aod, aerosol_model="opac").optical_profile((450.0, 650.0))
    d = dirs([v[0] for v in REAL_VIEWS], [180.0 + v[1] for v in REAL_VIEWS])
    mc = trace_radiance(prof, d, elev, 180.0, n_paths=60_000 if elev < 0 else 4000, seed=31)
    r = SkyMarcher(prof, elev, 180.0, 0.0, MarchSettings(exact=True)).radiance(d).radiance
    rel = r / mc.radiance - 1.0
    se = mc.stderr / mc.radiance
    assert np.all(np.abs(rel) <= 4.0 * se + 0.01), np.round(100 * rel, 1)
    mean_se = np.sqrt(np.sum(se**2)) / se.size
    assert abs(rel.mean()) <= 4.0 * mean_se + 0.01, (rel.mean(), mean_se)


def test_chunk_size_does_not_change_the_result():
    """Directions are marched in chunks (memory ~ chunk), the near-sun ones included: the
    chunk size changes nothing."""
    from dataclasses import replace

    from skymodel import Atmosphere
    from skymodel.render.sky import quality_settings

    prof = Atmosphere(location="rural", month=6).optical_profile([450, 650])
    d = np.random.default_rng(1).normal(size=(600, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    s = replace(quality_settings("preview"), sun_exact_deg=60.0)
    whole = SkyMarcher(prof, 30.0, 180.0, 0.0, replace(s, chunk=100_000)).radiance(d).radiance
    pieces = SkyMarcher(prof, 30.0, 180.0, 0.0, replace(s, chunk=37)).radiance(d).radiance
    np.testing.assert_array_equal(whole, pieces)


@pytest.mark.parametrize("exact", [False, True])
def test_single_component_is_true_single_scattering(exact):
    """With multiple scattering on, ``single`` (and the directly lit ``ground``) are what an
    orders=1 render gives: true extinction, full phase functions, not the delta-M reduced
    extinction the solver uses (that bookkeeping goes with ``multiple``, never negative)."""
    from dataclasses import replace

    from skymodel import Atmosphere

    prof = Atmosphere(location="desert", month=6).optical_profile([450.0, 650.0])
    s = replace(FAST, exact=exact, delta_m_cutoff_deg=12.0)
    d = dirs([0, 30, 60, 85, 89, 95, 120, 170, 5, 60], [0, 180, 90, 180, 0, 180, 30, 0, 175, 170])
    full = SkyMarcher(prof, 30.0, 180.0, 0.0, s).radiance(d)
    once = SkyMarcher(prof, 30.0, 180.0, 0.0, replace(s, orders=1)).radiance(d)
    assert full.info["orders"] > 1 and once.info["orders"] == 1
    np.testing.assert_allclose(full.single, once.single, rtol=1e-12, atol=0)
    np.testing.assert_allclose(full.ground, once.ground, rtol=1e-12, atol=0)
    assert np.all(full.multiple >= 0) and np.all(full.multiple[d[:, 2] > 0] > 0)
