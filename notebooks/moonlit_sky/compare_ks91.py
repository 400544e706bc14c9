"""Moonlit sky from skymodel's own radiative transfer against Krisciunas & Schaefer (1991).

    nice -n 10 python notebooks/moonlit_sky/compare_ks91.py      # about 40 s (3 solves, 3 wavelengths)

The sky is linear in its source, so the moonlit sky is the sky rendered with the sun at the
moon's place (skymodel.render.marcher.SkyMarcher, which accepts any elevation) times
E_moon(lambda) / E_sun(lambda), E_moon from skymodel.astro.lunar_irradiance (ROLO). Site:
the Mauna Loa preset (3397 m, AOD550 0.02), March; observer at the ground. K&S's model
(PASP 103, 1033, eqs. 15-21) is evaluated with the V extinction k = 1.0857 tau(545 nm) of the
same atmosphere, so the two differ only in how they scatter moonlight. Radiance at 545 nm is
turned into V mag/arcsec^2 (Bessell, Castelli & Plez 1998 zero point) and into nanolamberts
with K&S's B = 34.08 exp(20.7233 - 0.92104 V).
"""

from __future__ import annotations

import numpy as np

from skymodel import Atmosphere
from skymodel.astro.lunar_irradiance import lunar_irradiance
from skymodel.astro.night_background import radiance_to_surface_brightness
from skymodel.render.marcher import SkyMarcher

WL = np.array([440.0, 545.0, 640.0])
I545 = 1


def ks91_moon_nl(phase_deg, rho_deg, z_moon_deg, z_deg, k):
    """Krisciunas & Schaefer (1991) moonlight sky brightness, nanolamberts."""
    istar = 10 ** (-0.4 * (3.84 + 0.026 * abs(phase_deg) + 4e-9 * phase_deg**4))
    f = 10**5.36 * (1.06 + np.cos(np.radians(rho_deg)) ** 2) + 10 ** (6.15 - rho_deg / 40.0)

    def x(z):
        return (1 - 0.96 * np.sin(np.radians(z)) ** 2) ** -0.5

    return f * istar * 10 ** (-0.4 * k * x(z_moon_deg)) * (1 - 10 ** (-0.4 * k * x(z_deg)))


def nl_from_v(v):
    return 34.08 * np.exp(20.7233 - 0.92104 * v)


def direction(el, az):
    el, az = np.radians(el), np.radians(az)
    return np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])


def main():
    prof = Atmosphere(location="mauna_loa", month=3).optical_profile(WL)
    tau = prof.vertical_optical_depth(prof.extinction)
    k = 1.0857 * float(np.asarray(tau)[I545])
    print(f"Mauna Loa preset, March: tau(545) = {float(np.asarray(tau)[I545]):.4f}, k_V = {k:.3f} mag/airmass "
          "(K&S measured 0.172 at Mauna Kea)\n")
    print("| moon elevation | phase | sky point (el, az from moon) | rho | skymodel V | K&S V | ratio skymodel/K&S |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for moon_el in (30.0, 45.0, 60.0):
        m = SkyMarcher(prof, moon_el, 180.0)
        # the zenith, 15 degrees above the moon, and points across the sky (rho 30-130 degrees)
        points = [(90.0, 0.0), (moon_el + 15.0, 0.0), (45.0, 90.0), (45.0, 180.0), (20.0, 180.0), (60.0, 120.0)]
        dirs = np.array([direction(el, 180.0 + daz) for el, daz in points])
        sky = m.radiance(dirs).radiance  # (n, 3), W m^-2 sr^-1 nm^-1 per sun spectrum of the profile
        moon_dir = direction(moon_el, 180.0)
        for phase in (7.0, 45.0, 90.0):
            ratio_spec = lunar_irradiance(WL, phase) / prof.solar_irradiance
            moonlit = sky * ratio_spec
            for (el, daz), d, l in zip(points, dirs, moonlit):
                rho = float(np.degrees(np.arccos(np.clip(d @ moon_dir, -1, 1))))
                v = float(radiance_to_surface_brightness(l[I545], "V"))
                ks = ks91_moon_nl(phase, rho, 90.0 - moon_el, 90.0 - el, k)
                v_ks = (20.7233 - np.log(ks / 34.08)) / 0.92104
                r = nl_from_v(v) / ks
                ratios.append(r)
                print(f"| {moon_el:g} | {phase:g} | {el:g}, {daz:g} | {rho:.0f} | {v:.2f} | {v_ks:.2f} | {r:.2f} |")
    ratios = np.array(ratios)
    print(f"\nratio skymodel/K&S over {ratios.size} cases: median {np.median(ratios):.2f}, "
          f"range {ratios.min():.2f}-{ratios.max():.2f}; rms of ln(ratio) {np.sqrt(np.mean(np.log(ratios) ** 2)):.2f}")


if __name__ == "__main__":
    main()
