"""The volume shells of the add-on's Volumetric mode (skymodel.optics.shells): one home for
their edges, read by the add-on, the planner and its measured tables."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.errors import SkymodelInputError
from skymodel.optics import shells
from skymodel.optics.profile import layer_edges_by_optical_depth
from skymodel.wavelengths import default_wavelengths


@pytest.fixture(scope="module")
def rural():
    return Atmosphere(location="rural", month=6).optical_profile(default_wavelengths(20.0))


def test_shells_span_the_atmosphere_and_keep_every_species_column(rural):
    lay = shells.volume_shells(rural, 8)
    e = lay.edges_m
    assert e.size == 9 and e[0] == pytest.approx(rural.altitudes_m[0]) and e[-1] == pytest.approx(rural.altitudes_m[-1])
    assert np.all(np.diff(e) > 0)
    for name in ("rayleigh_scattering", "ozone_absorption", "aerosol_absorption"):
        assert lay.vertical_optical_depth(getattr(lay, name)) == pytest.approx(
            rural.vertical_optical_depth(getattr(rural, name)), rel=1e-6), name


def test_shell_edges_share_the_columns_of_extinction_to_the_exponent(rural):
    """Each shell holds the same share of the column of extinction(550 nm)^0.3; equal optical
    depth (exponent 1) leaves the upper air in one thick top layer, these shells cut it finer."""
    n = 8
    e = shells.layer_edges(rural, n)
    j = int(np.argmin(np.abs(rural.wavelengths_nm - 550.0)))
    h = rural.altitudes_m
    w = rural.extinction[:, j] ** shells.EDGE_EXPONENT
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(h))])
    shares = np.diff(np.interp(e, h, cum))
    assert shares == pytest.approx(np.full(n, cum[-1] / n), rel=1e-3)
    tau = layer_edges_by_optical_depth(rural, n)
    assert e[-2] > tau[-2] + 10_000.0  # the top shell starts at least 10 km higher
    assert np.allclose(shells.layer_edges(rural, n, exponent=1.0), tau, atol=1.0)


def test_bad_shell_counts_are_refused_by_name(rural):
    for bad in (0, -3, 2.5, True, "8"):
        with pytest.raises(SkymodelInputError, match="n_layers"):
            shells.volume_shells(rural, bad)


def test_the_add_on_and_the_planner_read_the_same_shells():
    from blender_addon import volumetric
    from skymodel.planner import decisions

    assert volumetric.layer_edges is shells.layer_edges
    assert volumetric.TWILIGHT_MIN_LAYERS == decisions.TWILIGHT_MIN_LAYERS == shells.TWILIGHT_MIN_LAYERS
