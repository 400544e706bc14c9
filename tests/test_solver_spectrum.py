"""The map from the solver's wavelengths to the render's (skymodel.render.solver_spectrum)."""

from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.colorimetry import cmf_weights
from skymodel.errors import SkymodelInputError
from skymodel.render.marcher import (MarchSettings, SkyMarcher, settings_solver_wavelengths, solve_sky,
                                     solver_wavelengths)
from skymodel.render.memory import _n_solver_wavelengths
from skymodel.render.quality import quality_settings
from skymodel.render.solver_spectrum import SolverSpectrumMap
from skymodel.validation.truth import view_directions
from skymodel.wavelengths import default_wavelengths, spread_indices

WL = default_wavelengths(5.0)


@pytest.fixture(scope="module")
def ozone():
    """The vertical ozone optical depth of a June mid-latitude column at the render wavelengths."""
    prof = Atmosphere(month=6).optical_profile(WL)
    return prof.vertical_optical_depth(prof.ozone_absorption)


def test_exact_at_the_solver_wavelengths_and_the_identity(ozone):
    src = solver_wavelengths(WL, 10.0)
    m = SolverSpectrumMap(src, WL, ozone)
    rng = np.random.default_rng(1)
    v = rng.uniform(0.1, 2.0, (5, src.size))
    out = m(v)
    at_nodes = np.searchsorted(WL, src)
    np.testing.assert_allclose(out[:, at_nodes], v, rtol=1e-10)
    same = SolverSpectrumMap(WL, WL, ozone)
    assert same.identity and same(out) is out


def test_a_power_law_through_an_ozone_column_is_carried_exactly(ozone):
    """ln S = a + b ln(lambda) + c ln^2(lambda) - N tau_O3(lambda) is the model: carried from
    10 nm (and 40 nm) to 5 nm exactly, where a straight line misses the Chappuis band's
    bumps by percents at a twilight column (N = 40 vertical columns)."""
    lam = WL / 550.0
    for n_col in (0.0, 5.0, 40.0):
        s = 3.0 * lam ** -4.1 * np.exp(0.3 * np.log(lam) ** 2 - n_col * ozone)
        for step in (10.0, 40.0):
            src = solver_wavelengths(WL, step)
            m = SolverSpectrumMap(src, WL, ozone)
            nodes = np.searchsorted(WL, src)
            np.testing.assert_allclose(m(s[nodes]), s, rtol=1e-9)
            if n_col == 40.0:
                assert np.abs(s[nodes] @ m.linear / s - 1).max() > (0.01 if step == 10.0 else 0.05)


def test_a_mixture_of_columns_is_close_and_far_closer_than_linear(ozone):
    """Light along many paths is a sum of such terms, not one: still within 0.4 % from 10 nm
    (0.28 %; linear 2.9 %)."""
    lam = WL / 550.0
    s = sum(w * lam ** -4 * np.exp(-n * ozone) for w, n in ((1.0, 2.0), (0.6, 20.0), (0.3, 60.0)))
    src = solver_wavelengths(WL, 10.0)
    m = SolverSpectrumMap(src, WL, ozone)
    nodes = np.searchsorted(WL, src)
    err, err_lin = np.abs(m(s[nodes]) / s - 1).max(), np.abs(s[nodes] @ m.linear / s - 1).max()
    assert err < 0.004 and err < err_lin / 5, (err, err_lin)


def test_spectra_with_zeros_are_read_linearly_and_the_dtype_kept(ozone):
    src = solver_wavelengths(WL, 10.0)
    m = SolverSpectrumMap(src, WL, ozone)
    v = np.stack([np.linspace(1.0, 2.0, src.size), np.zeros(src.size), np.r_[0.0, np.ones(src.size - 1)]])
    out = m(v.astype(np.float32))
    assert out.dtype == np.float32 and out.shape == (3, WL.size)
    np.testing.assert_array_equal(out[1], 0.0)
    np.testing.assert_allclose(out[2], (v[2] @ m.linear).astype(np.float32))
    assert np.all(np.isfinite(out))
    # no ozone in the profile: the model's other terms only (a power law is still exact)
    m0 = SolverSpectrumMap(src, WL, np.zeros(WL.size))
    np.testing.assert_allclose(m0((src / 550.0) ** -4), (WL / 550.0) ** -4, rtol=1e-9)


def test_first_axis_in_float32_is_the_last_axis_in_float64(ozone):
    """The spherical correction's factor goes through the map with the wavelength first and in
    float32 (``axis=0, dtype=float32``): the same numbers as the default reading of its transpose,
    to float32 rounding, zeros read linearly as there."""
    src = solver_wavelengths(WL, 100.0)
    m = SolverSpectrumMap(src, WL, ozone)
    rng = np.random.default_rng(2)
    v = rng.uniform(0.2, 3.0, (src.size, 4, 3)).astype(np.float32)
    v[1, 2, 0] = 0.0  # one column with a zero: linear
    first = m(v, axis=0, dtype=np.float32)
    assert first.dtype == np.float32 and first.shape == (WL.size, 4, 3)
    last = m(np.moveaxis(v, 0, -1))
    np.testing.assert_allclose(first, np.moveaxis(last, -1, 0), rtol=2e-6)
    np.testing.assert_allclose(first[:, 2, 0], v[:, 2, 0] @ m.linear, rtol=2e-6)
    with pytest.raises(ValueError, match="axis"):
        m(v, axis=1)


def test_twilight_sky_from_40_nm_solver_wavelengths_matches_every_wavelength():
    """A rural sky at sun -4 degrees (the Chappuis band is its colour), `preview`'s tables: the
    sky with the solver at 40 nm against the solver at every 5-nm wavelength, in CIE XYZ,
    on views from the zenith to the horizon. The linear map was 1-4 % off here."""
    prof = Atmosphere(location="rural", month=6, aod550=0.2).optical_profile(WL)
    views = np.array([[0, 0], [45, 0], [60, 90], [80, 0], [85, 180], [88, 0], [89, 90], [70, 180]], float)
    dirs = view_directions(views, 180.0)
    base = quality_settings("preview")
    every = SkyMarcher(prof, -4.0, 180.0, 0.0, replace(base, ms_wavelength_step_nm=5.0)).radiance(dirs).radiance
    sol = solve_sky(prof, base)
    coarse = SkyMarcher(prof, -4.0, 180.0, 0.0, base, solution=sol).radiance(dirs).radiance
    linear_map = sol.to_full.linear

    class Linear:
        def __call__(self, v):
            return np.asarray(v) @ linear_map

    linear = SkyMarcher(prof, -4.0, 180.0, 0.0, base, solution=replace(sol, to_full=Linear())).radiance(dirs).radiance
    cmf = cmf_weights(WL)
    err = np.abs((coarse @ cmf) / (every @ cmf) - 1).max()
    err_lin = np.abs((linear @ cmf) / (every @ cmf) - 1).max()
    assert err < 0.004 and err < err_lin / 4, (err, err_lin)


@pytest.mark.parametrize("lo, hi, step_nm, solver_step_nm", [(500.0, 600.0, 5.0, 40.0), (550.0, 650.0, 2.0, 20.0),
                                                             (380.0, 780.0, 1.0, 10.0)])
def test_narrow_and_fine_grids_stay_bounded(lo, hi, step_nm, solver_step_nm):
    """A band of 100 nm at 40 nm has 4 solver wavelengths, as many as the model's terms (an
    exact fit, the least squares gone): the weights stay near those of interpolation (at most
    1.7 here) and the twilight mixture is still read closer than linearly; a 1-nm grid too."""
    wl = np.arange(lo, hi + 0.01, step_nm)
    prof = Atmosphere(month=6).optical_profile(wl)
    tau = prof.vertical_optical_depth(prof.ozone_absorption)
    src = solver_wavelengths(wl, solver_step_nm)
    m = SolverSpectrumMap(src, wl, tau)
    assert np.abs(m.log).max() < 2.0
    lam = wl / 550.0
    s = sum(w * lam ** -4 * np.exp(-n * tau) for w, n in ((1.0, 2.0), (0.6, 20.0), (0.3, 60.0)))
    at_src = np.interp(src, wl, s)
    assert np.abs(m(at_src) / s - 1).max() < 0.5 * np.abs(at_src @ m.linear / s - 1).max()


def test_final_thins_its_solver_wavelengths_outside_the_eyes_band():
    """`final` solves every 10 nm over 440-660 nm and every 20 nm beyond (32 wavelengths for
    380-780 nm, not 41); the band's edges and the grid's ends among them; a grid inside the band
    (the truth's marches, 440-660 nm) keeps every 10 nm; an outer step no larger than the inner
    one, or none, is the even spacing as before."""
    s = quality_settings("final")
    wl = settings_solver_wavelengths(WL, s)
    assert wl.size == 32 and wl[0] == 380.0 and wl[-1] == 780.0
    inside = wl[(wl >= 440.0) & (wl <= 660.0)]
    np.testing.assert_allclose(inside, np.arange(440.0, 660.1, 10.0))
    np.testing.assert_allclose(np.diff(wl[wl <= 440.0]), 20.0)
    np.testing.assert_allclose(np.diff(wl[wl >= 660.0]), 20.0)
    truth_grid = np.arange(440.0, 660.1, 10.0)
    np.testing.assert_array_equal(settings_solver_wavelengths(truth_grid, s), truth_grid)
    for outer in (0.0, 5.0, 10.0):
        np.testing.assert_array_equal(solver_wavelengths(WL, 10.0, outer), solver_wavelengths(WL, 10.0))
    red = np.arange(700.0, 780.1, 5.0)
    np.testing.assert_allclose(solver_wavelengths(red, 10.0, 20.0), np.arange(700.0, 780.1, 20.0))
    # the spherical correction's probes stay 100 nm apart in wavelength on the uneven grid
    np.testing.assert_array_equal(wl[spread_indices(wl, 100.0)], [380.0, 480.0, 580.0, 680.0, 780.0])
    # and the memory guard counts what the solver will hold
    assert _n_solver_wavelengths(WL.size, WL, s) == 32


@pytest.mark.parametrize("field, value", [("ms_wavelength_outer_step_nm", -5.0), ("ms_fine_band_nm", (660.0, 440.0))])
def test_bad_solver_spacings_are_refused_by_name(field, value):
    with pytest.raises(SkymodelInputError, match=field):
        MarchSettings(**{field: value})


def test_twilight_colour_from_the_thinned_solver_matches_the_even_one():
    """The twilight sky (rural AOD 0.2, sun -4 degrees, the Chappuis band its colour) with the
    solver at 10 nm inside 440-660 nm and 20 nm outside, against 10 nm everywhere, small tables:
    CIE XYZ within 0.05 % on views from the zenith to the horizon and the spectrum within 1 % (here
    0.009 % and 0.3 %; 20 nm everywhere is 0.58 % and 1.8 % off; on `final`'s tables the colour moved
    by at most 0.012 % in four scenes, docs/accuracy.md)."""
    prof = Atmosphere(location="rural", month=6, aod550=0.2).optical_profile(WL)
    views = np.array([[0, 0], [45, 0], [60, 90], [80, 0], [85, 180], [88, 0], [89, 90], [70, 180]], float)
    dirs = view_directions(views, 180.0)
    base = replace(quality_settings("preview"), ms_wavelength_step_nm=10.0)
    even = SkyMarcher(prof, -4.0, 180.0, 0.0, base).radiance(dirs).radiance
    thinned_settings = replace(base, ms_wavelength_outer_step_nm=20.0)
    thinned = SkyMarcher(prof, -4.0, 180.0, 0.0, thinned_settings).radiance(dirs).radiance
    cmf = cmf_weights(WL)
    assert np.abs((thinned @ cmf) / (even @ cmf) - 1).max() < 5e-4
    assert np.abs(thinned / even - 1).max() < 0.01
    band = (WL >= 440.0) & (WL <= 660.0)
    assert not np.array_equal(thinned[:, ~band], even[:, ~band])  # the outer wavelengths did change
