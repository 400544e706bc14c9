"""Shared by the scripts here: the views they compare on, a solution cut down to some of its solver
wavelengths, and the linear map they compare against."""
from dataclasses import replace

import numpy as np

from skymodel.render.marcher import profile_at_wavelengths
from skymodel.render.medium import factor_medium
from skymodel.render.rays import sun_direction
from skymodel.validation.truth import EXCLUDE_DEG, angle_to_sun_deg, view_directions


def scene_views(sc, sun_azimuth_deg):
    """(views, dirs, keep) of a bench_truth ``Scene``: its own views and a grid (zenith 0-89.5 deg,
    azimuth from the sun 0-180 deg every 10), as (zenith, azimuth) rows and unit vectors, and which
    of them lie outside the sun's disc and the aureole's first 2 deg (truth.EXCLUDE_DEG)."""
    Z, A = np.meshgrid(np.r_[np.arange(0, 85, 5.0), 86, 87, 88, 89, 89.5], np.arange(0, 181, 10.0), indexing="ij")
    grid = np.stack([Z.ravel(), A.ravel()], -1)
    dirs = np.concatenate([sc.dirs, view_directions(grid, sun_azimuth_deg)])
    keep = angle_to_sun_deg(dirs, sun_direction(sc.elev, sun_azimuth_deg)) > EXCLUDE_DEG
    return np.concatenate([sc.views, grid]), dirs, keep


def every_wavelength_scene(name, wavelengths_nm):
    """bench_truth's scene ``name`` ("rural:-4", its views and grid by :func:`scene_views`) on
    ``wavelengths_nm``, with `final`'s settings solving at every one of them: (scene, profile,
    views, dirs, keep, settings). The scripts importing this put benchmarks/ on sys.path first."""
    import bench_truth as bt
    from skymodel.render.quality import QUALITIES

    a, e = name.split(":")
    sc = bt.Scene(a, float(e), "/nonexistent")
    prof = sc.atm.optical_profile(list(wavelengths_nm))
    views, dirs, keep = scene_views(sc, bt.SUN_AZIMUTH)
    s = replace(QUALITIES["final"].settings, ms_wavelength_step_nm=5.0, ms_wavelength_outer_step_nm=0.0)
    return sc, prof, views, dirs, keep, s


def sub_solution(sol, profile, idx, to_full):
    """``sol`` (a SkySolution solved at every wavelength of ``profile``) keeping only the solver
    wavelengths ``idx``, carried to the profile's by ``to_full`` (any callable on (..., n_idx))."""
    f = sol.field
    w = f.wavelengths_nm[idx]
    sc = None if f.scattering is None else replace(f.scattering, weights=f.scattering.weights[:, idx])
    field = replace(f, wavelengths_nm=w, source=np.ascontiguousarray(f.source[idx]),
                    ground_diffuse_irradiance=f.ground_diffuse_irradiance[:, idx], scattering=sc)
    pm = replace(profile_at_wavelengths(profile, w), solar_irradiance=np.ones_like(w))
    return replace(sol, medium_ms=factor_medium(pm, sol.medium.cutoff_deg), field=field, to_full=to_full)


class LinearMap:
    """Spectra carried by a plain matrix (the linear reading before the log-ozone map), called
    as the marcher calls its ``to_full``."""

    def __init__(self, matrix):
        self.matrix = matrix

    def __call__(self, values):
        return np.asarray(values) @ self.matrix
