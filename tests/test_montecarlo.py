"""Monte Carlo reference path tracer (skymodel.validation.montecarlo).

The checks compare the tracer with things it does not share code with: deterministic
quadrature of the single-scattering integral, brute-force optical depths, analytic
limits (optically thin sky, a bare Lambertian ground), and energy conservation of a
plane-parallel (huge-planet) atmosphere. Statistical comparisons use the estimator's
own standard errors; seeds are fixed so the tests are deterministic.
"""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.numerics import trapezoid
from skymodel.geometry import altitude_grid
from skymodel.optics.profile import OpticalProfile
from skymodel.validation.montecarlo import MCResult, _Medium, trace_radiance
from skymodel.render.rays import atmosphere_segment, direction_from_angles, sun_direction

R_EARTH = 6_360_000.0


# --------------------------------------------------------------------------------------
# synthetic media
# --------------------------------------------------------------------------------------


def hg(g, angles_deg):
    mu = np.cos(np.radians(angles_deg))
    return (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * mu) ** 1.5)


PHASE_ANGLES = np.concatenate([np.linspace(0.0, 10.0, 41), np.linspace(10.5, 180.0, 340)])


def synthetic_profile(wl=(450.0, 550.0, 650.0), n_alt=121, albedo=0.3, aod=0.15, ozone=True,
                      absorbing=True, scale=1.0, radius=R_EARTH) -> OpticalProfile:
    """Exponential Rayleigh (H = 8 km, 1.3e-5 /m at 550 nm), exponential tropospheric
    aerosol (H = 1.2 km, HG g = 0.7 phase table, single-scattering albedo 0.92), a thin
    stratospheric aerosol layer (HG g = 0.5) and a Gaussian ozone layer at 25 km."""
    wl = np.asarray(wl, float)
    h = altitude_grid(n_alt)
    ray = np.exp(-h / 8000.0)[:, None] * (1.3e-5 * (550.0 / wl) ** 4)[None, :]
    aer = np.exp(-h / 1200.0)[:, None] * (aod / 1200.0 * (550.0 / wl) ** 1.3)[None, :]
    ssa = 0.92 if absorbing else 1.0
    strat = (2e-3 / 6000.0 * np.exp(-0.5 * ((h - 22000.0) / 4000.0) ** 2))[:, None] * (550.0 / wl)[None, :]
    o3 = np.zeros_like(ray)
    if ozone:
        xs = np.interp(wl, [400, 500, 600, 700], [0.2e-25, 1.5e-25, 5e-25, 2e-25])  # m^2
        o3 = (5e18 * np.exp(-0.5 * ((h - 25000.0) / 7000.0) ** 2))[:, None] * xs[None, :]
    tab = np.stack([np.repeat(hg(0.7, PHASE_ANGLES)[:, None], wl.size, 1),
                    np.repeat(hg(0.5, PHASE_ANGLES)[:, None], wl.size, 1)])
    e_sun = np.interp(wl, [400.0, 700.0], [1.7, 1.4])
    return OpticalProfile(
        wavelengths_nm=wl, rayleigh_depolarization=np.full(wl.size, 0.0279),
        aerosol_phase_angles_deg=PHASE_ANGLES, aerosol_phase=tab,
        ground_albedo=np.full(wl.size, float(albedo)), solar_irradiance=e_sun,
        planet_radius_m=float(radius), altitudes_m=h,
        rayleigh_scattering=ray * scale, ozone_absorption=o3 * scale,
        aerosol_scattering_by_regime=np.stack([aer * ssa * scale, strat * scale]),
        aerosol_absorption=aer * (1.0 - ssa) * scale,
    )


@pytest.fixture(scope="module")
def profile():
    return synthetic_profile()


# --------------------------------------------------------------------------------------
# independent references
# --------------------------------------------------------------------------------------


def _geometric(length, n, a=6.0):
    u = np.linspace(0.0, 1.0, n)
    return length * np.expm1(a * u) / np.expm1(a)


def single_scattering_reference(prof, dirs, sun_el, sun_az, h_obs=0.0, n_view=600, n_sun=300):
    """E * integral over the view ray of T_view * sum_c sigma_c p_c * T_sun, all by
    trapezoidal quadrature on grids crowded toward each ray's start (albedo 0)."""
    R, top = prof.planet_radius_m, prof.planet_radius_m + prof.top_altitude_m
    s = sun_direction(sun_el, sun_az)
    o = np.array([0.0, 0.0, R + h_obs])
    out = np.zeros((len(dirs), prof.n_wavelengths))
    for i, d in enumerate(dirs):
        t0, t1, _ = atmosphere_segment(o, d, R, top)
        if not t1 > t0:
            continue
        t = t0 + _geometric(t1 - t0, n_view)
        x = o[None] + t[:, None] * d[None]
        smp = prof.sample(np.linalg.norm(x, axis=1) - R)
        ext = smp.extinction
        tau_v = np.concatenate([np.zeros((1, ext.shape[1])),
                                np.cumsum(0.5 * (ext[1:] + ext[:-1]) * np.diff(t)[:, None], axis=0)])
        mu = np.array(float(d @ s))
        beta_p = smp.rayleigh_scattering * prof.rayleigh_phase(mu)
        beta_p = beta_p + (smp.aerosol_scattering_by_regime * prof.aerosol_phase_at(mu)[:, None, :]).sum(0)
        ss0, ss1, hit = atmosphere_segment(x, np.broadcast_to(s, x.shape), R, top)
        t_sun = np.zeros_like(ext)
        lit = ~hit
        if lit.any():
            ts = ss0[lit][:, None] + _geometric(1.0, n_sun)[None, :] * (ss1[lit] - ss0[lit])[:, None]
            xs = x[lit][:, None, :] + ts[..., None] * s
            e2 = prof.sample(np.linalg.norm(xs, axis=-1) - R).extinction
            t_sun[lit] = np.exp(-(0.5 * (e2[:, 1:] + e2[:, :-1]) * np.diff(ts, axis=1)[..., None]).sum(1))
        f = np.exp(-tau_v) * beta_p * t_sun
        out[i] = (0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None]).sum(0) * prof.solar_irradiance
    return out


def _assert_statistically_equal(mc: MCResult, ref, rel_floor=2e-4):
    """Per-entry |MC - ref| within 4 standard errors (plus the quadrature's own
    accuracy, rel_floor) and an RMS z-score below 1.5: with ~30 entries, |z| < 3 for
    every one would fail ~8 % of honest runs, so we bound the maximum at 4 and ask the
    z-scores as a whole to look like N(0, 1)."""
    err = np.abs(mc.radiance - ref)
    tol = 4.0 * mc.stderr + rel_floor * np.abs(ref)
    assert np.all(err <= tol), (mc.radiance, ref, mc.stderr)
    pos = mc.stderr > 0
    z = (mc.radiance - ref)[pos] / mc.stderr[pos]
    assert np.sqrt(np.mean(z**2)) < 1.5, z


# --------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("layered", [False, True])
def test_medium_tables_reproduce_the_profile(profile, layered):
    prof = profile.layered(n_layers=12) if layered else profile
    med = _Medium(prof)
    rng = np.random.default_rng(0)
    h = np.concatenate([rng.uniform(0.0, prof.top_altitude_m, 2000), [0.0, prof.top_altitude_m]])
    w = rng.integers(0, prof.n_wavelengths, h.size)
    s = prof.sample(h)
    comp = med.components_at(h, w)
    m = np.arange(h.size)
    np.testing.assert_allclose(comp[0], s.rayleigh_scattering[m, w], rtol=1e-12, atol=1e-22)
    for r in range(2):
        np.testing.assert_allclose(comp[1 + r], s.aerosol_scattering_by_regime[r][m, w], rtol=1e-12, atol=1e-22)
    np.testing.assert_allclose(comp[-1], (s.ozone_absorption + s.aerosol_absorption)[m, w], rtol=1e-12, atol=1e-22)
    np.testing.assert_allclose(med.extinction_at(h, w), s.extinction[m, w], rtol=1e-11, atol=1e-22)
    cos = rng.uniform(-1.0, 1.0, 500)
    wc = rng.integers(0, prof.n_wavelengths, cos.size)
    i = np.arange(cos.size)
    np.testing.assert_allclose(med.rayleigh_phase(cos, wc), prof.rayleigh_phase(cos)[i, wc], rtol=1e-13)
    np.testing.assert_allclose(med.aerosol_phase(cos, wc), prof.aerosol_phase_at(cos)[:, i, wc], rtol=1e-12)
    # majorant bounds the extinction in every shell
    band = np.clip(np.searchsorted(med.band_edges, h, side="right") - 1, 0, med.n_bands - 1)
    assert np.all(med.majorant[band, w] >= med.extinction_at(h, w))
    if layered:  # regular tracking: the majorant is the extinction (no null collisions)
        np.testing.assert_allclose(med.majorant[band, w], med.extinction_at(h, w), rtol=1e-11)


@pytest.mark.parametrize("layered", [False, True])
def test_sun_ray_optical_depth_is_exact(profile, layered):
    """The closed-form optical depth along straight rays to the top against brute-force
    trapezoidal quadrature (200k points), including near-horizontal rays and the shadow."""
    prof = profile.layered(n_layers=12) if layered else profile
    med = _Medium(prof)
    R, top = prof.planet_radius_m, prof.planet_radius_m + prof.top_altitude_m
    rng = np.random.default_rng(2)
    cases = [(0.0, 1.0), (0.0, 0.0), (500.0, -0.01), (3000.0, -0.03), (15000.0, -0.06), (40000.0, 0.2),
             (99_000.0, -0.3), (20000.0, -0.5)]
    cases += [(rng.uniform(0, 30000), rng.uniform(-0.1, 1.0)) for _ in range(8)]
    for h, mu in cases:
        pos = np.array([0.0, 0.0, R + h])
        d = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
        tau, blocked = med.optical_depth_to_top(pos[None], d)
        t0, t1, hits = atmosphere_segment(pos, d, R, top)
        assert bool(blocked[0]) == bool(hits)
        if hits:
            assert np.all(np.isinf(tau))
            continue
        t = np.linspace(t0, t1, 200_001)
        ext = prof.sample(np.linalg.norm(pos[None] + t[:, None] * d[None], axis=1) - R).extinction
        ref = trapezoid(ext, t, axis=0)
        # smooth profile: trapezoid error ~1e-7; layered: the step edges cost ~1e-4
        np.testing.assert_allclose(tau[0], ref, rtol=2e-4 if layered else 1e-6)
    # per-wavelength selection agrees with the all-wavelength form
    pts = np.array([[0.0, 0.0, R + 1000.0], [0.0, 0.0, R + 5000.0]])
    full, _ = med.optical_depth_to_top(pts, sun_direction(10.0, 0.0))
    one, _ = med.optical_depth_to_top(pts, sun_direction(10.0, 0.0), np.array([2, 0]))
    np.testing.assert_allclose(one, [full[0, 2], full[1, 0]], rtol=1e-12)


def _binned_check(samples, pdf_cos, n_bins=40):
    """Histogram of cos(theta) samples against bin probabilities from the phase function
    integrated on a fine grid; every bin within 5 binomial sigma."""
    edges = np.linspace(-1.0, 1.0, n_bins + 1)
    counts = np.histogram(samples, edges)[0]
    fine = np.linspace(-1.0, 1.0, 400_001)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf_cos[1:] + pdf_cos[:-1]) * np.diff(fine))])
    p = np.diff(np.interp(edges, fine, cdf)) / cdf[-1]
    n = samples.size
    sigma = np.sqrt(n * p * (1 - p)) + 1.0
    assert np.all(np.abs(counts - n * p) < 5 * sigma), (counts, n * p)


def test_phase_sampling_follows_the_phase_functions(profile):
    med = _Medium(profile)
    rng = np.random.default_rng(5)
    n = 400_000
    w = np.full(n, 1)
    fine = np.linspace(-1.0, 1.0, 400_001)
    # Rayleigh with depolarisation: a strong depolarisation makes the check sharper
    strong = _Medium(profile.with_(rayleigh_depolarization=np.full(3, 0.3)))
    for m in (med, strong):
        _binned_check(m.sample_rayleigh_cos(w, rng), m.profile.rayleigh_phase(fine)[:, 1])
    # tabulated aerosol: strongly forward (g = 0.7) and g = 0.5; check the forward peak too
    for regime in (0, 1):
        c = med.sample_aerosol_cos(regime, w, rng)
        pdf = profile.aerosol_phase_at(fine)[regime, :, 1]
        _binned_check(c, pdf)
        _binned_check(np.clip((c - 0.99) / 0.01 * 2.0 - 1.0, -1.5, 1.0)[c > 0.99],
                      profile.aerosol_phase_at(0.99 + (fine + 1.0) * 0.005)[regime, :, 1])
        assert med.phase_mass[regime, 1] == pytest.approx(1.0, abs=2e-4)


# --------------------------------------------------------------------------------------
# the estimator
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("layered", [False, True])
@pytest.mark.parametrize("h_obs", [0.0, 10_000.0])
def test_single_scattering_matches_deterministic_integral(profile, layered, h_obs):
    prof = profile.with_(ground_albedo=np.zeros(3))
    if layered:
        prof = prof.layered(n_layers=16)
    dirs = direction_from_angles([0.0, 50.0, 75.0, 88.0, 60.0], [0.0, 90.0, 90.0, 90.0, 270.0])
    n_paths = 16384 if (h_obs == 0.0 and not layered) else 4096
    mc = trace_radiance(prof, dirs, 20.0, 90.0, observer_altitude_m=h_obs, n_paths=n_paths, max_bounces=1, seed=11)
    ref = single_scattering_reference(prof, dirs, 20.0, 90.0, h_obs)
    _assert_statistically_equal(mc, ref)
    # and within 2 % wherever the path count resolves 2 % (stderr <= 0.7 %): with 16k
    # paths, the slant views from the ground. Delta tracking spends most paths of a
    # thin view (zenith, or anything from 10 km) escaping without a collision, so there
    # the relative error per path is larger.
    good = mc.stderr <= 0.007 * ref
    if n_paths == 16384:
        assert good.sum() >= 4
    np.testing.assert_allclose(mc.radiance[good], ref[good], rtol=0.02)


def test_optically_thin_limit_is_linear_in_tau():
    """For a tiny density the radiance is E * integral of sigma_s p along the view ray
    (no attenuation, no multiple scattering): proportional to the scale of the medium."""
    dirs = direction_from_angles([88.0, 89.0], [90.0, 270.0])
    thin = []
    for k in (1e-3, 2e-3):
        prof = synthetic_profile(wl=(500.0,), scale=k, albedo=0.0).layered(n_layers=8)
        thin.append(trace_radiance(prof, dirs, 30.0, 90.0, n_paths=1 << 18, seed=3))
    unit = synthetic_profile(wl=(500.0,), scale=1.0, albedo=0.0).layered(n_layers=8)
    # analytic thin limit: quadrature of sigma_s * p along the view ray, per unit scale
    s = sun_direction(30.0, 90.0)
    R, top = unit.planet_radius_m, unit.planet_radius_m + unit.top_altitude_m
    lin = []
    for d in dirs:
        _, t1, _ = atmosphere_segment(np.array([0.0, 0.0, R]), d, R, top)
        t = _geometric(t1, 20001)
        smp = unit.sample(np.linalg.norm(np.array([0.0, 0.0, R]) + t[:, None] * d, axis=1) - R)
        mu = np.array(float(d @ s))
        f = smp.rayleigh_scattering * unit.rayleigh_phase(mu)
        f = f + (smp.aerosol_scattering_by_regime * unit.aerosol_phase_at(mu)[:, None, :]).sum(0)
        lin.append(trapezoid(f[:, 0], t) * unit.solar_irradiance[0])
    lin = np.array(lin)
    for k, res in zip((1e-3, 2e-3), thin):
        L, se = res.radiance[:, 0], res.stderr[:, 0]
        assert np.all(se < 0.05 * L)
        # O(tau) attenuation of the thin limit (tau of these slant paths <= 0.03) + 4 sigma
        assert np.all(np.abs(L - k * lin) <= 4 * se + 0.03 * k * lin), (L, k * lin, se)
    ratio = thin[1].radiance[:, 0] / thin[0].radiance[:, 0]
    rel = [t.stderr[:, 0] / t.radiance[:, 0] for t in thin]
    ratio_se = ratio * np.hypot(rel[0], rel[1])
    assert np.all(np.abs(ratio - 2.0) < 4 * ratio_se + 0.03)


def test_absorption_scales_each_scattering_order():
    """Survival weighting in multiple scattering: halve every scattering coefficient and
    turn the other half into absorption (same extinction, single-scattering albedo 1/2).
    Then the k-th scattering order is exactly 2^-k times that of the conservative medium,
    so L_absorbing = sum_k 2^-k (L_k - L_k-1), L_k the conservative radiance up to order
    k (albedo 0). With the same seed both media make the same tracking decisions, so
    the comparison is much tighter than the standard errors."""
    cons = synthetic_profile(wl=(450.0, 650.0), albedo=0.0, ozone=False, absorbing=False)
    half = cons.with_(rayleigh_scattering=0.5 * cons.rayleigh_scattering,
                      aerosol_scattering_by_regime=0.5 * cons.aerosol_scattering_by_regime,
                      aerosol_absorption=0.5 * (cons.rayleigh_scattering + cons.aerosol_scattering))
    dirs = direction_from_angles([0.0, 70.0, 88.0], [0.0, 90.0, 270.0])
    orders = [trace_radiance(cons, dirs, 10.0, 90.0, n_paths=2048, max_bounces=k, seed=9) for k in (1, 2, 3)]
    absorbing = trace_radiance(half, dirs, 10.0, 90.0, n_paths=2048, max_bounces=3, seed=9)
    L = [np.zeros_like(orders[0].radiance)] + [o.radiance for o in orders]
    pred = sum(0.5 ** k * (L[k] - L[k - 1]) for k in (1, 2, 3))
    assert np.all(L[3] - L[1] > 0.05 * L[1])  # multiple scattering matters here
    assert np.all(np.abs(absorbing.radiance - pred) <= 0.5 * absorbing.stderr + 1e-9 * pred)


def test_light_scattered_toward_the_ground_follows_the_phase_function():
    """The direction convention of phase sampling in multiple scattering. Aerosol only
    (HG g = 0.7, conservative), plane-parallel (planet 1000x the Earth), sun at the
    zenith, looking at the zenith from the ground. The albedo-1 minus albedo-0 radiance
    with max_bounces=2 is exactly the order-2 path 'scattered in the air toward the
    ground, reflected by the sunlit ground': a plane-parallel 2D integral

        E mu0 e^(-tau/mu0) / pi * int sigma(z) e^(-tau(z)) 2 pi int_{-1}^{0} p(mu) e^(-tau(z)/|mu|) dmu dz

    over the *backward* hemisphere of the phase function (8 % of a g = 0.7 table; a
    sampler that mixes up forward and backward gives 9x too much). Both runs share a
    seed, so the difference is each path's ground term; its spread over seeds is
    ~4.5 % at 32k paths (measured), the tolerance is 20 %."""
    base = synthetic_profile(wl=(550.0,), aod=0.3, ozone=False, absorbing=False, radius=1000 * R_EARTH)
    prof = base.with_(rayleigh_scattering=0.0 * base.rayleigh_scattering,
                      aerosol_scattering_by_regime=base.aerosol_scattering_by_regime * np.array([1.0, 0.0])[:, None, None])
    z = _geometric(prof.top_altitude_m, 4001, 8.0)
    sig = prof.sample(z).extinction[:, 0]
    tz = np.concatenate([[0.0], np.cumsum(0.5 * (sig[1:] + sig[:-1]) * np.diff(z))])
    mu = np.linspace(-1.0, -1e-6, 2001)
    p = prof.aerosol_phase_at(mu)[0, :, 0]
    inner = 2.0 * np.pi * trapezoid(p[None, :] * np.exp(-tz[:, None] / np.abs(mu)[None, :]), mu, axis=1)
    ref = prof.solar_irradiance[0] * np.exp(-tz[-1]) / np.pi * trapezoid(sig * np.exp(-tz) * inner, z)
    res = [trace_radiance(prof.with_(ground_albedo=np.array([a])), [[0.0, 0.0, 1.0]], 90.0, 0.0,
                          n_paths=1 << 15, max_bounces=2, seed=5) for a in (0.0, 1.0)]
    order2 = res[1].radiance[0, 0] - res[0].radiance[0, 0]
    assert order2 == pytest.approx(ref, rel=0.2)


def _cosine_directions(n, rng, upward):
    u1, u2 = rng.random(n), rng.random(n)
    st, ph = np.sqrt(1.0 - u1), 2.0 * np.pi * u2
    return np.stack([st * np.cos(ph), st * np.sin(ph), np.sqrt(u1) * (1.0 if upward else -1.0)], axis=1)


def _hemispheric_flux(prof, h, upward_view, sun_el, n_dir, seed):
    """pi * mean radiance over cosine-distributed view directions = the flux through a
    horizontal plane (downward through it if looking up)."""
    d = _cosine_directions(n_dir, np.random.default_rng(seed + 100), upward_view)
    r = trace_radiance(prof, d, sun_el, 0.0, observer_altitude_m=h, n_paths=8, seed=seed)
    per = np.pi * r.radiance
    return per.mean(0), per.std(0, ddof=1) / np.sqrt(n_dir)


@pytest.mark.slow
@pytest.mark.parametrize("albedo", [0.0, 0.5, 1.0])
def test_energy_conservation_plane_parallel(albedo):
    """A conservative atmosphere (no ozone, non-absorbing aerosol) over a planet 1000x
    the Earth's radius is plane-parallel to ~1e-4. Steady state and no absorption in the
    air: the net flux is the same at every height, and at the ground it is what the
    ground absorbs, so with F_down the total (diffuse + direct beam) flux on the ground

        F_up(top) + (1 - albedo) F_down(ground) = mu0 E.

    Albedo 0 is the brief's 'reflected + absorbed = incident'; albedo 1 is a white
    furnace for a beam (nothing absorbed anywhere: F_up(top) = mu0 E); albedo 1/2 makes
    path weights fall below 1, so Russian roulette acts. Exercises multiple scattering,
    phase sampling normalisation, the ground bounce, roulette and view rays from space."""
    prof = synthetic_profile(wl=(450.0, 650.0), albedo=albedo, ozone=False, absorbing=False, radius=1000 * R_EARTH)
    el = 40.0
    mu0E = np.sin(np.radians(el)) * prof.solar_irradiance
    up, se_up = _hemispheric_flux(prof, 120_000.0, False, el, 1536, seed=1)
    resid, se = up - mu0E, se_up
    if albedo < 1.0:
        dn, se_dn = _hemispheric_flux(prof, 0.0, True, el, 1536, seed=2)
        tau = prof.vertical_optical_depth(prof.extinction)
        dn = dn + mu0E * np.exp(-tau / np.sin(np.radians(el)))
        resid, se = resid + (1.0 - albedo) * dn, np.hypot(se_up, (1.0 - albedo) * se_dn)
    assert np.all(se < 0.01 * mu0E)
    assert np.all(np.abs(resid) < 4 * se), (resid / mu0E, se / mu0E)


def test_twilight_and_earth_shadow(profile):
    dirs = direction_from_angles([0.0, 85.0], [90.0, 90.0])  # zenith; horizon toward the sun
    day = trace_radiance(profile, dirs, 5.0, 90.0, n_paths=2048, seed=4)
    dusk = trace_radiance(profile, dirs, -4.0, 90.0, n_paths=16384, seed=4)
    night = trace_radiance(profile, dirs, -20.0, 90.0, n_paths=2048, seed=4)
    for r in (day, dusk, night):
        assert np.all(np.isfinite(r.radiance)) and np.all(r.radiance >= 0)
    # positive at -4 degrees (lit upper air; few paths reach it, so the relative error is
    # large: judge the sum over wavelengths), but much darker than with the sun up
    tot, tot_se = dusk.radiance.sum(1), np.sqrt((dusk.stderr**2).sum(1))
    assert np.all(tot > 4 * tot_se)
    assert np.all(dusk.radiance < 0.05 * day.radiance)
    # the zenith is darker than the horizon toward the sun
    assert tot[1] - tot[0] > 4 * np.hypot(tot_se[0], tot_se[1])
    assert np.all(dusk.radiance[0] < dusk.radiance[1])
    # sun 20 degrees down: the shadow reaches ~400 km above the observer
    assert np.all(night.radiance <= 1e-4 * day.radiance)


def test_ground_reflection_and_zero_albedo(profile):
    down = direction_from_angles([180.0, 150.0], [0.0, 90.0])
    # vacuum: only the sunlit Lambertian ground, exactly E a mu0 / pi, with zero variance
    vac = profile.with_(rayleigh_scattering=profile.rayleigh_scattering * 0,
                        ozone_absorption=profile.ozone_absorption * 0,
                        aerosol_scattering_by_regime=profile.aerosol_scattering_by_regime * 0,
                        aerosol_absorption=profile.aerosol_absorption * 0)
    obs = np.array([0.0, 0.0, R_EARTH + 20_000.0])
    t_hit = atmosphere_segment(obs[None], down, R_EARTH, R_EARTH + 100_000.0)[1]
    normal = obs + t_hit[:, None] * down
    mu0 = (normal / np.linalg.norm(normal, axis=1, keepdims=True)) @ sun_direction(35.0, 0.0)  # local sun height
    for a in (0.0, 0.8):
        r = trace_radiance(vac.with_(ground_albedo=np.full(3, a)), down, 35.0, 0.0,
                           observer_altitude_m=20_000.0, n_paths=64)
        exact = mu0[:, None] * profile.solar_irradiance * a / np.pi
        np.testing.assert_allclose(r.radiance, exact, rtol=1e-12, atol=0.0)
        assert np.all(r.stderr <= 1e-12 * r.radiance)
    # with air: albedo 0 leaves only the path radiance, clearly less than with 0.8
    dark, bright = (trace_radiance(profile.with_(ground_albedo=np.full(3, a)), down, 35.0, 0.0,
                                   observer_altitude_m=20_000.0, n_paths=1024, seed=6) for a in (0.0, 0.8))
    assert np.all(bright.radiance - dark.radiance > 10 * np.hypot(bright.stderr, dark.stderr))
    # and the albedo-0 radiance looking down is pure single+multiple scattering in the air:
    # its single-scattering part agrees with the quadrature (no ground term at all)
    ss = trace_radiance(profile.with_(ground_albedo=np.zeros(3)), down, 35.0, 0.0, observer_altitude_m=20_000.0,
                        n_paths=4096, max_bounces=1, seed=7)
    ref = single_scattering_reference(profile, down, 35.0, 0.0, 20_000.0)
    _assert_statistically_equal(ss, ref)


def _tangent_zenith_deg(h, R=R_EARTH):
    return 90.0 + np.degrees(np.arccos(R / (R + h)))


@pytest.mark.parametrize("layered", [False, True])
def test_finite_for_all_observer_altitudes_and_tangent_rays(profile, layered):
    prof = profile.layered(n_layers=10) if layered else profile
    top_tangent_120 = 90.0 + np.degrees(np.arccos((R_EARTH + 100_000.0) / (R_EARTH + 120_000.0)))
    cases = {
        0.0: [0.0, 45.0, 90.0, 90.0 + 1e-9, 95.0, 180.0],
        10_000.0: [0.0, 90.0, _tangent_zenith_deg(10_000.0), 120.0, 180.0],
        120_000.0: [0.0, 60.0, _tangent_zenith_deg(120_000.0), top_tangent_120, _tangent_zenith_deg(120_000.0) - 0.3,
                    170.0, top_tangent_120 - 0.3],
    }
    for h, zen in cases.items():
        dirs = direction_from_angles(zen, np.full(len(zen), 90.0))
        r = trace_radiance(prof, dirs, 10.0, 90.0, observer_altitude_m=h, n_paths=256, seed=8)
        assert r.radiance.shape == (len(zen), 3) and r.stderr.shape == (len(zen), 3)
        assert np.all(np.isfinite(r.radiance)) and np.all(np.isfinite(r.stderr))
        assert np.all(r.radiance >= 0.0) and np.all(r.stderr >= 0.0)
        if h == 120_000.0:
            assert np.all(r.radiance[[0, 1, 6]] == 0.0)  # rays missing the atmosphere see nothing
            assert np.all(r.radiance[[4, 5]] > 0.0)  # the limb glows, the sunlit ground too
        else:
            assert np.all(r.radiance[:2] > 0.0)


def test_reproducible_with_the_same_seed(profile):
    dirs = direction_from_angles([30.0, 80.0], [0.0, 45.0])
    a = trace_radiance(profile, dirs, 15.0, 60.0, n_paths=256, seed=42)
    b = trace_radiance(profile, dirs, 15.0, 60.0, n_paths=256, seed=42)
    c = trace_radiance(profile, dirs, 15.0, 60.0, n_paths=256, seed=43)
    np.testing.assert_array_equal(a.radiance, b.radiance)
    np.testing.assert_array_equal(a.stderr, b.stderr)
    assert not np.array_equal(a.radiance, c.radiance)
    # wavelength batching changes the random streams, not the expectation
    d = trace_radiance(profile, dirs, 15.0, 60.0, n_paths=256, seed=42, wavelength_batch=1)
    assert np.all(np.abs(d.radiance - a.radiance) < 5 * np.hypot(a.stderr, d.stderr))


def test_bad_input_is_rejected(profile):
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError):
        trace_radiance(profile, np.zeros((1, 3)), 10.0, 0.0)
    with pytest.raises(SkymodelInputError):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 10.0, 0.0, n_paths=0)
    with pytest.raises(SkymodelInputError):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 10.0, 0.0, observer_altitude_m=-5.0)
    with pytest.raises(SkymodelInputError, match="estimator"):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 10.0, 0.0, estimator="forward")


def test_real_atmosphere_smoke():
    try:
        from skymodel import Atmosphere

        prof = Atmosphere(location="rural", month=6).optical_profile([450.0, 550.0, 650.0])
    except (ImportError, AttributeError, FileNotFoundError) as exc:  # data modules not landed yet
        pytest.skip(f"Atmosphere not available: {exc}")
    dirs = direction_from_angles([0.0, 80.0, 100.0], [0.0, 90.0, 90.0])
    r = trace_radiance(prof, dirs, 30.0, 90.0, n_paths=256, seed=1)
    assert np.all(np.isfinite(r.radiance)) and np.all(r.radiance[:2] > 0.0)


# --------------------------------------------------------------------------------------
# the "sunlit" estimator (deep twilight): same expectation as next-event estimation
# --------------------------------------------------------------------------------------


def _assert_estimators_agree(a: MCResult, b: MCResult, zmax=4.0, zrms=1.5):
    """Two independent unbiased estimates of the same radiances: every difference within
    ``zmax`` combined standard errors and the z-scores' RMS below ``zrms``."""
    se = np.hypot(a.stderr, b.stderr)
    z = (a.radiance - b.radiance) / se
    assert np.all(np.abs(z) < zmax), z
    assert np.sqrt(np.mean(z**2)) < zrms, z


@pytest.mark.parametrize("sun_el", [10.0, -3.0])
def test_sunlit_single_scattering_matches_deterministic_integral(profile, sun_el):
    """Order 1 of the sunlit estimator (importance sampling over the sunlit part of the
    view line) against quadrature, with the sun up and with view lines crossing the
    Earth's shadow (sun 3 degrees down, low views toward the sun)."""
    dirs = direction_from_angles([0.0, 60.0, 85.0, 89.0, 85.0], [0.0, 180.0, 180.0, 180.0, 0.0])
    mc = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=2000, max_bounces=1, seed=11, estimator="sunlit")
    ref = single_scattering_reference(profile, dirs, sun_el, 180.0)
    assert np.all(ref > 0)
    _assert_statistically_equal(mc, ref, rel_floor=1e-3)
    assert np.all(mc.stderr < 0.03 * ref)  # the plain estimator: ~5 % at this path count


@pytest.mark.parametrize("sun_el", [5.0, 20.0])
def test_sunlit_estimator_agrees_with_nee_with_the_sun_up(profile, sun_el):
    dirs = direction_from_angles([0.0, 70.0, 85.0], [0.0, 180.0, 0.0])
    a = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=3000, seed=12)
    b = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=300, seed=13, estimator="sunlit")
    _assert_estimators_agree(a, b)


@pytest.fixture
def coarse_guide(monkeypatch):
    """The sunlit estimator's direction guide at a lower resolution (same code, faster)."""
    import skymodel.validation.montecarlo as mcm

    x = np.linspace(-1.0, 1.0, 17)
    monkeypatch.setattr(mcm, "_GUIDE_EL_EDGES", np.radians(90.0 * np.sign(x) * np.abs(x) ** 1.5))
    monkeypatch.setattr(mcm, "_GUIDE_PHI_EDGES", np.linspace(0.0, np.pi, 7))
    monkeypatch.setattr(mcm, "_GUIDE_ALTITUDES_M", np.array([500.0, 5000.0, 20000.0]))


def test_sunlit_estimator_with_its_guide_agrees_with_nee_below_the_horizon(profile, coarse_guide):
    """Sun 2 degrees down: the guide, the balance heuristic and the importance-sampled first
    collision are all in use; next-event estimation still converges there."""
    dirs = direction_from_angles([0.0, 60.0, 85.0], [0.0, 180.0, 0.0])
    a = trace_radiance(profile, dirs, -2.0, 180.0, n_paths=12000, seed=14)
    b = trace_radiance(profile, dirs, -2.0, 180.0, n_paths=300, seed=15, estimator="sunlit")
    _assert_estimators_agree(a, b)


def test_sunlit_estimator_measures_deep_twilight(profile, coarse_guide):
    """Sun 15 degrees down: next-event estimation sees (almost) nothing, the sunlit
    estimator a positive radiance with a usable error, darker than at -6 degrees and
    brighter toward the sun."""
    dirs = direction_from_angles([0.0, 80.0], [0.0, 180.0])  # zenith, low toward the sun
    nee = trace_radiance(profile, dirs, -15.0, 180.0, n_paths=2000, seed=16)
    deep = trace_radiance(profile, dirs, -15.0, 180.0, n_paths=300, seed=16, estimator="sunlit")
    dusk = trace_radiance(profile, dirs, -6.0, 180.0, n_paths=300, seed=16, estimator="sunlit")
    assert np.all(deep.radiance > 0) and np.all(np.isfinite(deep.stderr))
    tot, tot_se = deep.radiance.sum(1), np.sqrt((deep.stderr**2).sum(1))
    assert np.all(tot_se < 0.6 * tot)  # 300 paths, coarse guide (heavy-tailed: judge the sum)
    assert np.all(nee.radiance <= deep.radiance + 4 * nee.stderr + 1e-300)
    assert np.all(deep.radiance < 0.05 * dusk.radiance)
    assert np.all(deep.radiance[1] > deep.radiance[0])


@pytest.mark.parametrize("h", [0.0, 120_000.0])
def test_sunlit_estimator_finite_for_observers_and_the_ground(profile, h):
    zen = [0.0, 89.0, 100.0, 180.0] if h == 0.0 else [0.0, _tangent_zenith_deg(120_000.0) - 0.3, 170.0]
    dirs = direction_from_angles(zen, np.full(len(zen), 90.0))
    r = trace_radiance(profile, dirs, 10.0, 90.0, observer_altitude_m=h, n_paths=128, seed=17, estimator="sunlit")
    assert np.all(np.isfinite(r.radiance)) and np.all(np.isfinite(r.stderr)) and np.all(r.radiance >= 0.0)
    if h > 0.0:
        assert r.radiance[0].max() == 0.0 and np.all(r.radiance[1:] > 0.0)
    else:
        assert np.all(r.radiance > 0.0)


# --------------------------------------------------------------------------------------
# the sun guide (sharp forward peaks): new directions partly drawn around the sun
# --------------------------------------------------------------------------------------


def test_sun_guided_directions_carry_the_exact_weights(profile):
    """_guided_direction draws from the mixture q and weighs by p / q: the weights average
    to the phase functions' total (1 for normalised tables), and the weighted fraction
    of directions within 10 degrees of the sun equals that of plain phase sampling."""
    from skymodel.validation.montecarlo import _guided_direction, _rotate

    med = _Medium(profile, np.array([1]))
    rng = np.random.default_rng(3)
    m = 200_000
    d_in = np.broadcast_to(direction_from_angles(60.0, 0.0), (m, 3)).copy()
    sun = sun_direction(30.0, 180.0).reshape(3)
    sig_sc = med.components_at(np.full(m, 800.0), np.zeros(m, dtype=int))[:-1]
    w = np.zeros(m, dtype=int)
    d, wgt = _guided_direction(med, d_in, w, sig_sc, sun, 0.3, rng)
    se = wgt.std() / np.sqrt(m)
    assert abs(wgt.mean() - 1.0) < 4 * se + 2e-3
    near = (d @ sun) > np.cos(np.radians(10.0))
    guided_frac = np.mean(wgt * near)
    # plain sampling: scatterer by sigma_c / sigma_s, angle from its phase function
    comp = (rng.random(m) * sig_sc.sum(0) >= np.cumsum(sig_sc, 0)).sum(0)
    cos_t = np.where(comp == 0, med.sample_rayleigh_cos(w, rng), 0.0)
    for rg in range(med.n_regime):
        k = comp == rg + 1
        cos_t[k] = med.sample_aerosol_cos(rg, w[k], rng)
    plain = (_rotate(d_in, cos_t, rng) @ sun) > np.cos(np.radians(10.0))
    se2 = np.hypot(np.std(wgt * near), np.std(plain)) / np.sqrt(m)
    assert abs(guided_frac - plain.mean()) < 4 * se2
    assert near.mean() > 2.0 * plain.mean()  # the guide puts more samples there


@pytest.mark.parametrize("sun_el", [20.0, 3.0])
def test_sun_guided_nee_agrees_with_plain_nee(profile, sun_el):
    """sun_guide only changes the sampling (directions at collisions and ground bounces,
    the roulette): the same radiances within the standard errors, ground included."""
    dirs = direction_from_angles([0.0, 70.0, 85.0, 60.0], [0.0, 180.0, 0.0, 90.0])
    a = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=4000, seed=21)
    b = trace_radiance(profile, dirs, sun_el, 180.0, n_paths=4000, seed=22, sun_guide=0.3)
    _assert_estimators_agree(a, b)


def test_sun_guide_bad_values_are_rejected(profile):
    from skymodel.errors import SkymodelInputError

    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(SkymodelInputError, match="sun_guide"):
            trace_radiance(profile, [[0.0, 0.0, 1.0]], 10.0, 0.0, sun_guide=bad)
    with pytest.raises(SkymodelInputError, match="sun_guide"):
        trace_radiance(profile, [[0.0, 0.0, 1.0]], 10.0, 0.0, sun_guide=0.2, estimator="sunlit")


def test_dark_sun_rays_are_rouletted_without_bias(profile):
    """NEE with a low sun: rays the table reads darker than exp(-25) are traced with
    probability 1/16 and weighted 16 (expectation exact), the others exactly; rays into the
    ground are 0 without a draw; no dark ray, no random number (the stream of a sky with
    the sun up is unchanged)."""
    from skymodel.validation.montecarlo import _DARK_KEEP, _DARK_TAU, _DepthTable, _sun_transmittance

    med = _Medium(profile, np.array([0]))
    table = _DepthTable(med)
    sun = sun_direction(-0.5, 0.0).reshape(3)
    rng = np.random.default_rng(9)
    m = 3000
    h = rng.uniform(0.0, 3000.0, m)
    az = rng.uniform(0.0, 2.0 * np.pi, m)
    dist = rng.uniform(0.0, 300e3, m)  # points up to 300 km from the observer, around it
    ang = dist / med.R
    p = (med.R + h)[:, None] * np.column_stack([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.cos(ang)])
    w = np.zeros(m, dtype=int)
    tau, blocked = med.optical_depth_to_top(p, sun, w)
    exact = np.exp(-tau)
    t_tab, _ = table.optical_depth_to_top(p, sun, w)
    dark = (t_tab > _DARK_TAU) & ~blocked
    lit = (t_tab <= _DARK_TAU) & ~blocked
    assert dark.sum() > 100 and lit.sum() > 100 and blocked.sum() > 100
    assert np.array_equal(_sun_transmittance(med, p, w, sun, rng), exact)  # no table: exact
    runs = np.array([_sun_transmittance(med, p, w, sun, np.random.default_rng(s), table) for s in range(400)])
    assert np.all(runs[:, lit] == exact[lit]) and np.all(runs[:, blocked] == 0.0)
    d = runs[:, dark]
    assert np.all((d == 0.0) | np.isclose(d, exact[dark] / _DARK_KEEP, rtol=1e-12))
    kept = np.mean(d > 0.0)
    assert abs(kept - _DARK_KEEP) < 5.0 * np.sqrt(_DARK_KEEP / d.size)
    assert np.all(exact[dark] < np.exp(-_DARK_TAU + 0.1))
    g = np.random.default_rng(3)  # no dark ray: no draw
    _sun_transmittance(med, p[lit], w[lit], sun, g, table)
    assert g.random() == np.random.default_rng(3).random()


def test_nee_with_dark_rays_rouletted_agrees_with_plain_nee(profile, monkeypatch):
    """The same radiances with the dark-ray roulette (sun on the horizon) and without it."""
    import skymodel.validation.montecarlo as mcm

    dirs = direction_from_angles([0.0, 85.0, 89.0, 88.0], [0.0, 180.0, 5.0, 90.0])
    a = trace_radiance(profile, dirs, 0.0, 180.0, n_paths=6000, seed=41)
    monkeypatch.setattr(mcm, "_DARK_SUN_DEG", -90.0)
    b = trace_radiance(profile, dirs, 0.0, 180.0, n_paths=6000, seed=42)
    _assert_estimators_agree(a, b)
