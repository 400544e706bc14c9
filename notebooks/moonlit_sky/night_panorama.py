"""A full-moon night panorama from the pieces as they stand, and the moonlit sky's colour.

    nice -n 10 python notebooks/moonlit_sky/night_panorama.py      # about 1-2 minutes

Madrid, 2026-01-03 23:00 UTC (full moon high in the south-east, the sun 70 degrees down),
rural atmosphere for January, 20 nm grid. The moonlit sky is SkyMarcher's sky with the sun
at the moon's place times moon_irradiance / solar spectrum; the stars, the moon's disc and
the natural glow come from skymodel.astro.night_sky.night_sources_image, dimmed by the same
atmosphere's direct transmittance (the marcher's sun-transmittance table read along each
zenith angle). Writes night_panorama.png (equirectangular 512 x 256, centre azimuth 90,
the preview tonemap with its automatic exposure) and night_panorama_moonless.png (the same
stars and glow without the moon and its light, 1 EV above the automatic exposure), and prints the zenith's luminance and chromaticity for the
moonlit sky and for the same sky lit by the sun at the moon's place.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skymodel import Atmosphere
from skymodel.astro.lunar_irradiance import illuminance_lux, moon_irradiance
from skymodel.astro.night_background import dark_sky_zenith_radiance
from skymodel.astro.night_sky import night_sources_image
from skymodel.colorimetry import K_M, spectral_to_rgb, spectral_to_xyz
from skymodel.render.cameras import EquirectangularCamera
from skymodel.render.image_io import tonemap, write_png
from skymodel.render.marcher import SkyMarcher
from skymodel.wavelengths import default_wavelengths

HERE = Path(__file__).resolve().parent
WL = default_wavelengths(20.0)
HEIGHT = 256
LAT, LON, TIME = 40.4, -3.7, "2026-01-03T23:00:00"


def main():
    prof = Atmosphere(location="rural", month=1).optical_profile(WL)
    night = night_sources_image(HEIGHT, LAT, LON, TIME, WL, parts=())  # the moon's place and phase only
    moon = night.moon
    print(f"moon: elevation {moon.elevation_deg:.1f}, azimuth {moon.azimuth_deg:.1f}, phase angle "
          f"{moon.phase_angle_deg:.1f} deg, lit {moon.illuminated_fraction:.3f}, distance {moon.distance_km:.0f} km")
    m = SkyMarcher(prof, float(moon.elevation_deg), float(moon.azimuth_deg))
    cam = EquirectangularCamera(2 * HEIGHT, center_azimuth_deg=90.0)
    dirs, _ = cam.directions()
    sky = m.radiance(dirs.reshape(-1, 3)).radiance.reshape(HEIGHT, 2 * HEIGHT, WL.size)
    ratio = moon_irradiance(moon, WL) / prof.solar_irradiance
    moonlit = sky * ratio

    def transmittance(zenith_deg):
        mu = np.cos(np.radians(np.asarray(zenith_deg, float)))
        return m.sun_table.transmittance(np.zeros(mu.shape), mu)

    sources = night_sources_image(HEIGHT, LAT, LON, TIME, WL, transmittance=transmittance)
    total = moonlit + sources.radiance
    total[HEIGHT // 2:] = 0.0  # the ground half: not rendered here

    zen_day, zen_moon = sky[0].mean(axis=0), moonlit[0].mean(axis=0)
    for name, spec in (("sunlit (sun at the moon's place)", zen_day), ("moonlit", zen_moon),
                       ("natural glow (zenith)", dark_sky_zenith_radiance(WL))):
        xyz = spectral_to_xyz(spec, WL)
        x, y = xyz[0] / xyz.sum(), xyz[1] / xyz.sum()
        print(f"zenith, {name}: luminance {K_M * xyz[1]:.3e} cd/m^2, CIE x, y = {x:.4f}, {y:.4f}")
    e_ground = illuminance_lux(sources.moon_irradiance, WL) * np.sin(np.radians(moon.elevation_deg))
    print(f"direct moonlight on the ground: {e_ground:.3f} lux on a horizontal surface "
          f"({illuminance_lux(sources.moon_irradiance, WL):.3f} lux facing the moon)")
    print(f"stars drawn: {sources.n_stars_drawn}")
    sky_half = np.arange(HEIGHT)[:, None].repeat(2 * HEIGHT, 1) < HEIGHT // 2
    png = tonemap(spectral_to_rgb(total, WL), valid=sky_half)
    write_png(HERE / "night_panorama.png", png)
    # the same night without the moon: stars and glow only (the moon below the horizon)
    dark = night_sources_image(HEIGHT, LAT, LON, TIME, WL, transmittance=transmittance, parts=("stars", "glow"))
    png = tonemap(spectral_to_rgb(dark.radiance, WL), valid=sky_half, exposure_ev=1.0)
    write_png(HERE / "night_panorama_moonless.png", png)
    print(f"wrote {HERE / 'night_panorama.png'} and night_panorama_moonless.png")


if __name__ == "__main__":
    main()
