"""The sky-view table (skymodel.render.skyview): resampled once-marched sky against direct
marching of every pixel, at small sizes."""

from dataclasses import replace

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.errors import SkymodelInputError
from skymodel.render.cameras import make_camera
from skymodel.render.marcher import SkyMarcher, optics_key, solve_sky
from skymodel.render.quality import quality_settings
from skymodel.render.sky import render_sky, render_sky_reduced
from skymodel.render.skyview import (CAP_AROUND, CAP_EXACT_DEG, CAP_RADIAL, SkyViewTable, cap_radial_nodes,
                                     rgb_reduction, xyz_reduction)

SETTINGS = replace(quality_settings("preview"), table_altitudes=12, table_mu=12, table_phi=6, table_mus=12,
                   table_steps=16, sun_table_altitudes=32, sun_table_x=48, sun_table_steps=48, max_orders=4,
                   grid_zenith=48, grid_zenith_ground=12, grid_azimuth=25)
WL = np.linspace(400.0, 700.0, 11)


@pytest.fixture(scope="module")
def skies():
    out = {}
    for aerosol in ("rural", "desert"):
        prof = Atmosphere(location=aerosol, month=6).optical_profile(WL)
        out[aerosol] = (prof, solve_sky(prof, SETTINGS))
    return out


def _outside_disc(cam, sun_el, sun_az):
    from skymodel.render.rays import sun_direction

    dirs, valid = cam.directions()
    return valid & (dirs @ sun_direction(sun_el, sun_az) < np.cos(np.radians(0.3)))


@pytest.mark.parametrize("aerosol, sun_el", [("rural", 30.0), ("rural", -4.0), ("desert", 60.0), ("desert", 20.0),
                                             ("desert", 5.0), ("desert", 0.0)])
def test_table_matches_direct_marching(skies, aerosol, sun_el):
    """Mean <= 0.1 %, max <= 0.5 % (XYZ, per channel) outside the sun disc, as the issue asks;
    a 160x80 panorama puts ~60 pixels in the sun cap. Coarse desert dust included (measured max
    0.32/0.15/0.16 % at sun 60/20/5): until the peak spread cancelled the phase function's
    ripples (c9d5e72), direct marching drew rings 6-12 degrees from the sun that no cap follows
    (1.1-2.5 % here, 5.9-7.1 % at 512x256 `final`)."""
    _check_table(skies, aerosol, sun_el, 5e-3)


def _check_table(skies, aerosol, sun_el, max_rel):
    prof, sol = skies[aerosol]
    cam = make_camera("equirectangular", 160, n_wavelengths=3)
    red = xyz_reduction(WL)
    args = (prof, cam, sun_el, red, 3, 150.0, 0.0, SETTINGS)
    tab, _, info_t = render_sky_reduced(*args, solution=sol, method="table")
    dire, _, info_d = render_sky_reduced(*args, solution=sol, method="direct")
    assert info_t["method"] == "table" and info_d["method"] == "direct"
    keep = _outside_disc(cam, sun_el, 150.0) & (dire[..., 1] > 0)
    rel = np.abs(tab / np.where(keep[..., None], dire, 1.0) - 1.0)
    assert rel[keep].mean() <= 1e-3, rel[keep].mean()
    assert rel[keep].max() <= max_rel, rel[keep].max()


@pytest.mark.parametrize("sun_el, max_rel", [(3.0, 5e-3), (1.0, 2e-2)])
def test_table_beside_a_low_sun(skies, sun_el, max_rel):
    """Beside a sun a few degrees up, on its own row, the cap holds exact / main grid (within
    4 degrees of the horizon), and the main grid's cells cut the aureole's power-law fall into
    kinks unless the base is read along its rows in the logarithm of the angle from the sun.
    Measured max here 0.23/1.2 % at sun 3/1 (2.7/4.2 % with the base read linearly, 1.2/1.3 %
    bilinearly in the logarithm); at 512x256 rural 1 deg `preview` 0.87 %, `final` 0.21 %
    (docs/benchmarks.md, "Large environment maps")."""
    _check_table(skies, "rural", sun_el, max_rel)


def test_spectral_table_and_rgb_finish(skies):
    """render_sky's table path gives the spectra of direct marching; a gamut-fit finish is
    applied after the (linear) resampling, as reduce_to_rgb does to marched spectra."""
    from skymodel.render.environment import fit_into_gamut, reduce_to_rgb

    prof, sol = skies["rural"]
    cam = make_camera("equirectangular", 96, n_wavelengths=WL.size)
    t = render_sky(prof, cam, 20.0, 180.0, 0.0, SETTINGS, include_sun=False, solution=sol, method="table")
    d = render_sky(prof, cam, 20.0, 180.0, 0.0, SETTINGS, include_sun=False, solution=sol, method="direct")
    assert t.info["method"] == "table" and d.info["method"] == "direct"
    keep = _outside_disc(cam, 20.0, 180.0)
    np.testing.assert_allclose(t.radiance[keep], d.radiance[keep], rtol=5e-3)
    rgb, _, _ = render_sky_reduced(prof, cam, 20.0, rgb_reduction(WL, finish=fit_into_gamut), 3, 180.0, 0.0,
                                   SETTINGS, solution=sol, method="direct")
    np.testing.assert_allclose(rgb, reduce_to_rgb(d.radiance, WL), rtol=1e-9, atol=1e-12)


def test_reduced_render_draws_the_sun_disc_like_render_sky(skies):
    prof, sol = skies["rural"]
    cam = make_camera("equirectangular", 64, n_wavelengths=WL.size)
    full = render_sky(prof, cam, 30.0, 180.0, 0.0, SETTINGS, include_sun=True, solution=sol, method="direct")
    xyz, _, info = render_sky_reduced(prof, cam, 30.0, xyz_reduction(WL), 3, 180.0, 0.0, SETTINGS, solution=sol,
                                      method="direct", include_sun=True)
    assert info["sun_pixels"] == full.info["sun_pixels"] >= 1
    np.testing.assert_allclose(xyz, full.radiance @ xyz_reduction(WL).matrix, rtol=1e-9, atol=1e-12)


def test_table_symmetry_and_straddling_cap(skies):
    """A sun at the horizon: the cap straddles the sky/ground edge; pixels whose cap nodes
    are on the other side are marched exactly; the two halves mirror each other."""
    prof, sol = skies["desert"]
    m = SkyMarcher(prof, 0.0, 180.0, 0.0, SETTINGS, solution=sol)
    table = SkyViewTable(m, xyz_reduction(WL))
    g = np.radians(np.linspace(-7.9, 7.9, 41))
    for z in (89.0, 90.0, 91.0):
        zr = np.radians(z)
        d = np.stack([np.sin(zr) * np.sin(np.pi + g), np.sin(zr) * np.cos(np.pi + g), np.full(g.shape, np.cos(zr))], 1)
        v = table.lookup(d)
        np.testing.assert_allclose(v, v[::-1], rtol=1e-9)
        assert np.all(np.isfinite(v)) and np.all(v >= 0)


def test_method_is_checked(skies):
    prof, _ = skies["rural"]
    cam = make_camera("equirectangular", 16, n_wavelengths=3)
    with pytest.raises(SkymodelInputError, match="method"):
        render_sky_reduced(prof, cam, 30.0, xyz_reduction(WL), 3, quality=SETTINGS, method="fast")


def test_cap_keeps_its_log_spacing_when_wider(skies):
    """The cap's radial nodes grow with the log of its reach (final's 12-degree cap: 41, the
    8-degree one's spacing), and a table built for a 12-degree cap marches that many rings
    where the cap reaches the horizon's band (sun 10), every other one where it is clear (30)."""
    assert cap_radial_nodes(8.0) == CAP_RADIAL and cap_radial_nodes(12.0) == 41
    for deg in (8.0, 12.0, 20.0):
        step = np.log(deg / CAP_EXACT_DEG) / (cap_radial_nodes(deg) - 1)
        assert abs(step / (np.log(4.0) / (CAP_RADIAL - 1)) - 1.0) < 0.03
    prof, sol = skies["rural"]
    s12 = replace(SETTINGS, sun_exact_deg=12.0)
    m = SkyMarcher(prof, 30.0, 180.0, 0.0, s12, solution=replace(sol, settings=s12, key=optics_key(prof, s12)))
    clear = SkyViewTable(m, xyz_reduction(WL))
    assert clear.cap_u.size == 21
    low = SkyMarcher(prof, 10.0, 180.0, 0.0, s12, solution=replace(sol, settings=s12, key=optics_key(prof, s12)))
    table = SkyViewTable(low, xyz_reduction(WL))
    assert not table.clear and (table.cap_u.size, table.cap_psi.size) == (41, CAP_AROUND)
    # the memory guard counts the directions each table marched, given the sun (none: the full cap)
    from skymodel.render.memory import _cap_nodes

    assert _cap_nodes(12.0, 30.0) == clear.timings["cap_nodes"] == 21 * 25
    assert _cap_nodes(12.0, 10.0) == _cap_nodes(12.0, None) == table.timings["cap_nodes"] == 41 * CAP_AROUND


def test_clear_cap_keeps_every_other_node_and_splits_single_scattering(skies):
    """A cap clear of the horizon's band (sun 30, 8-degree cap) keeps every other node of the
    full grid; away from the horizon a pixel is its single scattering (reference times the
    interpolated ratio) plus the rest, so at a node the table gives the marched value."""
    prof, sol = skies["desert"]
    m = SkyMarcher(prof, 30.0, 180.0, 0.0, SETTINGS, solution=sol)
    red = xyz_reduction(WL)
    table = SkyViewTable(m, red)
    full = SkyViewTable(m, red, coarse_when_clear=False)
    assert table.clear and (table.cap_u.size, table.cap_psi.size) == ((CAP_RADIAL + 1) // 2, (CAP_AROUND + 1) // 2)
    assert (full.cap_u.size, full.cap_psi.size) == (CAP_RADIAL, CAP_AROUND)
    assert table.cap_split.all()
    # nodes of the coarse grid (inside, not on the cap's edges): the table returns the marched values
    g = table._gamma(table.cap_u[1:-1:3])
    p = table.cap_psi[2:-1:5]
    gg, pp = np.meshgrid(g, p, indexing="ij")
    d = (np.cos(gg)[..., None] * table.sun + np.sin(gg)[..., None]
         * (np.cos(pp)[..., None] * table.e1 + np.sin(pp)[..., None] * table.e2)).reshape(-1, 3)
    np.testing.assert_allclose(table.lookup(d), red.linear(sum(m._exact_parts(d))), rtol=1e-6)
    # the reference follows the aerosol phase function's shape in the angle from the sun
    ref = table._reference(g)
    assert np.all(ref > 0) and np.all(np.diff(ref[:, 1]) < 0)
