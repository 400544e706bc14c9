"""The figures of docs/night.md: skymodel.astro against its independent sources.

    python benchmarks/astro_figures.py            # about 10 s; needs ephem, skyfield, skyfield-data

Prints, as Markdown tables: the moon's place against JPL DE421 (skyfield) and PyEphem over
random places and times 1950-2050, the stars' places against skyfield for the whole
catalogue, the ROLO moon's V magnitude against the Allen phase law, full-moon figures, the
dark-sky background, and the time of each step.
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from skymodel.astro import lunar_irradiance as li
from skymodel.astro import moon, night_background, stars
from skymodel.colorimetry import K_M, cmf_weights
from skymodel.sun import solar_irradiance
from skymodel.wavelengths import default_wavelengths


def _sep(el1, az1, el2, az2):
    a1, z1, a2, z2 = map(np.radians, (el1, az1, el2, az2))
    c = np.sin(a1) * np.sin(a2) + np.cos(a1) * np.cos(a2) * np.cos(z1 - z2)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def moon_table(n=300, seed=7):
    import ephem
    import skyfield_data
    from skyfield.api import Loader, load, wgs84

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eph = Loader(skyfield_data.get_skyfield_data_path(), verbose=False)("de421.bsp")
    ts = load.timescale(builtin=True)
    rng = np.random.default_rng(seed)
    lat, lon = rng.uniform(-85, 85, n), rng.uniform(-180, 180, n)
    t = np.datetime64("1950-01-01T00:00:00", "us") + (rng.uniform(0, 99.9 * 365.25 * 86400, n) * 1e6).astype("timedelta64[us]")
    t0 = time.perf_counter()
    mp = moon.moon_position(lat, lon, t)
    dt = time.perf_counter() - t0
    s_de, s_ep, dd, df = [], [], [], []
    for i in range(n):
        d = t[i].astype(object)
        tt = ts.ut1(d.year, d.month, d.day, d.hour, d.minute, d.second + d.microsecond * 1e-6)
        app = (eph["earth"] + wgs84.latlon(lat[i], lon[i])).at(tt).observe(eph["moon"]).apparent()
        alt, az, dist = app.altaz()
        s_de.append(_sep(alt.degrees, az.degrees, mp.true_elevation_deg[i], mp.azimuth_deg[i]))
        dd.append(abs(dist.km - mp.distance_km[i]))
        df.append(abs(app.fraction_illuminated(eph["sun"]) - mp.illuminated_fraction[i]))
        o = ephem.Observer()
        o.lat, o.lon, o.elevation, o.pressure = str(lat[i]), str(lon[i]), 0.0, 0.0
        o.date = ephem.Date(d)
        m = ephem.Moon(o)
        s_ep.append(_sep(math.degrees(m.alt), math.degrees(m.az), mp.true_elevation_deg[i], mp.azimuth_deg[i]))
    s_de, s_ep = np.array(s_de), np.array(s_ep)
    print(f"### Moon: {n} random places and times 1950-2050 (seed {seed}); {dt * 1e3:.1f} ms for all {n}\n")
    print("| against | median (deg) | 99th pct (deg) | max (deg) | distance max (km) | lit fraction max |")
    print("|---|---|---|---|---|---|")
    print(f"| JPL DE421 (skyfield 1.55) | {np.median(s_de):.4f} | {np.percentile(s_de, 99):.4f} | {s_de.max():.4f} | {max(dd):.0f} | {max(df):.1e} |")
    print(f"| PyEphem 4.2.1 | {np.median(s_ep):.4f} | {np.percentile(s_ep, 99):.4f} | {s_ep.max():.4f} | | |\n")


def star_table():
    import skyfield_data
    from skyfield.api import Loader, Star, load, wgs84

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eph = Loader(skyfield_data.get_skyfield_data_path(), verbose=False)("de421.bsp")
    ts = load.timescale(builtin=True)
    cat = stars.catalogue()
    print(f"### Stars: all {len(cat)} catalogue stars against skyfield (same J2000 places)\n")
    print("| time (UT1) | place | max (deg) | median (deg) | star_positions (ms) |")
    print("|---|---|---|---|---|")
    for when, lat, lon in [("1960-08-15T03:00:00", -33.9, 18.4), ("2026-03-01T22:00:00", 48.0, 11.0),
                           ("2049-12-31T12:00:00", 70.0, -150.0)]:
        t0 = time.perf_counter()
        sp = stars.star_positions(lat, lon, when)
        dt = time.perf_counter() - t0
        d = np.datetime64(when).astype(object)
        tt = ts.ut1(d.year, d.month, d.day, d.hour, d.minute, d.second)
        app = (eph["earth"] + wgs84.latlon(lat, lon)).at(tt).observe(
            Star(ra_hours=cat.ra_deg / 15.0, dec_degrees=cat.dec_deg)).apparent()
        alt, az, _ = app.altaz()
        s = _sep(alt.degrees, az.degrees, sp.elevation_deg, sp.azimuth_deg)
        print(f"| {when} | {lat}, {lon} | {s.max():.5f} | {np.median(s):.5f} | {dt * 1e3:.1f} |")
    print()


def moonlight_table(wl):
    g = np.array([0.0, 2.0, 5.0, 7.0, 10.0, 30.0, 60.0, 90.0, 120.0, 150.0, 170.0])
    e = li.lunar_irradiance(wl, g)
    v = li.v_magnitude(e, wl)
    vw = li.v_magnitude(li.lunar_irradiance(wl, g, sun_selenographic_longitude_deg=-g), wl)
    lux = li.illuminance_lux(e, wl)
    i545 = int(np.searchsorted(wl, 545.0))
    ratio = e[:, i545] / solar_irradiance(wl)[i545]
    print("### Moonlight above the atmosphere (mean distances)\n")
    print("| phase angle (deg) | V waxing | V waning | Allen law V | illuminance (lux) | E_moon/E_sun at 545 nm |")
    print("|---|---|---|---|---|---|")
    for k in range(g.size):
        print(f"| {g[k]:g} | {v[k]:.2f} | {vw[k]:.2f} | {li.allen_phase_law_v_mag(g[k]):.2f} | {lux[k]:.4f} | {ratio[k]:.2e} |")
    a = li.lunar_reflectance(wl, 7.0)
    print(f"\nReflectance at 7 degrees: {a[0]:.3f} at {wl[0]:g} nm, {a[np.searchsorted(wl, 550)]:.3f} at 550 nm, "
          f"{a[-1]:.3f} at {wl[-1]:g} nm.\n")


def background_table(wl):
    l0 = night_background.dark_sky_zenith_radiance(wl)
    lum = K_M * l0 @ cmf_weights(wl)[:, 1]
    z = np.array([0.0, 30.0, 60.0, 80.0, 90.0])
    v = night_background.radiance_to_surface_brightness(
        night_background.dark_sky_radiance(wl, z)[:, int(np.searchsorted(wl, 545.0))], "V")
    print("### Dark-sky background (Benn & Ellison 1998 zenith, Krisciunas & Schaefer 1991 zenith-angle law)\n")
    print(f"Zenith: V 21.9 mag/arcsec^2 = {night_background.surface_brightness_to_radiance(21.9):.3e} "
          f"W m^-2 sr^-1 nm^-1 at 545 nm; luminance {lum * 1e6:.0f} ucd/m^2.\n")
    print("| zenith angle (deg) | " + " | ".join(f"{x:g}" for x in z) + " |")
    print("|---|" + "---|" * z.size)
    print("| V (mag/arcsec^2) | " + " | ".join(f"{x:.2f}" for x in v) + " |\n")


def main():
    wl = default_wavelengths()
    moon_table()
    star_table()
    moonlight_table(wl)
    background_table(wl)
    h = 256
    t0 = time.perf_counter()
    sp = stars.star_positions(40.0, -3.7, "2026-06-21T23:00:00")
    e = stars.star_irradiance(wl)
    img = stars.splat_stars(np.zeros((h, 2 * h, wl.size)), sp.elevation_deg, sp.azimuth_deg, e)
    dt = time.perf_counter() - t0
    print(f"Whole catalogue placed, given spectra (81 wavelengths) and splatted into a {2 * h}x{h} "
          f"image: {dt * 1e3:.0f} ms ({int((sp.elevation_deg >= 0).sum())} stars above the horizon; "
          f"image max {img.max():.2e} W m^-2 sr^-1 nm^-1).")


if __name__ == "__main__":
    main()
