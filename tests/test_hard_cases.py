"""Hard cases stay numerically stable (issue 3): twilight, grazing and tangent rays,
observers on the ground, at the top of the atmosphere and in space, extreme aerosol
loads, no aerosol / no ozone, albedo 0 and 1, odd wavelength grids and the extremes of
Lorentz-Mie theory.

Every check asks for more than "no exception": finite and non-negative radiance,
physical bounds or orderings, and continuity. Continuity thresholds are derived, not
picked: if f is smooth near a pair of samples a small step h apart, the mean value
theorem bounds |f(a + h) - f(a)| by h max|f'|. We estimate max|f'| (of log f) from the
difference quotients on the coarse intervals on either side of the pair, which do not
contain it (so a jump there cannot inflate them), and allow 3 times that, because the
quotients average the slope over their intervals. A jump J between the pair fails the
check once J > 3 h max|f'|: for the 0.01-degree sun steps here, a few tenths of a
percent.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skymodel.validation.synthetic import synthetic_profile

from skymodel.optics import mie
from skymodel.optics.aerosols import aerosol_types
from skymodel.render.marcher import MarchSettings, SkyMarcher
from skymodel.render.rays import atmosphere_segment, direction_from_angles
from skymodel.render.sun_transmittance import SUN_ANGULAR_RADIUS_RAD

WL = (450.0, 550.0, 650.0)
#: Small tables: these tests probe stability, not accuracy (tests/test_marcher.py and
#: benchmarks/validate_montecarlo.py do accuracy).
SMALL = MarchSettings(view_steps=48, table_altitudes=16, table_mu=16, table_phi=8, table_mus=16,
                      sun_table_altitudes=48, sun_table_x=96, sun_table_steps=96, ms_wavelength_step_nm=100,
                      exact=True)
TINY = replace(SMALL, table_altitudes=10, table_mu=8, table_phi=4, table_mus=10, table_steps=24, view_steps=32)
SINGLE = replace(SMALL, orders=1)
SUN_RADIUS_DEG = float(np.degrees(SUN_ANGULAR_RADIUS_RAD))
R_E = 6_360_000.0  # the profiles' planet radius, m
TOP = 100_000.0  # their top of the atmosphere, m


def dirs(zen_deg, az_deg):
    return direction_from_angles(np.asarray(zen_deg, float), np.asarray(az_deg, float))


def horizon_zenith(h, radius):
    """Zenith angle (rad) of the ray from altitude h (above a sphere of radius R_E)
    tangent to a sphere of ``radius`` below the observer."""
    return np.pi - np.arcsin(radius / (R_E + h))


def zen_dirs(zen_rad, az_deg=0.0):
    z = np.asarray(zen_rad, float)
    a = np.radians(az_deg)
    return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)], axis=-1)


def check_physical(r):
    for part in (r.single, r.multiple, r.ground, r.radiance):
        assert np.all(np.isfinite(part)) and np.all(part >= 0.0)


def assert_continuous(values, x, pair):
    """``values`` (n, ...) sampled at increasing ``x`` (n,); ``pair`` = (i, i + 1) the
    two neighbours a small step apart, the other samples form the coarse grid around
    them. Relative change across the pair <= 3 x the largest coarse slope x the step."""
    v = np.log(np.maximum(np.asarray(values, float), 1e-300))
    i, j = pair
    coarse = [k for k in range(len(x) - 1) if k != i]
    slopes = [np.abs(v[k + 1] - v[k]) / (x[k + 1] - x[k]) for k in coarse]
    allowed = 3.0 * np.max(slopes, axis=0) * (x[j] - x[i]) + 1e-9
    jump = np.abs(v[j] - v[i])
    assert np.all(jump <= allowed), (jump, allowed)


@pytest.fixture(scope="module")
def prof():
    return synthetic_profile(WL)


# --------------------------------------------------------------------------------------
# ray geometry: tangent and near-tangent rays
# --------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)  # exact geometry: random draws each run
@given(h=st.floats(0.0, 120_000.0), offset=st.floats(-1e-5, 1e-5), sphere=st.sampled_from(["ground", "top"]))
def test_near_tangent_segments_are_exact_and_consistent(h, offset, sphere):
    """A ray at zenith angle (tangent + offset) from altitude h: its segment in the
    atmosphere is finite and ordered, and whether it meets the ground, misses the
    atmosphere or crosses it, and the distances, follow from the closest approach of
    the line to the planet's centre (computed here from the angle, not the dot
    products of rays.py)."""
    radius = R_E if sphere == "ground" else R_E + TOP
    if sphere == "top" and h <= TOP:
        return  # no tangent to the top from inside
    z = horizon_zenith(h, radius) + offset
    z = min(z, np.pi)
    d = zen_dirs(z)[None]
    r0 = R_E + h
    p = np.array([[0.0, 0.0, r0]])
    t0, t1, hits = atmosphere_segment(p, d, R_E, R_E + TOP)
    assert np.isfinite(t0[0]) and np.isfinite(t1[0]) and 0.0 <= t0[0] <= t1[0]
    h = r0 - R_E  # the altitude as represented (R_E + 1e-7 m is rounded to ~1e-9 m)
    # closest approach of the line to the centre: distance ``along`` ahead, radius b with
    # R^2 - b^2 = along^2 - (r0^2 - R^2) (no cancellation of b ~ R)
    along = -r0 * np.cos(z)
    ground_gap = along**2 - h * (2 * R_E + h)  # R^2 - b^2
    top_gap = along**2 - (h - TOP) * (2 * R_E + h + TOP)  # (R + top)^2 - b^2
    # a direction from angles is tangent only to rounding: leave the undecidable ones out
    fuzz = 1e-9 * (along**2 + r0 * r0 * 1e-6) + 1e-6
    if min(abs(ground_gap), abs(top_gap)) < fuzz:
        return
    if ground_gap > 0 and along > 0:  # strictly crosses the ground ahead
        assert hits[0]
        np.testing.assert_allclose(t1[0], along - np.sqrt(ground_gap), rtol=1e-6, atol=1e-6)
    elif top_gap < 0 or (h > TOP and along <= 0):  # misses the atmosphere
        assert not hits[0] and t1[0] - t0[0] == 0.0
    elif ground_gap < 0:  # passes above the ground: a chord through the top sphere
        assert not hits[0]
        half = np.sqrt(top_gap)
        np.testing.assert_allclose(t1[0] - t0[0], along + half - max(along - half, 0.0), rtol=1e-6, atol=1e-3)


def test_exactly_tangent_rays():
    """Exactly horizontal from the ground (b^2 == c with no rounding): counted as
    meeting the ground at distance 0 (it touches once); the rays within rounding of the
    tangent from above meet it at the tangent distance; tangent to the top from space:
    a chord of (almost) zero length, no ground."""
    for d in ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5), 0.0]):
        t0, t1, hits = atmosphere_segment(np.array([[0.0, 0.0, R_E]]), np.array([d]), R_E, R_E + TOP)
        assert hits[0] and t0[0] == 0.0 and t1[0] == 0.0
    for h in (10_000.0, 100_000.0, 120_000.0):
        d = zen_dirs(horizon_zenith(h, R_E) + np.array([-1e-9, 1e-9]))
        t0, t1, hits = atmosphere_segment(np.full((2, 3), [0.0, 0.0, R_E + h]), d, R_E, R_E + TOP)
        assert not hits[0] and hits[1] and np.all(np.isfinite(t1))
        # 1e-9 rad below the tangent the ray meets the ground ~70 m before the tangent point
        along = -(R_E + h) * d[1, 2]
        np.testing.assert_allclose(t1[1], along - np.sqrt(along**2 - h * (2 * R_E + h)), rtol=1e-7)
        assert t1[0] - t0[0] > t1[1] - t0[1]  # the ray that misses goes on through the air
    d = zen_dirs(horizon_zenith(120_000.0, R_E + TOP))[None]
    t0, t1, hits = atmosphere_segment(np.array([[0.0, 0.0, R_E + 120_000.0]]), d, R_E, R_E + TOP)
    assert not hits[0] and abs(t1[0] - t0[0]) < 50.0  # touches the top sphere only


# --------------------------------------------------------------------------------------
# twilight and the terminator
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def twilight(prof):
    return {e: SkyMarcher(prof, e, 180.0, 0.0, SMALL) for e in (-12.0, -6.0, -4.0, -SUN_RADIUS_DEG, 0.0, 5.0)}


TWILIGHT_DIRS = dirs([0.0, 60.0, 85.0, 89.9, 85.0, 89.9, 120.0], [0.0, 180.0, 180.0, 180.0, 0.0, 0.0, 180.0])


def test_twilight_sequence_is_finite_ordered_and_shadowed(twilight):
    res = {e: m.radiance(TWILIGHT_DIRS) for e, m in twilight.items()}
    for r in res.values():
        check_physical(r)
    elevs = sorted(res)
    # every sky direction brightens as the sun rises (the sunlit part of the air grows)
    sky = np.array([res[e].radiance[:6] for e in elevs])
    assert np.all(np.diff(sky, axis=0) > 0)
    # -12 degrees: the shadow is 140 km above the observer: no single scattering overhead
    assert np.all(res[-12.0].single[0] == 0.0)
    # but light scattered twice from the lit air toward the sun still arrives
    assert np.all(res[-12.0].multiple[0] > 0.0)
    # at twilight the horizon under the sun outshines the anti-sun horizon (where the
    # Earth's shadow rises), and in the red also the zenith (in the blue the long
    # grazing path toward the sun dims it below the zenith)
    for e in (-6.0, -4.0):
        r = res[e].radiance
        assert r[3, 2] > r[0, 2] and np.all(r[3] > r[5])
    # the ground (albedo 0.2) seen from the ground gets no direct sun below the horizon
    for e in (-12.0, -6.0, -4.0, -SUN_RADIUS_DEG):
        np.testing.assert_array_equal(twilight[e].direct_sun_irradiance(), 0.0)
    # sun centre on the horizon: exactly half the disc, through the grazing air mass
    half = twilight[0.0].direct_sun_irradiance()
    assert np.all(half > 0) and np.all(half < 0.5 * twilight[5.0].direct_sun_irradiance())


def test_visible_fraction_of_the_disc_at_the_horizon(twilight):
    sun = twilight[0.0].sun_table
    h = np.zeros(5)
    mu = np.sin(np.radians([-SUN_RADIUS_DEG, -0.5 * SUN_RADIUS_DEG, 0.0, 0.5 * SUN_RADIUS_DEG, SUN_RADIUS_DEG]))
    f = sun.visible_fraction(h, mu)
    np.testing.assert_allclose(f[[0, 2, 4]], [0.0, 0.5, 1.0], atol=1e-9)
    np.testing.assert_allclose(f[1] + f[3], 1.0, atol=1e-12)  # symmetric about the horizon
    # from 10 km the horizon dips by 3.2 degrees: a sun at -0.27 degrees is whole
    assert sun.visible_fraction(np.array([10_000.0]), np.sin(np.radians([-SUN_RADIUS_DEG])))[0] == 1.0


@pytest.mark.parametrize("edge", [-SUN_RADIUS_DEG, 0.0])
def test_no_jump_across_the_terminator(prof, edge):
    """Single-scattered sky and the direct sun at the observer, as the sun's upper limb
    (-0.27 deg) or its centre (0 deg) crosses the horizon: pair 0.01 deg apart,
    coarse grid 0.1 deg around it (threshold derived in the module docstring)."""
    elevs = np.array([edge - 0.2, edge - 0.1, edge - 0.005, edge + 0.005, edge + 0.1, edge + 0.2])
    d = dirs([0.0, 60.0, 85.0, 89.0], [0.0, 180.0, 180.0, 0.0])
    sky, sun = [], []
    for e in elevs:
        m = SkyMarcher(prof, float(e), 180.0, 0.0, SINGLE)
        r = m.radiance(d)
        check_physical(r)
        sky.append(r.radiance)
        sun.append(m.direct_sun_irradiance())
    assert_continuous(sky, elevs, (2, 3))
    if edge == 0.0:  # the direct beam is 0 until the upper limb rises (at -0.27)
        assert_continuous(sun, elevs, (2, 3))
    else:
        assert np.all(np.array(sun[:3]) == 0.0) and np.all(np.array(sun[3:]) > 0.0)
        assert np.all(np.array(sun[3]) < 0.02 * np.array(sun[-1]))  # a sliver of the disc


# --------------------------------------------------------------------------------------
# horizontal, grazing and tangent view rays; observers from 0 m to space
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def observers(prof):
    return {h: SkyMarcher(prof, 20.0, 180.0, h, SMALL) for h in (0.0, 10_000.0, TOP, 120_000.0)}


@pytest.mark.parametrize("h", [0.0, 10_000.0, TOP, 120_000.0])
def test_rays_at_the_horizon(observers, h):
    """View rays at the observer's geometric horizon and within 1e-6 rad of it, toward
    and away from the sun: finite, non-negative; continuous on the sky side; the ray
    exactly tangent (and just below) sees the ground, just above does not."""
    m = observers[h]
    zh = horizon_zenith(h, R_E)
    # the coarse grid reaches to within 4e-6 rad: from 100-120 km the sky's slope steepens toward the
    # grazing ray (smoothly: log-radiance slope 17 per rad 1-2e-3 above it, 21 within 1e-5, measured)
    offs = np.array([-2e-3, -1e-3, -1e-5, -4e-6, -2e-6, -1e-6, 0.0, 1e-6])
    for az in (180.0, 0.0, 90.0):
        r = m.radiance(zen_dirs(zh + offs, az))
        check_physical(r)
        sky = r.radiance[:6]
        assert np.all(sky > 0)
        assert_continuous(sky, offs[:6], (4, 5))
        assert np.all(r.ground[:6] == 0.0)
        assert np.all(r.ground[7] > 0.0)  # sunlit ground (albedo 0.2), even 1e-6 rad below the horizon
        # (offset 0 is tangent only to rounding: either side is right, it only has to be finite)
    if h == 0.0:
        # exactly horizontal from the ground and the air just above: the horizon sky is
        # brighter than the zenith, the ground seen at zero distance is E_ground a / pi
        r = m.radiance(np.concatenate([zen_dirs(np.array([0.0, np.pi / 2 - 1e-6])), [[0.0, 1.0, 0.0]]]))
        assert np.all(r.radiance[1] > r.radiance[0])
        assert np.all(r.single[2] == 0.0) and np.all(r.ground[2] > 0.0)


def test_observer_in_space_sees_the_limb_and_black_space(observers):
    """120 km, sun 20 degrees: straight up and above the top of the atmosphere space
    is black (exactly 0); the limb glows, brighter as the ray dips deeper into the
    upper atmosphere shell; straight down the sunlit ground and the air above it."""
    m = observers[120_000.0]
    tangent_km = np.array([110.0, 101.0, 99.0, 90.0, 80.0, 60.0, 40.0, 30.0])
    z = horizon_zenith(120_000.0, R_E + tangent_km * 1e3)
    d = np.concatenate([zen_dirs([0.0, 0.5 * np.pi]), zen_dirs(z, 90.0), zen_dirs([np.pi])])
    r = m.radiance(d)
    check_physical(r)
    assert np.all(r.radiance[:4] == 0.0)  # zenith, horizontal, tangent above the top
    limb = r.radiance[4:-1]
    assert np.all(limb > 0)
    assert np.all(np.diff(limb, axis=0) > 0)  # brighter the deeper the ray dips
    down = r.radiance[-1]
    assert np.all(down > limb[0]) and np.all(r.ground[-1] > 0)
    # the observer exactly at the top: up is space, down the same ground
    top = observers[TOP].radiance(zen_dirs([0.0, np.pi]))
    assert np.all(top.radiance[0] == 0.0)
    np.testing.assert_allclose(top.radiance[1], down, rtol=0.02)
    # direct sun above the atmosphere is the unattenuated solar spectrum
    np.testing.assert_allclose(m.direct_sun_irradiance(), m.profile.solar_irradiance, rtol=1e-12)


# --------------------------------------------------------------------------------------
# extreme aerosol loads, no aerosol, no ozone, albedo 0 and 1
# --------------------------------------------------------------------------------------


def _flat_aerosol(aod550):
    """The synthetic profile with a spectrally flat aerosol (Angstrom exponent 0)."""
    p = synthetic_profile(WL, aod550=aod550)
    k = (np.asarray(WL) / 550.0) ** 1.3  # undo the (lambda / 550)^-1.3 of the synthetic aerosol
    return p.with_(aerosol_scattering_by_regime=p.aerosol_scattering_by_regime * k,
                   aerosol_absorption=p.aerosol_absorption * k)


def _global_horizontal(m):
    """Global (direct + diffuse) irradiance on the horizontal ground, W m^-2 nm^-1."""
    mus = m.sun[2]
    diffuse = m.to_full(m.field.ground_irradiance_at(np.array([mus])))[0] * m.profile.solar_irradiance
    return m.direct_sun_irradiance() * mus + diffuse


@pytest.mark.parametrize("model", ["opac", "guimera2018"])
def test_extreme_aerosol_loads_real_types(model):
    """AOD550 0.1 -> 10 for urban (absorbing, fine) and desert (coarse dust) aerosol of both
    aerosol models (the figures below are the OPAC model's):
    finite and non-negative everywhere, ground irradiance falls monotonically with the
    load (direct beam and global). Colour: the Rayleigh blue is gone at AOD 10, but the
    sky does not turn grey: both types absorb more in the blue (single-scattering
    albedo at 450 / 650 nm: urban 0.68 / 0.65 with a 1.6x larger optical depth at 450,
    desert dust 0.83 / 0.90), and in a thick layer the diffuse light decays as
    exp(-sqrt(3 (1 - ssa)(1 - g)) tau), so the zenith turns red-brown (ratio 450/650,
    relative to the sun's, below 1) as in heavy smog or a dust storm. The paper's desert
    (Jaenicke's coarse dust) absorbs about as much in the blue as in the red (ssa 0.56 /
    0.57 at 450 / 650 nm, g 0.94): its thick sky turns a dim grey instead (|log ratio| < 0.1
    at AOD 10, measured +0.03). The grey limit of a spectrally flat, conservative aerosol is
    the next test."""
    from skymodel import Atmosphere

    d = dirs([0.0, 60.0, 85.0, 120.0], [0.0, 0.0, 180.0, 0.0])
    for loc in ("urban", "desert"):
        glob, direct, zenith = [], [], []
        for aod in (0.1, 1.0, 10.0):
            p = Atmosphere(location=loc, month=6, aod550=aod, aerosol_model=model).optical_profile(WL)
            m = SkyMarcher(p, 30.0, 180.0, 0.0, TINY)
            r = m.radiance(d)
            check_physical(r)
            glob.append(_global_horizontal(m))
            direct.append(m.direct_sun_irradiance())
            zenith.append(r.radiance[0] / p.solar_irradiance)
        assert np.all(np.diff(direct, axis=0) < 0) and np.all(np.diff(glob, axis=0) < 0), loc
        assert np.all(np.array(direct[-1]) < 1e-3 * np.array(direct[0]))  # tau ~ 20 slant: beam gone
        colour = [np.log(z[0] / z[2]) for z in zenith]  # > 0 blue, < 0 red
        assert colour[0] > 0.5, loc  # AOD 0.1: a blue sky
        assert colour[0] > colour[1] > colour[2], (loc, colour)
        if model == "guimera2018" and loc == "desert":
            assert abs(colour[2]) < 0.1, (loc, colour)  # grey: its absorption is flat in wavelength
        else:
            assert colour[2] < 0, (loc, colour)


def test_thick_aerosol_scattering_orders_are_complete():
    """Desert dust at AOD 10 scatters light many times (each order ~0.85 of the last):
    stopping at 20 orders left the sky up to 8 % too dark before the solver added the
    rest of the series geometrically; now 20 orders agree with the series run to a
    1e-6 tolerance (58 orders). The OPAC model's desert (single-scattering albedo ~0.85-0.9;
    the paper's Jaenicke desert, SSA ~0.6, needs fewer orders)."""
    from skymodel import Atmosphere

    p = Atmosphere(location="desert", month=6, aod550=10.0, aerosol_model="opac").optical_profile(WL)
    d = dirs([0.0, 60.0, 85.0], [0.0, 0.0, 180.0])
    short = SkyMarcher(p, 30.0, 180.0, 0.0, replace(TINY, max_orders=20))
    long = SkyMarcher(p, 30.0, 180.0, 0.0, replace(TINY, max_orders=200, order_tolerance=1e-6))
    assert short.field.orders == 20 and long.field.orders > 40  # 58 measured
    np.testing.assert_allclose(short.radiance(d).radiance, long.radiance(d).radiance, rtol=0.01)
    np.testing.assert_allclose(_global_horizontal(short), _global_horizontal(long), rtol=0.01)


def test_dense_layer_order_series_converges():
    """'background' aerosol (a free-troposphere layer) at AOD 5, sun on the horizon:
    linear interpolation of the extinction between the solver's altitude nodes once let
    some grid rays gather 15-35 times the light a ray can carry (the exact value is
    < 1), so every scattering order came out larger than the last and the sky reached
    8 times the solar irradiance. Now each order is smaller than the last, the series
    converges, and the sky stays below E_sun per steradian. The OPAC background (ssa 0.96)
    converges within 100 orders (50 measured when the grid rays' steps were weighted by their
    midpoint transmittance, which lost light on optically thick steps; since they carry each step's
    mean transmittance the orders decay by 0.94 instead of 0.91 and take ~75); the paper's (Jaenicke's free troposphere as sulfuric acid,
    ssa 1.000, conservative) decays more slowly, and the solver adds the rest of the series
    geometrically, so only the decrease and the bounds are asserted for it."""
    for model in ("opac", "guimera2018"):
        p = _typed_profile("background", 5.0, model)
        m = SkyMarcher(p, 0.0, 180.0, 0.0, replace(SMALL, max_orders=100))
        c = m.field.order_contributions
        if model == "opac":
            assert m.field.orders < 100 and c[-1] < 1e-3
        assert all(b < a for a, b in zip(c[3:], c[4:])), model
        d = dirs([0.0, 30.0, 60.0, 85.0], [0.0, 90.0, 0.0, 0.0])
        r = m.radiance(d)
        check_physical(r)
        assert np.all(r.radiance < p.solar_irradiance), model


def test_thick_flat_aerosol_makes_the_sky_grey():
    """A spectrally flat, nearly conservative aerosol: at AOD 10 the light reaching the
    ground has been scattered many times by particles that treat every wavelength
    alike, so the sky is greyer (its colour ratio 450/650 nm nearer the sun's) than the
    Rayleigh-blue sky at AOD 0.1. (The real types absorb more in the blue and turn
    red-brown instead: previous test.)"""
    d = dirs([0.0, 45.0, 70.0], [0.0, 0.0, 90.0])

    def blueness(aod):
        p = _flat_aerosol(aod)
        r = SkyMarcher(p, 30.0, 180.0, 0.0, TINY).radiance(d)
        check_physical(r)
        c = r.radiance / p.solar_irradiance
        return np.abs(np.log(c[:, 0] / c[:, 2]))

    thin, thick = blueness(0.1), blueness(10.0)
    assert np.all(thick < 0.5 * thin), (thin, thick)


def test_no_aerosol_no_ozone_and_albedo_bounds(prof):
    d = dirs([0.0, 45.0, 80.0, 95.0, 150.0], [0.0, 180.0, 0.0, 90.0, 0.0])
    base = SkyMarcher(prof, 30.0, 180.0, 1_000.0, SMALL).radiance(d)
    check_physical(base)
    # no ozone: absorption removed, so nothing can get darker; the 600 nm band brightens
    no_o3 = SkyMarcher(prof.with_(ozone_absorption=0 * prof.ozone_absorption), 30.0, 180.0, 1_000.0, SMALL).radiance(d)
    check_physical(no_o3)
    assert np.all(no_o3.radiance >= base.radiance * (1 - 2e-3))
    assert np.all(no_o3.radiance[:3, 1:] > base.radiance[:3, 1:] * 1.005)
    # no aerosol at all (every regime zero): a Rayleigh sky, bluer overhead
    clean = prof.with_(aerosol_scattering_by_regime=0 * prof.aerosol_scattering_by_regime,
                       aerosol_absorption=0 * prof.aerosol_absorption)
    ray = SkyMarcher(clean, 30.0, 180.0, 1_000.0, SMALL).radiance(d)
    check_physical(ray)
    assert ray.radiance[0, 0] / ray.radiance[0, 2] > base.radiance[0, 0] / base.radiance[0, 2]
    # albedo 1: everything at least as bright as with 0.2, the ground much brighter
    white = SkyMarcher(prof.with_(ground_albedo=np.ones(3)), 30.0, 180.0, 1_000.0, SMALL).radiance(d)
    check_physical(white)
    assert np.all(white.radiance >= base.radiance)
    np.testing.assert_allclose(white.ground[3:], base.ground[3:] * 5.0, rtol=1e-9)


def test_vacuum_with_white_ground_is_exact(prof):
    """No air at all, albedo 1: the sky is black, the ground seen from 10 km is
    exactly E mu0 / pi with mu0 the sun's cosine at the point seen."""
    vac = prof.with_(rayleigh_scattering=0 * prof.rayleigh_scattering, ozone_absorption=0 * prof.ozone_absorption,
                     aerosol_scattering_by_regime=0 * prof.aerosol_scattering_by_regime,
                     aerosol_absorption=0 * prof.aerosol_absorption, ground_albedo=np.ones(3))
    m = SkyMarcher(vac, 30.0, 180.0, 10_000.0, TINY)
    d = dirs([0.0, 80.0, 100.0, 150.0, 180.0], [0.0, 180.0, 180.0, 0.0, 0.0])
    r = m.radiance(d)
    check_physical(r)
    assert np.all(r.radiance[:2] == 0.0) and np.all(r.single == 0.0) and np.all(r.multiple == 0.0)
    o = np.array([0.0, 0.0, R_E + 10_000.0])
    _, t1, hits = atmosphere_segment(np.broadcast_to(o, d[2:].shape), d[2:], R_E, R_E + TOP)
    assert np.all(hits)
    g = o + t1[:, None] * d[2:]
    mu0 = (g / np.linalg.norm(g, axis=1, keepdims=True)) @ m.sun
    np.testing.assert_allclose(r.ground[2:], mu0[:, None] * vac.solar_irradiance / np.pi, rtol=2e-3)
    np.testing.assert_allclose(m.direct_sun_irradiance(), vac.solar_irradiance, rtol=1e-9)


# --------------------------------------------------------------------------------------
# wavelength grids: one wavelength, 2 nm steps
# --------------------------------------------------------------------------------------


def test_single_wavelength_and_2nm_grids():
    """One wavelength, three, and the full 380-780 nm grid in 2 nm steps (201): the
    same medium at a wavelength gives the same radiance whatever else is on the grid.
    Single scattering and the ground are computed per wavelength; multiple scattering
    is solved on every 100 nm of the grid here (380, 480, 580, ...), so 580 nm matches
    exactly and the others carry the wavelength-interpolation error (measured <= 7 %)."""
    d = dirs([0.0, 50.0, 88.0, 100.0], [0.0, 180.0, 0.0, 0.0])
    # a fixed order count: the to-tolerance stop sums |J_n| over all the wavelengths of
    # the run, so it may stop one order apart on different grids (~1e-3 of the total)
    fixed = replace(SMALL, orders=8)
    wl3 = (450.0, 580.0, 650.0)
    three = SkyMarcher(synthetic_profile(wl3), 15.0, 180.0, 0.0, fixed).radiance(d)
    one = SkyMarcher(synthetic_profile((580.0,)), 15.0, 180.0, 0.0, fixed).radiance(d)
    check_physical(one)
    assert one.radiance.shape == (4, 1)
    np.testing.assert_allclose(one.radiance[:, 0], three.radiance[:, 1], rtol=1e-4)
    wl = np.arange(380.0, 780.1, 2.0)
    fine = SkyMarcher(synthetic_profile(wl), 15.0, 180.0, 0.0, fixed).radiance(d)
    check_physical(fine)
    assert fine.radiance.shape == (4, 201)
    idx = [int(np.argmin(np.abs(wl - w))) for w in wl3]
    np.testing.assert_allclose(fine.single[:, idx], three.single, rtol=1e-6)
    np.testing.assert_allclose(fine.ground[:, idx], three.ground, rtol=1e-6)
    np.testing.assert_allclose(fine.multiple[:, idx[1]], three.multiple[:, 1], rtol=1e-4)
    np.testing.assert_allclose(fine.multiple[:, idx], three.multiple, rtol=0.1)
    # smooth from one 2 nm step to the next: no spikes (relative second differences)
    sg = fine.single + fine.ground
    assert np.max(np.abs(np.diff(sg / sg.mean(axis=1, keepdims=True), 2, axis=1))) < 1e-3
    # multiple scattering is carried from the solver's wavelengths (100 nm apart here) by the
    # log-ozone map (skymodel.render.solver_spectrum): smooth too, its curvature the ozone
    # band's and the model's (largest 1.2e-3 of the mean, at the node 680 nm and at the
    # grid's end), no spikes
    ms = fine.multiple / fine.multiple.mean(axis=1, keepdims=True)
    assert np.max(np.abs(np.diff(ms, 2, axis=1))) < 2e-3


# --------------------------------------------------------------------------------------
# property-based: any sun, any observer altitude, any aerosol type and load
# --------------------------------------------------------------------------------------


_TYPE_CACHE: dict = {}


def _typed_profile(kind, aod, model=None):
    from skymodel import Atmosphere
    from skymodel.scene import default

    key = (kind, aod, model)
    if key not in _TYPE_CACHE:
        _TYPE_CACHE[key] = Atmosphere(latitude=45.0, longitude=0.0, aerosol=kind, month=6, aod550=aod,
                                      aerosol_model=model or default("aerosol_model")).optical_profile((450.0, 650.0))
    return _TYPE_CACHE[key]


@settings(max_examples=8, deadline=None, derandomize=True)
@given(sun=st.floats(-12.0, 90.0), h=st.floats(0.0, 120_000.0), aod=st.sampled_from([0.0, 0.05, 0.5, 5.0]),
       kind=st.sampled_from(aerosol_types()))
def test_any_sun_altitude_and_aerosol_gives_finite_bounded_radiance(sun, h, aod, kind):
    p = _typed_profile(kind, aod)
    # every direction marched (a coarse direction grid would smear the aureole of a
    # thick aerosol far from the sun, an interpolation matter tested in test_marcher.py).
    # This test found the order series diverging (to 8x the solar irradiance) for the
    # 'background' aerosol at AOD 5, sun 0: see test_dense_layer_order_series_converges.
    m = SkyMarcher(p, sun, 180.0, h, replace(SMALL, view_steps=32))
    rng = np.random.default_rng(int(sun * 1000) % 2**31)
    d = rng.normal(size=(64, 3))
    d = np.concatenate([d / np.linalg.norm(d, axis=1, keepdims=True), zen_dirs([0.0, horizon_zenith(h, R_E)])])
    r = m.radiance(d)
    check_physical(r)
    # a loose physical bound that catches blow-ups: away from the aureole (phase
    # functions < 1 sr^-1 beyond 20 degrees) no radiance reaches E_sun per steradian
    far = d @ m.sun < np.cos(np.radians(20.0))
    assert np.all(r.radiance[far] <= p.solar_irradiance)


# --------------------------------------------------------------------------------------
# Lorentz-Mie extremes
# --------------------------------------------------------------------------------------


mie_n = st.floats(1.0001, 3.0)
mie_k = st.one_of(st.just(0.0), st.floats(1e-8, 10.0))


def spheres(n=mie_n, k=mie_k, x=st.floats(-6.0, np.log10(2e4)), log_x=True, size=8):
    """Batches of spheres (m, x): one vectorised call per example keeps large x cheap
    (all spheres of a call advance through the series orders together)."""
    def build(rows):
        m = np.array([complex(a, b) for a, b, _ in rows])
        xx = np.array([10.0**c if log_x else c for _, _, c in rows])
        return m, xx
    return st.lists(st.tuples(n, k, x), min_size=1, max_size=size).map(build)


@settings(max_examples=12, deadline=None, derandomize=True)
@given(mx=spheres())
def test_mie_efficiencies_finite_and_bounded(mx):
    m, x = mx
    e = mie.efficiencies(m, x)
    for name in e._fields:
        assert np.all(np.isfinite(getattr(e, name))), name
    assert np.all(e.qsca > 0) and np.all(e.qabs >= 0) and np.all(e.qback >= 0) and np.all(np.abs(e.g) <= 1.0)
    np.testing.assert_allclose(e.qext, e.qsca + e.qabs, rtol=1e-12)
    real = m.imag == 0
    assert np.all(np.abs(e.qabs[real]) <= 1e-9 * e.qext[real])
    small = x < 300  # the phase function of the same spheres on a few angles
    if np.any(small):
        p = mie.phase_function(m[small], x[small], np.array([-1.0, 0.0, 1.0]))
        assert np.all(np.isfinite(p)) and np.all(p > 0)


@settings(max_examples=12, deadline=None, derandomize=True)
@given(mx=spheres(x=st.floats(-6.0, -3.0)))
def test_mie_rayleigh_limit_scales_as_x4(mx):
    """For x |m| << 1 scattering grows as x^4: doubling x multiplies Q_sca by 16, up to
    relative corrections O((|m| x)^2); Q_sca itself is (8/3) x^4 |(m^2-1)/(m^2+2)|^2."""
    m, x = mx
    q1, q2 = mie.efficiencies(m, x).qsca, mie.efficiencies(m, 2 * x).qsca
    tol = 50 * (np.abs(m) * 2 * x) ** 2 + 1e-9
    assert np.all(np.abs(q2 / q1 / 16.0 - 1.0) <= tol)
    alpha = (m * m - 1) / (m * m + 2)
    assert np.all(np.abs(q1 / (8.0 / 3.0 * x**4 * np.abs(alpha) ** 2) - 1.0) <= tol)


@settings(max_examples=4, deadline=None, derandomize=True)
@given(mx=spheres(n=st.floats(1.2, 3.0), x=st.floats(1000.0, 5000.0), log_x=False, size=4))
def test_mie_extinction_tends_to_two(mx):
    """Large spheres remove twice their geometric cross section (the extinction
    paradox). The approach is O(x^-2/3): the edge term is ~2 x^-2/3 (Nussenzveig &
    Wiscombe 1980), and non-absorbing spheres add resonance ripple; measured over
    n = 1.2..3, k = 0..10, x = 3e3..2e4: |Q_ext - 2| x^(2/3) <= 8.1 (real m), <= 4.4
    (k >= 1e-4). Allowed: 10 x^-2/3 (x = 2e4 itself is in tests/test_mie.py)."""
    m, x = mx
    assert np.all(np.abs(mie.efficiencies(m, x).qext - 2.0) < 10.0 * x ** (-2.0 / 3.0))


@settings(max_examples=6, deadline=None, derandomize=True)
@given(mx=spheres(n=st.floats(1.0001, 1.01), k=st.just(0.0), x=st.floats(50.0, 2e4), log_x=False))
def test_mie_soft_spheres_follow_anomalous_diffraction(mx):
    """m -> 1 and large x: Q_ext is van de Hulst's anomalous diffraction
    2 - (4 / rho) sin rho + (4 / rho^2)(1 - cos rho), rho = 2 x (n - 1); it reaches 2
    only when rho >> 1, so 'Q_ext -> 2' needs the phase shift, not x alone, large."""
    m, x = mx
    rho = 2.0 * x * (m.real - 1.0)
    adt = 2.0 - 4.0 / rho * np.sin(rho) + 4.0 / rho**2 * (1.0 - np.cos(rho))
    q = mie.efficiencies(m, x).qext
    assert np.all(np.abs(q - adt) <= 0.05 * adt + 2.0 * x ** (-2.0 / 3.0))


@settings(max_examples=10, deadline=None, derandomize=True)
@given(mx=spheres(x=st.floats(-6.0, np.log10(300.0)), size=4))
def test_mie_phase_function_normalised(mx):
    """2 pi integral of p over mu = 1 by Gauss-Legendre with nstop + 2 nodes (exact for
    the polynomial |S1|^2 + |S2|^2), over the whole range of m and x."""
    m, x = mx
    nodes, weights = np.polynomial.legendre.leggauss(int(mie.wiscombe_nstop(x).max()) + 2)
    p = mie.phase_function(m, x, nodes)
    assert np.all(np.isfinite(p)) and np.all(p >= 0)
    np.testing.assert_allclose(2 * np.pi * p @ weights, 1.0, atol=1e-7)
