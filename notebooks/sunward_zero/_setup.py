"""What the sunward_zero scripts share: a truth scene of benchmarks/bench_truth.py, its marcher
profile, `final`'s marcher with every direction exact, the truth and the saved `base` march, a view
by name and the sun's local frame.

The study ran with the 12-degree cone on every sky (revision 7c6307f); since 650375c rural haze
takes 6 degrees (skymodel.render.medium.delta_m_cone_deg). The scripts keep the study's cone:
MILD_CONE=6 gives today's."""
import os
import sys
from dataclasses import replace

import numpy as np

sys.path[:0] = ["benchmarks"]
import bench_truth as bt  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402
from skymodel.render.quality import QUALITIES  # noqa: E402

TRUTH_CACHE = os.environ.get("TRUTH_CACHE", ".cache/truth")
OUT = os.environ.get("TRUTH_MISSES_OUT", ".cache/truth_misses")


def settings(**changes):
    """`final` with every direction exact and the study's cone (module docstring)."""
    return replace(QUALITIES["final"].settings, exact=True,
                   delta_m_mild_cutoff_deg=float(os.environ.get("MILD_CONE", "0")), **changes)


def scene(name):
    """'rural:0' -> (the bench_truth Scene, its marcher profile, wavelengths (nm), indices of the
    truth's 450/550/650 nm in them)."""
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), TRUTH_CACHE)
    prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
    wl = np.asarray(prof.wavelengths_nm)
    return sc, prof, wl, [int(np.argmin(np.abs(wl - w))) for w in bt.MC_WAVELENGTHS_NM]


def marcher(sc, prof, **changes):
    return SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, settings(**changes))


def truth_and_base(sc):
    """The truth per unit solar irradiance (views, 3), its standard error, and the saved `base`
    variant (notebooks/peak_multi/set_constants.py <scene> base "")."""
    prof_mc, mc = sc.load_mc()
    e0 = np.asarray(prof_mc.solar_irradiance)[None, :]
    return mc["mean"] / e0, mc["se"] / e0, np.load(f"{OUT}/var_{sc.name}_base.npz")["r"]


def view(sc, name):
    """'89/4.899' -> (its index in the scene's view set, its unit direction)."""
    i = sc.view_rows([name])[0]
    return i, sc.dirs[i] / np.linalg.norm(sc.dirs[i])


def sun_frame(m):
    """The observer's horizontal unit vectors toward the sun's azimuth and 90 degrees from it,
    the zenith, and vec(elevation_deg, azimuth_from_sun_deg) -> unit directions (..., 3)."""
    sun = m.sun / np.linalg.norm(m.sun)
    up = np.array([0.0, 0.0, 1.0])
    hor = sun - sun[2] * up
    hor /= np.linalg.norm(hor)
    side = np.cross(up, hor)

    def vec(el, az):
        el, az = np.radians(el), np.radians(az)
        return ((np.cos(el) * np.cos(az))[..., None] * hor + (np.cos(el) * np.sin(az))[..., None] * side
                + np.sin(el)[..., None] * up)

    return hor, side, up, vec


def rel(x):
    return "/".join(f"{100 * v:+.2f}" for v in x)
