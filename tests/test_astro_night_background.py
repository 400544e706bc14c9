"""The natural night sky (skymodel.astro.night_background) against its published figures."""

import numpy as np
import pytest

from skymodel.astro import night_background as nb
from skymodel.colorimetry import K_M, cmf_weights
from skymodel.errors import SkymodelInputError
from skymodel.wavelengths import default_wavelengths

WL = default_wavelengths()


def test_zenith_spectrum_gives_back_the_published_band_brightnesses():
    l = nb.dark_sky_zenith_radiance(WL)
    for band in ("B", "V", "R"):
        lam = nb.BAND_EFFECTIVE_WAVELENGTH_NM[band]
        mag = nb.radiance_to_surface_brightness(np.interp(lam, WL, l), band)
        assert mag == pytest.approx(nb.DARK_SKY_ZENITH_MAG_ARCSEC2[band], abs=0.01)  # 438, 641 nm lie between grid points
    # V = 21.9 mag/arcsec^2 is 2.7e-9 W m^-2 sr^-1 nm^-1 at 545 nm
    assert nb.surface_brightness_to_radiance(21.9) == pytest.approx(2.69e-9, rel=0.01)


def test_luminance_matches_the_natural_sky_of_light_pollution_atlases():
    """Falchi et al. (2016, Science Advances 2, e1600377) take the natural sky as 22.0
    mag_V/arcsec^2 = 174 ucd/m^2; the spectrum here, set to V = 22.0, gives 192 ucd/m^2
    (photopic luminance from the CIE 1931 ybar; ratio 1.10: the red airglow bands, R 0.9 mag
    brighter than V, add to the photopic band beyond what the V magnitude alone carries)."""
    l = nb.dark_sky_zenith_radiance(WL, zenith_v_mag=22.0)
    lum = K_M * l @ cmf_weights(WL)[:, 1]
    assert lum == pytest.approx(174e-6, rel=0.15)


def test_zenith_angle_dependence_is_krisciunas_schaefer():
    assert nb.van_rhijn_factor(0.0) == pytest.approx(1.0)
    assert nb.van_rhijn_factor(90.0) == pytest.approx(5.0)
    z = np.array([0.0, 30.0, 60.0, 80.0, 90.0])
    l = nb.dark_sky_radiance(WL, z)
    x = nb.van_rhijn_factor(z)
    expected = nb.dark_sky_zenith_radiance(WL) * (x * 10 ** (-0.4 * 0.172 * (x - 1)))[:, None]
    assert np.allclose(l, expected)
    v = nb.radiance_to_surface_brightness(l[:, np.searchsorted(WL, 545)], "V")
    assert np.all(np.diff(v) < 0)  # brighter toward the horizon (measured 0.97 mag at 80 degrees)
    assert v[0] - v[3] == pytest.approx(1.1, abs=0.3)
    # a caller's own transmittance ratio replaces the grey extinction
    ratio = np.full((z.size, WL.size), 0.5)
    assert np.allclose(nb.dark_sky_radiance(WL, z, transmittance_ratio=ratio),
                       nb.dark_sky_zenith_radiance(WL) * x[:, None] * 0.5)


@pytest.mark.parametrize(
    "call, parameter",
    [
        (lambda: nb.dark_sky_zenith_radiance(WL, zenith_v_mag=30.0), "zenith_v_mag"),
        (lambda: nb.dark_sky_radiance(WL, 95.0), "zenith_deg"),
        (lambda: nb.dark_sky_radiance(WL, 10.0, transmittance_ratio=-1.0), "transmittance_ratio"),
        (lambda: nb.surface_brightness_to_radiance(21.0, "K"), "band"),
    ],
)
def test_bad_input_names_the_parameter(call, parameter):
    with pytest.raises(SkymodelInputError) as err:
        call()
    assert err.value.parameter == parameter
