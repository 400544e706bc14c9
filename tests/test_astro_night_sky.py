"""The night's own light in one image (skymodel.astro.night_sky): energy, glow, a setting moon."""

import numpy as np
import pytest

from skymodel.astro import night_sky
from skymodel.astro.lunar_irradiance import moon_irradiance
from skymodel.astro.moon import moon_position
from skymodel.astro.night_background import dark_sky_zenith_radiance, van_rhijn_factor
from skymodel.astro.stars import equirectangular_solid_angles, star_irradiance
from skymodel.errors import SkymodelInputError
from skymodel.wavelengths import default_wavelengths

WL = default_wavelengths(20.0)
H = 64
# a full moon high over Madrid (2026-01-03 is full moon)
PLACE = dict(latitude_deg=40.4, longitude_deg=-3.7)
TIME = "2026-01-03T23:00:00"


def _energy(img):
    return (img * equirectangular_solid_angles(img.shape[0])[:, None, None]).sum(axis=(0, 1))


def test_stars_and_moon_keep_their_irradiance():
    stars = night_sky.night_sources_image(H, time_utc=TIME, wavelengths_nm=WL, parts=("stars",), **PLACE)
    up = stars.stars.elevation_deg >= 0
    assert stars.n_stars_drawn == int(up.sum()) and 3000 < stars.n_stars_drawn < 6000
    assert np.allclose(_energy(stars.radiance), star_irradiance(WL)[up].sum(axis=0), rtol=1e-12)
    moon = night_sky.night_sources_image(H, time_utc=TIME, wavelengths_nm=WL, parts=("moon",), **PLACE)
    assert moon.moon.elevation_deg > 30 and moon.moon.phase_angle_deg < 10
    assert np.allclose(moon.moon_irradiance, moon_irradiance(moon.moon, WL))
    assert np.allclose(_energy(moon.radiance), moon.moon_irradiance, rtol=1e-12)
    assert np.all(moon.radiance[H // 2 + 1:] == 0)


def test_glow_keeps_its_zenith_and_follows_the_callers_transmittance():
    def transmittance(zenith_deg):
        airmass = 1.0 / np.maximum(np.cos(np.radians(zenith_deg)), 0.03)
        return np.exp(-0.15 * airmass)[:, None] * (WL / 550.0)[None, :] ** 0  # grey, (n, n_wl)

    out = night_sky.night_sources_image(H, time_utc=TIME, wavelengths_nm=WL, parts=("glow",),
                                        transmittance=transmittance, **PLACE)
    zen = (np.arange(H) + 0.5) * 180.0 / H
    row = 10
    expected = dark_sky_zenith_radiance(WL) * van_rhijn_factor(zen[row]) * transmittance(np.array([zen[row]]))[0] \
        / transmittance(np.array([0.0]))[0]
    assert np.allclose(out.radiance[row, 0], expected) and np.allclose(out.radiance[row, 17], expected)
    assert np.all(out.radiance[H // 2:] == 0)
    # with the stars and the moon dimmed by the same transmittance
    full = night_sky.night_sources_image(H, time_utc=TIME, wavelengths_nm=WL, transmittance=transmittance, **PLACE)
    t_moon = transmittance(np.array([90.0 - full.moon.elevation_deg]))[0]
    assert np.allclose(full.moon_irradiance, t_moon * moon_irradiance(full.moon, WL))
    assert np.all(np.isfinite(full.radiance)) and np.all(full.radiance >= 0)


def test_a_setting_moon_fades_with_its_disc():
    """Continuity at the moon's horizon, criterion: at 10 s steps the drawn moon changes by
    no more than the visible fraction of its disc can (the disc, 0.5 degrees across, takes
    about two minutes to set: at most 0.12 of the full moon per step), and it reaches 0
    only when the whole disc is below the horizon."""
    mp = moon_position(40.4, -3.7, np.arange(np.datetime64("2026-01-04T07:00"), np.datetime64("2026-01-04T09:00"),
                                             np.timedelta64(1, "m")))
    i = int(np.flatnonzero((mp.true_elevation_deg[:-1] > 0) & (mp.true_elevation_deg[1:] <= 0))[0])
    t = mp.time_utc[i] - np.timedelta64(3, "m") + np.arange(0, 360, 10).astype("timedelta64[s]")
    e = np.array([night_sky.night_sources_image(8, time_utc=x, wavelengths_nm=WL, parts=("moon",), **PLACE)
                  .moon_irradiance[5] for x in t])
    full = moon_irradiance(moon_position(40.4, -3.7, t[0]), WL)[5]
    assert e[0] > 0.99 * full and e[-1] == 0.0
    assert np.max(np.abs(np.diff(e))) < 0.12 * full
    assert np.all(np.diff(e) <= 1e-12 * full)  # fading, never coming back
    frac = night_sky.disc_fraction_above_horizon(np.array([-1.0, 0.0, 1.0]), 1.0)
    assert np.allclose(frac, [0.0, 0.5, 1.0])


@pytest.mark.parametrize(
    "kwargs, parameter",
    [
        (dict(height=0), "height"),
        (dict(height=True), "height"),
        (dict(parts=("planets",)), "parts"),
        (dict(parts="stars"), "parts"),
        (dict(time_utc=["2026-01-01", "2026-01-02"]), "time_utc"),
        (dict(transmittance=lambda z: -np.ones_like(z)), "transmittance"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, parameter):
    args = dict(height=8, time_utc=TIME, wavelengths_nm=WL, **PLACE)
    args.update(kwargs)
    with pytest.raises(SkymodelInputError) as err:
        night_sky.night_sources_image(**args)
    assert err.value.parameter == parameter
