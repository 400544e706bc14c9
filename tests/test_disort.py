"""The marcher against DISORT (pydisort, through skymodel.validation.disort), a small
version of benchmarks/validate_disort.py.

Runs only where pydisort is installed (it pulls torch; CI does not install it): see
docs/validation.md for the environment and the full comparison."""

import importlib.util
from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.validation import disort
from skymodel.validation.disort import plane_parallel_single_scattering, run_disort, run_marcher
from skymodel.validation.plane_parallel import plane_parallel_layers

needs_pydisort = pytest.mark.skipif(importlib.util.find_spec("pydisort") is None,
                                    reason="pydisort is not installed (it pulls torch; see docs/validation.md)")

SUN_ELEVATION = np.array([40.0])
VIEW_ZENITH = np.array([0.0, 30.0, 60.0])
RELATIVE_AZIMUTH = np.array([0.0, 90.0, 180.0])


def test_bridge_imports_without_pydisort():
    """The bridge is plain numpy until DISORT is run: pydisort and torch are imported
    inside run_disort only, so the validation package imports where they are absent."""
    assert set(disort.__all__) >= {"run_disort", "run_marcher", "plane_parallel_single_scattering"}
    ang = disort.scattering_angles_deg(np.array([30.0]), np.array([60.0, 0.0]), np.array([0.0, 180.0]))
    np.testing.assert_allclose(ang[0, 0], [0.0, 120.0], atol=1e-6)  # toward the sun at its zenith angle; behind
    np.testing.assert_allclose(ang[0, 1], [60.0, 60.0], atol=1e-6)  # the zenith: 90 - 30 from the sun


@pytest.fixture(scope="module")
def rayleigh():
    atm = Atmosphere(location="rural", month=6, aerosol="none", stratospheric="none", albedo=0.0)
    prof = atm.optical_profile([450.0])
    return prof, plane_parallel_layers(prof, n_layers=40, n_moments=16)


@needs_pydisort
def test_disort_single_scattering_limit_matches_closed_form(rayleigh):
    """With the scattering made negligible, DISORT's radiance is single scattering: it
    must equal the closed form for the same layers (checks umu/phi signs and fbeam units)."""
    prof, lay = rayleigh
    scale = 1e-3
    thin = replace(lay, optical_depth=lay.optical_depth * scale)
    dis = run_disort(thin, 90.0 - SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH, n_streams=16)
    ss = plane_parallel_single_scattering(prof, thin, 90.0 - SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH)
    np.testing.assert_allclose(dis, ss, rtol=2e-3)
    assert dis[0, 1, 0, 0] > dis[0, 1, 2, 0]  # toward the sun (relative azimuth 0) is brighter


@needs_pydisort
def test_marcher_agrees_with_disort_rayleigh(rayleigh):
    prof, lay = rayleigh
    dis = run_disort(lay, 90.0 - SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH, n_streams=16)
    mar = run_marcher(prof, SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH, quality="preview")
    rel = mar / dis - 1.0
    assert np.max(np.abs(rel)) < 0.02, rel
