"""The marcher against DISORT (pydisort), a small version of benchmarks/validate_disort.py.

Runs only where pydisort is installed (it pulls torch; CI does not install it): see
docs/accuracy.md for the environment and the full comparison."""

import os
import sys
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("pydisort")

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks"))

from validate_disort import plane_parallel_single_scattering, run_disort, run_marcher  # noqa: E402

from skymodel import Atmosphere  # noqa: E402
from skymodel.validation.plane_parallel import plane_parallel_layers  # noqa: E402

SUN_ELEVATION = np.array([40.0])
VIEW_ZENITH = np.array([0.0, 30.0, 60.0])
RELATIVE_AZIMUTH = np.array([0.0, 90.0, 180.0])


@pytest.fixture(scope="module")
def rayleigh():
    atm = Atmosphere(location="rural", month=6, aerosol="none", stratospheric="none", albedo=0.0)
    prof = atm.optical_profile([450.0])
    return prof, plane_parallel_layers(prof, n_layers=40, n_moments=16)


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


def test_marcher_agrees_with_disort_rayleigh(rayleigh):
    prof, lay = rayleigh
    dis = run_disort(lay, 90.0 - SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH, n_streams=16)
    mar = run_marcher(prof, SUN_ELEVATION, VIEW_ZENITH, RELATIVE_AZIMUTH, quality="preview")
    rel = mar / dis - 1.0
    assert np.max(np.abs(rel)) < 0.02, rel
