"""What the scripts of this folder share: peak_paths' constants from the command line, the bent
beam in the solver too (env SOLVER=1), and the medium with the dust scattering only into its cut peak."""
import os

import numpy as np

import skymodel.render.marcher as mm
import skymodel.render.peak_paths as pp
from skymodel.numerics import linear_interp_matrix
from skymodel.render.aureole import peak_part
from skymodel.render.medium import truncate_forward_peak
from skymodel.render.quality import QUALITIES


def set_constants(items):
    """NAME=VALUE items: module constants of skymodel.render.peak_paths (their own types)."""
    for kv in items:
        k, v = kv.split("=")
        setattr(pp, k, type(getattr(pp, k))(float(v)))


def beam_in_solver_if_asked():
    """With env SOLVER=1 the bent beam's columns go into the sun table's medium 1 too (the
    solver's delta-M beam: its first order and so every later one), not only medium 2."""
    if not os.environ.get("SOLVER"):
        return

    def add_both(sun_table, profile, medium, cutoff_deg, which=2):
        probes, corr = pp.bent_beam_depth(sun_table, profile, medium, cutoff_deg, scaled_medium=2)
        if np.any(corr):
            sun_table.add_depth_columns(2, corr, linear_interp_matrix(probes, profile.wavelengths_nm))
            wl_ms = mm.settings_solver_wavelengths(profile.wavelengths_nm, QUALITIES["final"].settings)
            sun_table.add_depth_columns(1, corr, linear_interp_matrix(probes, wl_ms))

    mm.add_peak_paths = add_both


def dust_peak_only(p, cone_deg=12.0):
    """The profile with its first aerosol regime (the dust) scattering only into its forward
    peak cut at ``cone_deg`` (the peak renormalised, scattering x f) and the other regimes
    removed (x 1e-6); Rayleigh and ozone as they are."""
    f, _ = truncate_forward_peak(p.aerosol_phase_angles_deg, p.aerosol_phase, cone_deg)
    ph = p.aerosol_phase.copy()
    ph[0] = peak_part(p.aerosol_phase_angles_deg, p.aerosol_phase, cone_deg)[0] / f[0][None, :]
    s = p.aerosol_scattering_by_regime.copy()
    s[0] *= f[0][None, :]
    s[1:] *= 1e-6
    return p.with_(aerosol_phase=ph, aerosol_scattering_by_regime=s)
