"""The night's own light in one equirectangular image: stars, the moon's disc and the natural glow.

:func:`night_sources_image` is the one call a renderer needs to add what the night brings
besides scattered light: the catalogue stars and the moon as point sources of the right
irradiance (:func:`skymodel.astro.stars.splat_stars`, energy kept per pixel) and the
natural sky glow (:func:`skymodel.astro.night_background.dark_sky_radiance`), all dimmed by
the caller's own direct transmittance of the atmosphere, so that the same atmosphere that
lights the scattered sky dims the sources. The moonlit *sky* (the atmosphere scattering
moonlight) is not here: that is the renderer's sky with the sun at the moon's place, times
``moon_irradiance / solar_irradiance`` (docs/night.md).

Horizon
    Below the horizon (the ground half of the image) nothing is drawn. The moon's disc sets
    gradually: its irradiance is weighted by the fraction of the disc above the horizon (a
    circular segment of the topocentric disc), so a setting moon fades over the two minutes
    its disc takes to cross the horizon instead of vanishing in one frame. A star is a point
    and leaves when its centre does; the transmittance near the horizon is small (airmass
    about 38), so the step is small too.

Image conventions as :class:`skymodel.render.cameras.EquirectangularCamera`: zenith at the
top row, azimuth increasing to the right, the centre line toward ``center_azimuth_deg``
(default 90, the environment maps' choice); radiance W m^-2 sr^-1 nm^-1 on the wavelength grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymodel.astro.lunar_irradiance import moon_irradiance
from skymodel.astro.moon import MoonPosition, moon_position
from skymodel.astro.night_background import DARK_SKY_ZENITH_MAG_ARCSEC2, dark_sky_radiance
from skymodel.astro.stars import StarPlaces, splat_stars, star_irradiance, star_positions
from skymodel.errors import SkymodelInputError
from skymodel.wavelengths import as_wavelengths

#: Largest image height accepted (a 16384 x 8192 map).
MAX_HEIGHT = 8192
#: The parts :func:`night_sources_image` can draw.
PARTS = ("stars", "moon", "glow")


def disc_fraction_above_horizon(elevation_deg, angular_radius_deg) -> np.ndarray:
    """Fraction (0..1) of a disc of the given angular radius whose centre is at
    ``elevation_deg`` that lies above the horizon (flat-horizon circular segment:
    1 - (acos(d) - d sqrt(1 - d^2)) / pi with d = elevation / radius, clipped to [-1, 1])."""
    d = np.clip(np.asarray(elevation_deg, float) / np.asarray(angular_radius_deg, float), -1.0, 1.0)
    return 1.0 - (np.arccos(d) - d * np.sqrt(1.0 - d * d)) / np.pi


@dataclass(frozen=True)
class NightSources:
    """What :func:`night_sources_image` drew."""

    radiance: np.ndarray  #: (H, 2H, n_wl), W m^-2 sr^-1 nm^-1
    wavelengths_nm: np.ndarray
    moon: MoonPosition  #: the moon's place and phase at the time
    moon_irradiance: np.ndarray  #: (n_wl,) at the ground, disc fraction and transmittance applied, W m^-2 nm^-1
    stars: StarPlaces  #: every catalogue star's place at the time
    n_stars_drawn: int  #: catalogue stars above the horizon


def _transmittance(fn, zenith_deg, n_wl):
    if fn is None:
        return np.ones((np.size(zenith_deg), n_wl))
    t = np.asarray(fn(np.asarray(zenith_deg, float)), dtype=float)
    if t.ndim == 1:
        t = np.repeat(t[:, None], n_wl, axis=1)
    if t.shape != (np.size(zenith_deg), n_wl) or not np.all(np.isfinite(t)) or np.any(t < 0):
        raise SkymodelInputError("transmittance", f"values of shape {t.shape}",
                                 f"a function of zenith angle (n,) returning finite values >= 0 of shape (n,) or (n, {n_wl})")
    return t


def night_sources_image(height: int, latitude_deg: float, longitude_deg: float, time_utc, wavelengths_nm=None, *,
                        transmittance=None, center_azimuth_deg: float = 90.0,
                        zenith_v_mag: float = DARK_SKY_ZENITH_MAG_ARCSEC2["V"], parts=PARTS,
                        altitude_m: float = 0.0) -> NightSources:
    """Stars, moon and natural glow for one place and time in an equirectangular image
    ``2 height`` wide (module docstring).

    ``transmittance``: None (no atmosphere: the sources as above it, the glow as measured
    at a dark site with Krisciunas & Schaefer's grey extinction) or a function
    ``f(zenith_deg (n,)) -> (n, n_wl)`` (or ``(n,)``) giving the direct transmittance from
    the top of the atmosphere to the observer along each zenith angle (0-90); the glow is
    then scaled by ``f(z) / f(0)`` so that its zenith keeps the published value.
    ``parts``: any of ``"stars"``, ``"moon"``, ``"glow"``.
    """
    if isinstance(height, bool) or not isinstance(height, (int, np.integer)) or not 1 <= height <= MAX_HEIGHT:
        raise SkymodelInputError("height", height, f"an integer in [1, {MAX_HEIGHT}] (the image is 2 x height wide)")
    wl = as_wavelengths(wavelengths_nm)
    unknown = [p for p in parts if p not in PARTS]
    if unknown or isinstance(parts, str):
        raise SkymodelInputError("parts", parts, "a list of " + ", ".join(PARTS))
    mp = moon_position(latitude_deg, longitude_deg, time_utc, altitude_m=altitude_m)
    if np.ndim(mp.elevation_deg) != 0:
        raise SkymodelInputError("time_utc", time_utc, "one time")
    sp = star_positions(latitude_deg, longitude_deg, time_utc)
    img = np.zeros((height, 2 * height, wl.size))
    n_wl = wl.size

    if "glow" in parts:
        zen = (np.arange(height) + 0.5) * (180.0 / height)
        sky_rows = zen <= 90.0
        z = zen[sky_rows]
        if transmittance is None:
            glow = dark_sky_radiance(wl, z, zenith_v_mag=zenith_v_mag)
        else:
            ratio = _transmittance(transmittance, z, n_wl) / np.maximum(_transmittance(transmittance, [0.0], n_wl), 1e-300)
            glow = dark_sky_radiance(wl, z, zenith_v_mag=zenith_v_mag, transmittance_ratio=ratio)
        img[sky_rows] += glow[:, None, :]

    n_drawn = 0
    if "stars" in parts:
        up = sp.elevation_deg >= 0.0
        n_drawn = int(up.sum())
        e = star_irradiance(wl)[up]
        splat_stars(img, sp.elevation_deg[up], sp.azimuth_deg[up], e, center_azimuth_deg=center_azimuth_deg,
                    transmittance=None if transmittance is None else (lambda zz: _transmittance(transmittance, zz, n_wl)))

    e_moon = np.zeros(n_wl)
    if "moon" in parts:
        frac = float(disc_fraction_above_horizon(mp.elevation_deg, mp.angular_radius_deg))
        if frac > 0.0:
            zen_moon = min(90.0 - float(mp.elevation_deg), 90.0)
            t = _transmittance(transmittance, [zen_moon], n_wl)[0]
            e_moon = frac * t * moon_irradiance(mp, wl)
            splat_stars(img, [max(float(mp.elevation_deg), 0.0)], [float(mp.azimuth_deg)], e_moon[None, :],
                        center_azimuth_deg=center_azimuth_deg)
    return NightSources(radiance=img, wavelengths_nm=wl, moon=mp, moon_irradiance=e_moon, stars=sp,
                        n_stars_drawn=n_drawn)
