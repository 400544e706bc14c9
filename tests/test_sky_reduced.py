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
