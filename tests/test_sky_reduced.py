"""Band-by-band rendering straight to RGB (``render_sky_reduced``) gives the same pixels as
reducing the full spectral image of ``render_sky``, whatever the band size."""

import numpy as np
import pytest

from skymodel import Atmosphere
from skymodel.colorimetry import spectral_to_rgb
from skymodel.render.cameras import make_camera
from skymodel.render.sky import render_sky, render_sky_reduced


@pytest.fixture(scope="module")
def case():
    prof = Atmosphere(location="rural", month=6).optical_profile(np.arange(400.0, 701.0, 50.0))
    cam = make_camera("fisheye", 24)
    full = render_sky(prof, cam, 20.0, 150.0, quality="preview", include_sun=False)
    return prof, cam, full


@pytest.mark.parametrize("band_pixels", [1, 37, 10_000])
def test_bands_reproduce_the_full_render(case, band_pixels):
    prof, cam, full = case
    rgb, sun_irr, info = render_sky_reduced(prof, cam, 20.0, lambda r, w: spectral_to_rgb(r, w), 3, 150.0,
                                            quality="preview", band_pixels=band_pixels)
    expect = spectral_to_rgb(full.radiance, prof.wavelengths_nm)
    assert rgb.shape == cam.shape + (3,)
    np.testing.assert_allclose(rgb[full.valid], expect[full.valid], rtol=1e-10, atol=1e-14)
    assert np.all(rgb[~full.valid] == 0.0)
    np.testing.assert_allclose(sun_irr, full.sun_irradiance, rtol=1e-12)
    assert info["bands"] == int(np.ceil(full.valid.sum() / band_pixels))


def test_memory_guard_counts_only_the_kept_channels():
    # 2048x1024 at 81 wavelengths is refused as a spectral cube, accepted as 3 channels
    from skymodel.errors import SkymodelInputError

    with pytest.raises(SkymodelInputError, match="memory|GiB|bytes"):
        make_camera("equirectangular", 4096, n_wavelengths=81)
    make_camera("equirectangular", 4096, n_wavelengths=3)


def test_render_sky_reduced_checks_render_skys_memory_estimate_before_any_work(case, monkeypatch):
    """Called directly (the add-on's path), render_sky_reduced refuses a render over the limit
    with the same estimate as render_sky and the CLI (skymodel.render.memory: n_channels values
    a pixel, the spectra of band_pixels marched pixels), before solving or marching anything."""
    from skymodel.errors import SkymodelInputError
    from skymodel.render import sky
    from skymodel.render.memory import GIB, estimate_render_memory
    from skymodel.render.skyview import xyz_reduction

    prof, _, _ = case

    def no_work(*a, **k):
        raise AssertionError("work started before the memory check")

    monkeypatch.setattr(sky, "_solution", no_work)
    monkeypatch.setattr(sky, "SkyMarcher", no_work)
    n_wl = prof.wavelengths_nm.size
    cam = make_camera("equirectangular", 8192, n_wavelengths=3)  # the camera's own image-only guard lets it pass
    for reduce, method, table in ((xyz_reduction(prof.wavelengths_nm), "auto", None),
                                  (xyz_reduction(prof.wavelengths_nm), "direct", False),
                                  (lambda r, w: spectral_to_rgb(r, w), "auto", False)):
        est = estimate_render_memory(8192, 4096, n_wl, "final", wavelengths_nm=prof.wavelengths_nm, image_channels=3,
                                     band_pixels=4096, sky_view_table=table, sun_elevation_deg=20.0, camera=cam)
        limit = 0.99 * est.total / GIB
        with pytest.raises(SkymodelInputError) as e:
            render_sky_reduced(prof, cam, 20.0, reduce, 3, quality="final", band_pixels=4096, method=method,
                               max_memory_gib=limit)
        assert e.value.parameter == "max_memory" and est.text() in str(e.value)
    direct = estimate_render_memory(8192, 4096, n_wl, "final", image_channels=3, band_pixels=4096,
                                    sky_view_table=False)
    assert direct.total > estimate_render_memory(8192, 4096, n_wl, "final", image_channels=3,
                                                 band_pixels=4096).total
    # the default limit (the registry's max_memory, 4 GiB) applies as in render_sky
    with pytest.raises(SkymodelInputError, match="max_memory"):
        render_sky_reduced(prof, make_camera("equirectangular", 8192, n_wavelengths=3), 20.0,
                           lambda r, w: spectral_to_rgb(r, w), 3, quality="final", band_pixels=1 << 20)


@pytest.mark.parametrize("name, sun_el, sun_az", [("equirectangular", 20.0, 150.0), ("equirectangular", 89.9, 10.0),
                                                  ("fisheye", 30.0, 200.0), ("fisheye", -5.0, 200.0),
                                                  ("dome", 0.2, 90.0)])
def test_sun_disc_found_by_bands_of_rows_is_the_whole_images(name, sun_el, sun_az):
    """render_sky_reduced finds the disc's pixels by bands of rows (never every direction at once)."""
    from skymodel.render.rays import sun_direction
    from skymodel.render.sky import _sun_disc_of_camera, sun_disc_spectra

    cam = make_camera(name, 200)
    wl = np.array([450.0, 550.0, 650.0])
    irr = np.array([1.0, 2.0, 3.0])
    s = sun_direction(sun_el, sun_az)
    d, valid = cam.directions()
    mask, spectra = sun_disc_spectra(d, valid, cam.pixel_solid_angles(), s, irr, wl)
    mask_b, spectra_b = _sun_disc_of_camera(cam, s, irr, wl, rows=7)
    np.testing.assert_array_equal(mask_b, mask)
    np.testing.assert_array_equal(spectra_b, spectra)


def test_float32_image_is_the_float64_one_rounded(case):
    """``dtype=np.float32`` (the CLI's colour path) stores each band, computed in float64, as float32."""
    from skymodel.errors import SkymodelInputError
    from skymodel.render.skyview import xyz_reduction

    prof, cam, _ = case
    reduce = xyz_reduction(prof.wavelengths_nm)
    x64, _, _ = render_sky_reduced(prof, cam, 20.0, reduce, 3, 150.0, quality="preview", band_pixels=37,
                                   include_sun=True)
    x32, _, _ = render_sky_reduced(prof, cam, 20.0, reduce, 3, 150.0, quality="preview", band_pixels=37,
                                   include_sun=True, dtype=np.float32)
    assert x64.dtype == np.float64 and x32.dtype == np.float32
    np.testing.assert_array_equal(x32, x64.astype(np.float32))
    with pytest.raises(SkymodelInputError, match="dtype"):
        render_sky_reduced(prof, cam, 20.0, reduce, 3, quality="preview", dtype=np.int32)
