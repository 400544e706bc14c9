"""The cut forward peak's small-angle scattering of the diffuse light near the horizon
(skymodel.render.peak_diffuse): what the term is, on small grids."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.render import multiple_scattering as ms
from skymodel.render.medium import factor_medium, truncate_forward_peak
from skymodel.render.peak_diffuse import BAND_DEG, PeakDiffuse, elevation_operator, peak_of, projected_kernel

WL = [450.0, 550.0, 650.0]


@pytest.fixture(scope="module")
def desert():
    prof = Atmosphere(location="desert", month=6, aod550=0.5).optical_profile(WL)
    med = factor_medium(prof, 12.0)
    grid = ms.build_table_grid(prof, med, n_altitudes=6, n_mu=32, n_phi=4, n_mus=3)
    return prof, med, grid


def test_the_peak_is_what_delta_m_cuts(desert):
    """peak_of recovers p - min(p, p(cutoff)) from the medium, and its projection on one
    axis of the small-angle plane integrates to the cut fraction f."""
    prof, med, _ = desert
    peak = peak_of(prof, med)
    ang = prof.aerosol_phase_angles_deg
    assert np.all(peak[:, ang > 12.5] == 0.0)
    f, _ = truncate_forward_peak(ang, prof.aerosol_phase, 12.0)
    for reg in range(peak.shape[0]):
        x, k = projected_kernel(ang, peak[reg])
        np.testing.assert_allclose(k.sum(axis=0) * (x[1] - x[0]), f[reg], rtol=3e-3)
        np.testing.assert_allclose(k, k[::-1], rtol=1e-12)  # even in x


def test_operator_redistributes_and_stays_near_the_horizon(desert):
    """Each row sums to zero (a constant field gets no term: light is only moved), rows
    exist only for nodes within BAND_DEG of the horizon, and a field bright below the
    horizon (the ground) and dark above gives light to the nodes just above it, taken from
    those just below, falling off away from it."""
    prof, med, grid = desert
    x, k = projected_kernel(prof.aerosol_phase_angles_deg, peak_of(prof, med)[0])
    d, band = elevation_operator(grid.mu_nodes, x, k)
    e = np.degrees(np.arcsin(grid.mu_nodes))
    assert np.all(np.abs(e[band]) <= BAND_DEG) and band.size == np.count_nonzero(np.abs(e) <= BAND_DEG)
    np.testing.assert_allclose(d.sum(axis=2), 0.0, atol=1e-12)
    step = (grid.mu_nodes < 0).astype(float)
    c = d @ step  # (W, n_band)
    eb = e[band]
    up, down = eb > 0, eb < 0
    assert np.all(c[:, up] >= -1e-12) and np.all(c[:, down] <= 1e-12)
    assert np.all(np.diff(c[:, up], axis=1) <= 0)  # falls away from the horizon
    # the step at the horizon, averaged over the hat of the node 0.3 degrees up: the peak's
    # mass beyond the node's neighbourhood, a few % of f for coarse dust
    f = k.sum(axis=0) * (x[1] - x[0])
    assert np.all((c[:, up][:, 0] > 0.01 * f) & (c[:, up][:, 0] < 0.2 * f))


def test_source_is_zero_for_a_constant_field_and_without_aerosol(desert):
    prof, med, grid = desert
    pd = PeakDiffuse(prof, med, grid)
    field = np.ones((grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus), dtype=np.float32)
    assert pd and np.abs(pd.source(field)).max() < 1e-6 * np.abs(med.aerosol[0].at(grid.h_nodes)).max()
    clean = Atmosphere(location="desert", month=6, aerosol="none", stratospheric="none").optical_profile(WL)
    cmed = factor_medium(clean, 12.0)
    assert not PeakDiffuse(clean, cmed, ms.build_table_grid(clean, cmed, n_altitudes=6, n_mu=8, n_phi=2, n_mus=3))


def test_solver_adds_ground_light_above_the_horizon_only(desert):
    """Solved with and without the term (order 2): the source changes only within the band,
    grows just above the horizon over the bright desert ground, and stays finite."""
    prof, med, _ = desert
    from skymodel.render.sun_transmittance import SunTransmittance

    sun = SunTransmittance([med.extinction, med.extinction_scaled], prof.planet_radius_m, prof.top_altitude_m,
                           24, 48, 48)
    # order 2 only: the term of L_1 (later orders carry it to every direction)
    kw = dict(n_altitudes=8, n_mu=16, n_phi=4, n_mus=6, n_steps=16, orders=2, spherical_orders=0)
    off = ms.solve_multiple_scattering(prof, med, sun, **kw)
    on = ms.solve_multiple_scattering(prof, med, sun, peak_diffuse=True, **kw)
    e = np.degrees(np.arcsin(off.mu_nodes))
    outside = np.abs(e) > BAND_DEG
    np.testing.assert_array_equal(on.source[:, outside], off.source[:, outside])
    assert np.all(np.isfinite(on.source))
    first_up = int(np.argmax(e > 0))
    sunlit = off.mus_nodes > 0.5
    near_ground = (slice(None), first_up, slice(None), 0, sunlit)
    assert np.all(on.source[near_ground] > off.source[near_ground])


def test_the_convolution_is_scipys_same_mode():
    """peak_diffuse convolves by numpy's FFT (no scipy.signal import at render time): the
    central samples of the full convolution, as scipy.signal.fftconvolve's mode "same",
    for kernels shorter and longer than the signal, odd and even lengths."""
    from scipy.signal import fftconvolve

    from skymodel.render.peak_diffuse import _convolve_same

    rng = np.random.default_rng(7)
    for n, m in ((100, 31), (3601, 241), (50, 80), (8, 6)):
        a, k = rng.random((n, 4, 3)), rng.random((m, 1, 3))
        np.testing.assert_allclose(_convolve_same(a, k), fftconvolve(a, k, mode="same", axes=0), rtol=0, atol=1e-12)


def test_the_fft_length_is_the_next_product_of_2_3_and_5():
    """The transforms are padded to the smallest 2^a 3^b 5^c at or above n + m - 1 (the 6-degree
    cone's 3841 = 23 x 167 became 3888 = 2^4 3^5, the 12-degree cone's 4081 became 4096)."""
    from skymodel.render.peak_diffuse import _fast_length

    smooth = [k for k in range(1, 5000) if _only_2_3_5(k)]
    for n in (1, 2, 7, 13, 241, 3841, 4081, 4097):
        assert _fast_length(n) == min(k for k in smooth if k >= n)
    assert _fast_length(3841) == 3888 and _fast_length(4081) == 4096


def _only_2_3_5(k):
    for p in (2, 3, 5):
        while k % p == 0:
            k //= p
    return k == 1


def test_the_ground_light_near_the_horizon_needs_the_ground_split(monkeypatch):
    """Desert dust, sun at 60 degrees, the horizon 90-135 degrees from it: the peak term turns
    bright ground light into the sky just above the horizon, and its source changes within tens
    of metres of the ground. With the solver's lowest altitude interval split in three
    (multiple_scattering.GROUND_SPLIT) 24 nodes land within 0.15 % of 64; read linearly over the
    unsplit lowest interval the horizon is 0.2-0.3 % higher here (in `final`'s full setting
    0.5-0.75 %, which put it 1-1.5 % above the Monte Carlo truth; notebooks/ground_nodes)."""
    from skymodel.render.marcher import MarchSettings, SkyMarcher
    from skymodel.render.rays import direction_from_angles

    prof = Atmosphere(location="desert", month=6, aod550=0.5).optical_profile([550.0])
    d = direction_from_angles(np.array([89.0, 89.0, 88.0]), np.array([90.0, 180.0, 135.0]))

    def horizon(n_altitudes, split):
        monkeypatch.setattr(ms, "GROUND_SPLIT", split)
        s = MarchSettings(exact=True, table_altitudes=n_altitudes, table_mu=16, table_phi=8, table_mus=12,
                          ms_wavelength_step_nm=200.0, peak_diffuse=True)
        return SkyMarcher(prof, 60.0, 180.0, 0.0, s).radiance(d).radiance[:, 0]

    converged = horizon(64, 3)
    split = horizon(24, 3) / converged - 1
    unsplit = horizon(24, 1) / converged - 1
    assert np.all(np.abs(split) < 0.0015), split
    assert np.all(unsplit > 0.0018), unsplit


def test_the_coarse_grid_shares_the_operators(desert):
    """on_grid: the same term on half the azimuths (what a fresh one there computes), and a
    refusal for other zenith nodes."""
    prof, med, grid = desert
    pd = PeakDiffuse(prof, med, grid)
    coarse = ms.coarse_azimuth_grid(grid)
    shared, fresh = pd.on_grid(coarse), PeakDiffuse(prof, med, coarse)
    assert shared.grid is coarse and shared.terms is pd.terms
    rng = np.random.default_rng(4)
    radiance = rng.random((coarse.n_wl, coarse.n_dir, coarse.n_h, coarse.n_mus)).astype(np.float32)
    assert np.array_equal(shared.source(radiance), fresh.source(radiance))
    other = ms.build_table_grid(prof, med, n_altitudes=6, n_mu=16, n_phi=4, n_mus=3)
    with pytest.raises(ValueError, match="same zenith"):
        pd.on_grid(other)
