"""``skymodel profile``: per-wavelength optical depths of an atmosphere (and its layers)."""

from __future__ import annotations

import json
import sys

import numpy as np

from skymodel import scene
from skymodel.cli.options import (add_atmosphere_arguments, add_option, add_wavelengths_argument,
                                  atmosphere_from_args, wavelengths_from_args)


def add_command(sub) -> None:
    """Register ``skymodel profile`` on the CLI's subparsers."""
    p = sub.add_parser("profile", help="per-wavelength optical depths of an atmosphere")
    add_atmosphere_arguments(p)
    add_wavelengths_argument(p)
    add_option(p, "layers", note="also print N piecewise-constant layers")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_profile)


def profile_summary(profile, layers: int | None = None) -> dict:
    """Column quantities per wavelength (and the layered atmosphere when ``layers``)."""
    p = profile
    tau_r = p.vertical_optical_depth(p.rayleigh_scattering)
    tau_o = p.vertical_optical_depth(p.ozone_absorption)
    sca = p.vertical_optical_depth(p.aerosol_scattering)
    ext = sca + p.vertical_optical_depth(p.aerosol_absorption)
    with np.errstate(invalid="ignore", divide="ignore"):
        ssa = np.where(ext > 0, sca / np.where(ext > 0, ext, 1.0), 1.0)
        mu = np.cos(np.radians(p.aerosol_phase_angles_deg))
        # asymmetry of the column-mean aerosol phase function (scattering-weighted regimes)
        w = np.stack([p.vertical_optical_depth(a) for a in p.aerosol_scattering_by_regime])  # (R, W)
        phase = (w[:, None, :] * p.aerosol_phase).sum(0) / np.where(w.sum(0) > 0, w.sum(0), 1.0)
        from skymodel.numerics import trapezoid

        g = -2 * np.pi * trapezoid(phase * mu[:, None], mu, axis=0)
    out = {
        "atmosphere": {k: v for k, v in p.metadata.items()},
        "wavelengths_nm": p.wavelengths_nm.tolist(),
        "rayleigh_optical_depth": tau_r.tolist(),
        "ozone_optical_depth": tau_o.tolist(),
        "aerosol_optical_depth": ext.tolist(),
        "aerosol_single_scattering_albedo": ssa.tolist(),
        "aerosol_asymmetry": g.tolist(),
        "ozone_column_du": p.metadata["ozone_du"],
        "angstrom_exponent": p.metadata["angstrom_exponent"],
        "solar_irradiance_W_m2_nm": p.solar_irradiance.tolist(),
    }
    if layers:
        lay = p.layered(n_layers=layers)
        dz = np.diff(lay.edges_m)[:, None]
        a_sca = lay.aerosol_scattering * dz
        a_ext = a_sca + lay.aerosol_absorption * dz
        with np.errstate(invalid="ignore", divide="ignore"):
            lay_ssa = np.where(a_ext > 0, a_sca / np.where(a_ext > 0, a_ext, 1.0), 1.0)
            wr = lay.aerosol_scattering_by_regime  # (R, L, W)
            lay_phase = (wr[:, :, None, :] * lay.aerosol_phase[:, None, :, :]).sum(0) / np.where(
                wr.sum(0) > 0, wr.sum(0), 1.0)[:, None, :]
        out["layers"] = {
            "edges_m": lay.edges_m.tolist(),
            "rayleigh_optical_depth": (lay.rayleigh_scattering * dz).tolist(),
            "ozone_optical_depth": (lay.ozone_absorption * dz).tolist(),
            "aerosol_optical_depth": a_ext.tolist(),
            "aerosol_single_scattering_albedo": lay_ssa.tolist(),
            "aerosol_phase_angles_deg": lay.aerosol_phase_angles_deg.tolist(),
            "aerosol_phase_function_sr-1": lay_phase.tolist(),
            "shape_note": "per-layer arrays are [layer][wavelength]; phase is [layer][angle][wavelength]",
        }
    return out


def _print_profile_table(s: dict) -> None:
    a = s["atmosphere"]
    print(f"location {a['location']}  lat {a['latitude_deg']:.2f}  lon {a['longitude_deg']:.2f}  month {a['month']}")
    print(f"aerosol {a['aerosol']} ({a['aerosol_model']} model; stratospheric {a['stratospheric']})  "
          f"site {a['site_altitude_m']:.0f} m  AOD550 {a['aod550']:.4f}  "
          f"Angstrom {a['angstrom_exponent']:.3f}  ozone {a['ozone_du']:.1f} DU  albedo {a['albedo']:.2f}")
    print(f"{'nm':>6} {'tau_R':>9} {'tau_O3':>9} {'tau_aer':>9} {'ssa':>6} {'g':>6}")
    for i, wl in enumerate(s["wavelengths_nm"]):
        print(f"{wl:6.1f} {s['rayleigh_optical_depth'][i]:9.5f} {s['ozone_optical_depth'][i]:9.5f} "
              f"{s['aerosol_optical_depth'][i]:9.5f} {s['aerosol_single_scattering_albedo'][i]:6.3f} "
              f"{s['aerosol_asymmetry'][i]:6.3f}")
    if "layers" in s:
        print("layers (edges in km):", ", ".join(f"{e / 1000:.2f}" for e in s["layers"]["edges_m"]))


def _in_order(summary: dict, back) -> dict:
    """The per-wavelength arrays of :func:`profile_summary` put in the order ``back``
    (the wavelengths' last axis everywhere)."""
    n = len(summary["wavelengths_nm"])

    def reorder(v):
        a = np.asarray(v)
        return a[..., back].tolist() if a.ndim and a.shape[-1] == n else v

    out = {k: (reorder(v) if isinstance(v, list) else v) for k, v in summary.items()}
    if "layers" in out:
        out["layers"] = {k: (v if k in ("edges_m", "aerosol_phase_angles_deg") or not isinstance(v, list)
                             else reorder(v)) for k, v in out["layers"].items()}
    return out


def cmd_profile(args) -> int:
    layers = scene.check("layers", args.layers)
    wl, back = wavelengths_from_args(args)  # computed on an ascending grid, answered in the user's order
    atm = atmosphere_from_args(args)
    prof = atm.optical_profile(wl)
    s = _in_order(profile_summary(prof, layers), back)
    if args.json:
        json.dump(s, sys.stdout, indent=1)
        print()
    else:
        _print_profile_table(s)
    return 0
