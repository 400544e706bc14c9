"""The sky as lighting (skymodel.validation.lighting): the irradiance on a horizontal
surface and its errors, which the effect table and the accuracy table's knob rows share."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.colorimetry import spectral_to_xyz
from skymodel.render.cameras import make_camera
from skymodel.validation.lighting import horizontal_irradiance, lighting_errors
from skymodel.wavelengths import default_wavelengths


def _sphere(width=256):
    cam = make_camera("equirectangular", width, width // 2)
    d, _ = cam.directions()
    return d.reshape(-1, 3), cam.pixel_solid_angles().ravel()


def test_a_uniform_sky_gives_pi_times_its_radiance_plus_the_sun_on_the_plane():
    """E_h = pi L for a sky of uniform radiance L (the ground's half left out), plus the
    direct beam times the sine of the sun's elevation, and nothing of the sun below the horizon."""
    dirs, omega = _sphere()
    wl = default_wavelengths(20.0)
    L = np.linspace(0.05, 0.3, wl.size)
    sun = np.linspace(1.0, 2.0, wl.size)
    rad = np.broadcast_to(L, (dirs.shape[0], wl.size))
    assert omega.sum() == pytest.approx(4 * np.pi, rel=1e-3)
    assert horizontal_irradiance(rad, dirs, omega, 0 * sun, 30.0) == pytest.approx(np.pi * L, rel=2e-3)
    assert horizontal_irradiance(rad, dirs, omega, sun, 30.0) == pytest.approx(np.pi * L + 0.5 * sun, rel=2e-3)
    assert np.array_equal(horizontal_irradiance(rad, dirs, omega, sun, -4.0),
                          horizontal_irradiance(rad, dirs, omega, 0 * sun, -4.0))
    # light from below the horizon does not reach the plane's upper face
    below = np.where(dirs[:, 2:3] < 0, 1.0, 0.0) * L
    assert np.all(horizontal_irradiance(below, dirs, omega, 0 * sun, 30.0) == 0.0)


def test_lighting_errors_count_brightness_and_colour_against_the_reference():
    wl = default_wavelengths(10.0)
    ref = spectral_to_xyz(np.linspace(1.0, 0.6, wl.size), wl)
    same = lighting_errors(ref, ref)
    assert same["illuminance_rel"] == 0.0 and same["de2000"] == pytest.approx(0.0, abs=1e-9)
    brighter = lighting_errors(1.02 * ref, ref)
    assert brighter["illuminance_rel"] == pytest.approx(0.02)
    assert 0.0 < brighter["de2000"] < 2.0  # 2 % more light: a small change of lightness
    bluer = spectral_to_xyz(np.linspace(1.1, 0.5, wl.size), wl)
    bluer *= ref[1] / bluer[1]  # the same illuminance, another colour
    tinted = lighting_errors(bluer, ref)
    assert tinted["illuminance_rel"] == pytest.approx(0.0, abs=1e-12) and tinted["de2000"] > brighter["de2000"]
