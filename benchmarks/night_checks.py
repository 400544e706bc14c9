"""The night through the renderer against published values (issue #24), printed as Markdown.

    nice -n 5 python benchmarks/night_checks.py          # about 1-2 minutes on the 2-core dev machine

1. Moonlit sky against Krisciunas & Schaefer (1991, PASP 103, 1033, eqs. 15-21): real instants
   of 2026 at Mauna Loa with the sun below -18 deg and the moon near 30/45/60 deg elevation and
   7/45/90 deg phase angle, found by scanning January-June every 10 minutes. The moonlit sky is
   what ``skymodel render --time`` composes (``skymodel.render.night``: the marcher with the
   moon's ROLO irradiance for its sun, the moon where skymodel.astro.moon puts it), rendered into
   an equirectangular 256x128 camera at the preview quality and read at K&S's sky points by
   bilinear interpolation; one atmosphere for all (the Mauna Loa preset, March, as
   notebooks/moonlit_sky/compare_ks91.py). K&S is evaluated with the instant's own phase angle
   and moon zenith angle and the V extinction k = 1.0857 tau(545 nm) of that atmosphere.
2. Full-moon illuminance on the ground at Zaragoza (rural continental, January), moon at 30,
   45 and 60 deg: the direct part from :func:`skymodel.render.night.moon_lamp` times sin(el),
   the diffuse part integrated over the rendered moonlit sky (cos-weighted).
3. Dark-sky zenith: a moonless night (2026-01-18 23:00 UTC, Zaragoza), the zenith of the
   rendered image (median of the top row, so no star counts) in V mag/arcsec^2 and ucd/m^2.
4. What the bounds drop: the sunlit sky at sun -12..-19 deg and the moonlit sky (full moon) at
   moon 0..-18 deg against the natural glow (rural, June, 550 nm, preview), and what the night's
   light would add to a sunlit sky at sun 0 deg.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from skymodel import scene
from skymodel.astro.moon import moon_position
from skymodel.astro.night_background import radiance_to_surface_brightness
from skymodel.colorimetry import K_M, cmf_weights
from skymodel.optics.atmosphere import Atmosphere, locations
from skymodel.render import night
from skymodel.render.cameras import make_camera
from skymodel.render.sequence import SolutionCache
from skymodel.render.sky import render_sky_reduced
from skymodel.render.skyview import Reduction
from skymodel.sun import solar_position
from skymodel.wavelengths import default_wavelengths

WL = default_wavelengths(5.0)
I545 = int(np.argmin(np.abs(WL - 545.0)))
V_COLUMN = np.eye(WL.size)[:, [I545]]  # the 545 nm radiance as the one channel
Y_COLUMN = cmf_weights(WL)[:, [1]]  # ybar-weighted radiance (x 683 = cd m^-2)
CAMERA = make_camera("equirectangular", 256, center_azimuth_deg=90.0)


def ks91_moon_nl(phase_deg, rho_deg, z_moon_deg, z_deg, k):
    """Krisciunas & Schaefer (1991) moonlight sky brightness, nanolamberts (eqs. 15-21)."""
    istar = 10 ** (-0.4 * (3.84 + 0.026 * abs(phase_deg) + 4e-9 * phase_deg**4))
    f = 10**5.36 * (1.06 + math.cos(math.radians(rho_deg)) ** 2) + 10 ** (6.15 - rho_deg / 40.0)

    def x(z):
        return (1 - 0.96 * math.sin(math.radians(z)) ** 2) ** -0.5

    return f * istar * 10 ** (-0.4 * k * x(z_moon_deg)) * (1 - 10 ** (-0.4 * k * x(z_deg)))


def v_from_nl(nl):
    return (20.7233 - math.log(nl / 34.08)) / 0.92104


def direction(el, az):
    el, az = math.radians(el), math.radians(az)
    return np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])


def sample(image, d):
    """Bilinear value of an equirectangular image (H, W, K) at direction d."""
    (x, y), _ = CAMERA.project(d)
    h, w = image.shape[:2]
    y = min(max(y, 0.0), h - 1.0)
    x0, y0 = int(math.floor(x)), int(math.floor(y))
    fx, fy = x - x0, y - y0
    y1 = min(y0 + 1, h - 1)
    a, b = image[y0, x0 % w], image[y0, (x0 + 1) % w]
    c, e = image[y1, x0 % w], image[y1, (x0 + 1) % w]
    return (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + e * fx) * fy


def moonlit(profile, moon, matrix, cache):
    red = Reduction(matrix, matrix.shape[1])
    img, _, _ = render_sky_reduced(night.moon_profile(profile, moon), CAMERA, float(moon.elevation_deg), red,
                                   red.n_channels, float(moon.azimuth_deg), 0.0, "preview", solutions=cache)
    return img


def find_instants(lat, lon, targets, start="2026-01-01", end="2026-07-01"):
    t = np.arange(np.datetime64(start + "T00:00"), np.datetime64(end + "T00:00"), np.timedelta64(10, "m"))
    mp = moon_position(lat, lon, t)
    sun_el = np.asarray(solar_position(lat, lon, np.datetime_as_string(t, unit="s")).elevation_deg)
    dark = sun_el < -18.0
    out = []
    for el, ph in targets:
        cost = ((mp.elevation_deg - el) / 1.0) ** 2 + ((mp.phase_angle_deg - ph) / 3.0) ** 2
        cost = np.where(dark, cost, np.inf)
        out.append(str(t[int(np.argmin(cost))]) + ":00Z")
    return out


def ks_table(cache):
    site = locations()["mauna_loa"]
    lat, lon = site["latitude"], site["longitude"]
    profile = Atmosphere(location="mauna_loa", month=3).optical_profile(WL)
    k = 1.0857 * float(profile.vertical_optical_depth(profile.extinction)[I545])
    targets = [(el, ph) for el in (30.0, 45.0, 60.0) for ph in (7.0, 45.0, 90.0)]
    print(f"### Moonlit sky against Krisciunas & Schaefer (1991)\n\nMauna Loa preset (March), k_V = {k:.3f} "
          "mag/airmass; preview quality; 256x128 equirectangular.\n")
    print("| instant (UTC) | moon el | phase | moon distance | sky point (el, az from moon) | rho | skymodel V | K&S V "
          "| ratio | ratio at 384400 km |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ratios, at_mean, full45 = [], [], None
    for (el_t, ph_t), t in zip(targets, find_instants(lat, lon, targets)):
        moon = moon_position(lat, lon, t)
        m_el, m_az, ph = float(moon.elevation_deg), float(moon.azimuth_deg), float(moon.phase_angle_deg)
        img = moonlit(profile, moon, V_COLUMN, cache)
        points = [(90.0, 0.0), (m_el + 15.0, 0.0), (45.0, 90.0), (45.0, 180.0), (20.0, 180.0), (60.0, 120.0)]
        for p_el, daz in points:
            d = direction(p_el, m_az + daz)
            rho = math.degrees(math.acos(float(np.clip(d @ direction(m_el, m_az), -1, 1))))
            v = float(radiance_to_surface_brightness(float(sample(img, d)[0]), "V"))
            ks = ks91_moon_nl(ph, rho, 90.0 - m_el, 90.0 - p_el, k)
            v_ks = v_from_nl(ks)
            r = 10 ** (-0.4 * (v - v_ks))
            ratios.append(r)
            at_mean.append(r * (float(moon.distance_km) / 384_400.0) ** 2)
            if p_el == 90.0 and ph_t == 7.0 and el_t == 45.0:
                full45 = (v, v_ks)
            print(f"| {t[:16]} | {m_el:.1f} | {ph:.1f} | {float(moon.distance_km):.0f} km | {p_el:.1f}, {daz:g} | "
                  f"{rho:.0f} | {v:.2f} | {v_ks:.2f} | {r:.2f} | {at_mean[-1]:.2f} |")
    for name, rr in (("", np.array(ratios)), (" with the moon moved to K&S's mean distance", np.array(at_mean))):
        print(f"\nRatio skymodel/K&S (radiance){name} over {rr.size} cases: median {np.median(rr):.2f}, range "
              f"{rr.min():.2f}-{rr.max():.2f}, rms of ln {np.sqrt(np.mean(np.log(rr) ** 2)):.2f} "
              "(K&S quote 8-23 % scatter of their fit).")
    if full45:
        print(f"Full moon near 45 deg, zenith: V {full45[0]:.2f} mag/arcsec^2 against K&S {full45[1]:.2f}.\n")


def illuminance_table(cache):
    lat, lon = locations()["zaragoza"]["latitude"], locations()["zaragoza"]["longitude"]
    profile = Atmosphere(location="zaragoza", month=1).optical_profile(WL)
    targets = [(30.0, 5.0), (45.0, 5.0), (60.0, 5.0)]
    print("### Full-moon illuminance on the ground\n\nZaragoza preset (January), preview quality.\n")
    print("| instant (UTC) | moon el | phase | direct (horizontal) | moonlit sky (diffuse) | total |")
    print("|---|---|---|---|---|---|")
    d, valid = CAMERA.directions()
    up = valid & (d[..., 2] > 0)
    omega = CAMERA.pixel_solid_angles()
    for t in find_instants(lat, lon, targets, "2025-10-01", "2026-10-01"):
        moon = moon_position(lat, lon, t)
        lamp = night.moon_lamp(profile, lat, lon, t)
        direct = lamp.illuminance_lux * math.sin(math.radians(lamp.elevation_deg))
        y = moonlit(profile, moon, Y_COLUMN, cache)[..., 0]
        diffuse = K_M * float(np.sum(np.where(up, y * d[..., 2] * omega, 0.0)))
        print(f"| {t[:16]} | {lamp.elevation_deg:.1f} | {lamp.phase_angle_deg:.1f} | {direct:.3f} lux | "
              f"{diffuse:.4f} lux | {direct + diffuse:.3f} lux |")
    print("\nPublished: 0.1-0.3 lux for a full moon high in a clear sky (Krisciunas & Schaefer 1991, "
          "Kyba et al. 2017).\n")


def dark_sky():
    lat, lon = locations()["zaragoza"]["latitude"], locations()["zaragoza"]["longitude"]
    profile = Atmosphere(location="zaragoza", month=1).optical_profile(WL)
    t = "2026-01-18T23:00:00Z"
    sun = scene.place_sun(lat, lon, t, allow_night=True)
    img, info = night.night_light(profile, CAMERA, lat, lon, t, np.hstack([V_COLUMN, Y_COLUMN]),
                                  sun_elevation_deg=sun.elevation_deg, quality="preview")
    top = np.median(img[0], axis=0)
    v = float(radiance_to_surface_brightness(float(top[0]), "V"))
    print("### Dark-sky zenith\n")
    print(f"Moonless night ({t}, sun {sun.elevation_deg:.0f} deg, moon {info.moon_elevation_deg:.0f} deg): zenith "
          f"V {v:.2f} mag/arcsec^2, luminance {K_M * float(top[1]) * 1e6:.0f} ucd/m^2; published: V 21.9 at a dark "
          "site (Benn & Ellison 1998, La Palma, solar minimum), 174 ucd/m^2 for the natural sky (Falchi et al. "
          "2016), 22.0 mag/arcsec^2 in V.\n")


def bounds():
    """How much of the sunlit sky is dropped at the sun's bound, and of the moonlit sky at the moon's."""
    from skymodel.astro.lunar_irradiance import lunar_irradiance
    from skymodel.astro.night_background import dark_sky_radiance
    from skymodel.render.marcher import SkyMarcher, solve_sky
    from skymodel.render.quality import quality_settings

    wl = default_wavelengths(20.0)
    i = int(np.argmin(np.abs(wl - 550.0)))
    prof = Atmosphere(location="rural", month=6).optical_profile(wl)
    sol = solve_sky(prof, quality_settings("preview"))
    cam = make_camera("equirectangular", 64)
    d, _ = cam.directions()
    up = d[..., 2] > 0
    zen = np.degrees(np.arccos(d[up][:, 2]))
    glow = dark_sky_radiance(wl, zen)[:, i]
    zi = int(np.argmin(zen))
    print("### What the bounds drop\n\nRural, June, preview, 550 nm, 64x32 sky pixels; the natural glow of "
          "skymodel.astro.night_background (V 21.9 at the zenith).\n")
    print("| source | elevation | at the zenith / glow | brightest sky pixel / glow | mean / glow |")
    print("|---|---|---|---|---|")
    for el in (-12.0, -15.0, -16.0, -17.0, -18.0, -19.0):
        L = SkyMarcher(prof, el, 180.0, 0.0, solution=sol).radiance(d[up]).radiance[:, i]
        print(f"| sun | {el:g} | {L[zi] / glow[zi]:.3g} | {(L / glow).max():.3g} | {(L / glow).mean():.3g} |")
    mprof = dataclasses.replace(prof, solar_irradiance=lunar_irradiance(wl, 7.0))
    for el in (0.0, -3.0, -6.0, -9.0, -12.0, -18.0):
        L = SkyMarcher(mprof, el, 180.0, 0.0, solution=sol).radiance(d[up]).radiance[:, i]
        print(f"| full moon (phase 7) | {el:g} | {L[zi] / glow[zi]:.3g} | {(L / glow).max():.3g} | "
              f"{(L / glow).mean():.3g} |")
    # the daytime: what the night's light would add to the sunlit sky at sun 0
    sky0 = SkyMarcher(prof, 0.0, 180.0, 0.0, solution=sol).radiance(d[up]).radiance[:, i]
    moon = SkyMarcher(mprof, 90.0, 180.0, 0.0, solution=sol).radiance(d[up]).radiance[:, i]
    print(f"\nSun at 0 deg: glow / sunlit sky at most {(glow / sky0).max():.2g}; a full moon at the zenith's sky / "
          f"sunlit sky at most {(moon / sky0).max():.2g}.\n")


def main():
    t0 = time.perf_counter()
    cache = SolutionCache(keep=2)
    ks_table(cache)
    illuminance_table(cache)
    dark_sky()
    bounds()
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
