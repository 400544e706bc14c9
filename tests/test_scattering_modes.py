"""The solver's scattering step by azimuth mode equals the dense phase-matrix product."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.render import multiple_scattering as ms
from skymodel.render.medium import factor_medium


def _setup(n_phi):
    prof = Atmosphere(location="rural", month=6, aerosol="desert").optical_profile(np.array([450.0, 550.0, 650.0]))
    med = factor_medium(prof)
    grid = ms.build_table_grid(prof, med, n_altitudes=5, n_mu=8, n_phi=n_phi, n_mus=4)
    return prof, med, grid


def test_phase_modes_rebuild_the_phase_matrix():
    prof, med, grid = _setup(7)
    pm = ms.phase_matrix(ms.aerosol_phase_function(prof, med, 0), grid, ms.direction_pair_cosines(grid))
    lam = ms.phase_modes(pm, grid).astype(float)  # (m, w, mu, mu')
    c = ms.azimuth_modes(grid)
    norm = np.where(np.arange(grid.n_phi) == 0, 1.0, 2.0) / grid.n_phi
    rebuilt = np.einsum("mwab,pm,qm,m->wapbq", lam, c, c, norm).reshape(pm.shape)
    np.testing.assert_allclose(rebuilt, pm, rtol=0, atol=2e-7 * np.abs(pm).max())


@pytest.mark.parametrize("n_phi", [5, 6, 24])
def test_phase_modes_from_one_column_equal_the_dense_route(n_phi):
    """The solver's phase modes from one column of each circulant (phase_modes_of) against the
    modes projected from the dense matrix, for the air and a desert aerosol."""
    prof, med, grid = _setup(n_phi)
    for phase in (prof.rayleigh_phase, ms.aerosol_phase_function(prof, med, 0)):
        dense = ms.phase_modes(ms.phase_matrix(phase, grid, ms.direction_pair_cosines(grid)), grid)
        got = ms.phase_modes_of(phase, grid)
        assert got.dtype == np.float32 and got.shape == dense.shape == (n_phi, grid.n_wl, grid.n_mu, grid.n_mu)
        np.testing.assert_allclose(got, dense, rtol=0, atol=1e-6 * np.abs(dense).max())


@pytest.mark.parametrize("n_phi", [5, 6, 24])
def test_scattered_source_equals_the_dense_product(n_phi):
    """Odd and even azimuth counts, and `reference`'s 24."""
    prof, med, grid = _setup(n_phi)
    species = ms.scattering_species(prof, med, grid)
    pair = ms.direction_pair_cosines(grid)
    dense = [ms.phase_matrix(prof.rayleigh_phase, grid, pair)] + [
        ms.phase_matrix(ms.aerosol_phase_function(prof, med, r), grid, pair)
        for r in range(len(med.aerosol_scaled)) if np.any(med.aerosol_scaled[r].at(grid.h_nodes) > 0)]
    assert len(dense) == len(species) >= 2
    rng = np.random.default_rng(3)
    radiance = rng.random((grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus)).astype(np.float32)
    got = ms.scattered_source(radiance, species, grid)
    flat = radiance.astype(float).reshape(grid.n_wl, grid.n_dir, -1)
    want = sum((pm @ flat).reshape(radiance.shape) * sig.T[:, None, :, None] for pm, (_, sig) in zip(dense, species))
    assert got.dtype == np.float32 and got.shape == radiance.shape
    np.testing.assert_allclose(got, want, rtol=2e-6)


def test_kept_arrays_give_the_same_orders():
    """scattered_source and gathered_radiance into WorkArrays' arrays equal the new-array
    route bit for bit; gathered_radiance equals M J + G L_g on the ray layout."""
    prof, med, grid = _setup(6)
    species = ms.scattering_species(prof, med, grid)
    rng = np.random.default_rng(5)
    field = (grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus)
    radiance = rng.random(field).astype(np.float32)
    work = ms.WorkArrays()
    kept = work.get("source", field)
    got = ms.scattered_source(radiance, species, grid, out=kept)
    assert got.base is kept.base and np.array_equal(got, ms.scattered_source(radiance, species, grid))
    n_rays = grid.n_h * grid.n_mu
    M = rng.random((grid.n_wl, n_rays, n_rays)).astype(np.float32)
    G = rng.random((grid.n_wl, n_rays)).astype(np.float32)
    lg = rng.random((grid.n_mus, grid.n_wl)).astype(np.float32)
    got = ms.gathered_radiance(radiance, lg, M, G, grid, out=work.get("radiance", field))
    assert np.array_equal(got, ms.gathered_radiance(radiance, lg, M, G, grid))
    ray = np.matmul(M, ms.to_ray_layout(radiance, grid)).reshape(grid.n_wl, n_rays, grid.n_phi, grid.n_mus)
    ray += G[:, :, None, None] * lg.T[:, None, None, :]
    want = ms.to_dir_layout(ray.reshape(grid.n_wl, n_rays, -1), grid)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    # the same size keeps the memory; another size replaces it
    assert work.get("source", field[::-1]).base is kept.base
    smaller = work.get("source", (grid.n_wl, grid.n_dir // 2, grid.n_h, grid.n_mus))
    assert smaller.base is not kept.base and smaller.shape == (grid.n_wl, grid.n_dir // 2, grid.n_h, grid.n_mus)


def test_layouts_follow_the_documented_index_maps():
    """The dir layout's (dir = i_mu n_phi + i_phi, h, sun) and the ray layout's
    (ray = i_h n_mu + i_mu, i_phi n_mus + sun), written out index by index: dir_in_ray_order
    is a view (writes land in the field), to_ray_layout / to_dir_layout invert each other."""
    _, _, grid = _setup(5)
    field = np.arange(grid.n_wl * grid.n_dir * grid.n_h * grid.n_mus, dtype=np.float32).reshape(
        grid.n_wl, grid.n_dir, grid.n_h, grid.n_mus)
    w, i_mu, i_phi, i_h, s = 2, grid.n_mu - 2, 3, grid.n_h - 1, 1
    value = field[w, i_mu * grid.n_phi + i_phi, i_h, s]
    view = ms.dir_in_ray_order(field, grid.n_mu, grid.n_phi)
    assert view.shape == (grid.n_wl, grid.n_h, grid.n_mu, grid.n_phi, grid.n_mus)
    assert view[w, i_h, i_mu, i_phi, s] == value
    assert ms.dir_in_ray_order(field[w], grid.n_mu, grid.n_phi)[i_h, i_mu, i_phi, s] == value
    ray = ms.to_ray_layout(field, grid)
    assert ray[w, i_h * grid.n_mu + i_mu, i_phi * grid.n_mus + s] == value
    assert np.array_equal(ms.to_dir_layout(ray, grid), field)
    view[w, i_h, i_mu, i_phi, s] = -1.0
    assert field[w, i_mu * grid.n_phi + i_phi, i_h, s] == -1.0


def test_abs_sums_per_wavelength():
    a = np.random.default_rng(2).normal(size=(3, 4, 5, 6)).astype(np.float32)
    np.testing.assert_allclose(ms.abs_sums(a), np.abs(a.astype(float)).sum(axis=(1, 2, 3)), rtol=1e-6)
