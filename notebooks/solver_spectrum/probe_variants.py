"""Readings of the spherical correction's factor between its probe wavelengths, end to end.

Each run solves `final` with the factor computed at every solver wavelength (10 nm), then hands
the solver a candidate read from the probe rows only (380, 480, ..., 780 nm, as `final` picks them);
the sky on bench_truth's views and a grid (render grid 5 nm) is compared with the exact one.

Candidates (every one but `linear` on ln factor; a node with a factor <= 0 at any probe is read
linearly): `linear`, `loglin` (ln factor linear in the wavelength), `map` (SolverSpectrumMap, the
log-ozone model: what the solver does now), and least-squares fits over the five probes of
ln factor on 1 and optical depths, the residuals at the two bracketing probes added linearly:
`tauR` (Rayleigh), `tauT` (total), `tauTO` (total, ozone), `tauRA` (Rayleigh, aerosol), `tauROA`.
``--bounded``: every candidate clipped to [0.8 x, 1.25 x] the probes' range at its node and read
linearly where that range leaves [0.05, 20].

    python notebooks/solver_spectrum/probe_variants.py rural:-4,desert:-4 linear,loglin,map,tauR
"""
import sys, time; sys.path[:0] = [str(__import__("pathlib").Path(__file__).resolve().parents[2] / "benchmarks")]
import numpy as np, bench_truth as bt
from _setup import scene_views
from dataclasses import replace
import skymodel.render.multiple_scattering as ms
from skymodel.numerics import linear_interp_matrix
from skymodel.render.marcher import SkyMarcher, settings_solver_wavelengths
from skymodel.render.quality import QUALITIES
from skymodel.render.solver_spectrum import SolverSpectrumMap
from skymodel.wavelengths import default_wavelengths, spread_indices
from skymodel.colorimetry import cmf_weights

TERMS = {"tauR": "R", "tauT": "T", "tauTO": "TO", "tauRA": "RA", "tauROA": "ROA"}
BOUNDED = "--bounded" in sys.argv
args = [a for a in sys.argv[1:] if a != "--bounded"]
wl = default_wavelengths(5.0); cmf = cmf_weights(wl)
exact_correction = ms._SphericalTransport.correction
CTX = {"mode": "exact"}


def fit_weights(depths):
    """(P, W) weights on ln factor at the probes: least squares on [1, depths...] over every
    probe, the residuals at the bracketing probes added linearly (exact at the probes)."""
    tp = np.stack([np.ones(CTX["idx"].size)] + [CTX["tau"][k][CTX["idx"]] for k in depths], -1)
    ta = np.stack([np.ones(CTX["wl"].size)] + [CTX["tau"][k] for k in depths], -1)
    scale = np.abs(tp).max(0)
    tp, ta = tp / scale, ta / scale
    p = np.linalg.pinv(tp, rcond=1e-6)
    return (ta @ p).T + (np.eye(tp.shape[0]) - tp @ p).T @ CTX["lin"]


def candidate(mode, r):
    """The factor (W, ...) from its probe rows ``r`` (P, ...)."""
    lin = CTX["lin"].astype(np.float32)
    linear = np.einsum("p...,pw->w...", r, lin)
    if mode == "linear":
        return linear
    W = {"loglin": CTX["lin"], "map": CTX["map"]}.get(mode)
    W = fit_weights(TERMS[mode]) if W is None else W
    positive = np.all(r > 0, axis=0)
    out = np.exp(np.clip(np.einsum("p...,pw->w...", np.log(np.where(r > 0, r, 1.0)), W.astype(np.float32)), -80, 80))
    if BOUNDED:
        lo, hi = r.min(0), r.max(0)
        positive &= (lo > 0.05) & (hi < 20)
        out = np.clip(out, 0.8 * lo, 1.25 * hi)
    return np.where(positive[None], out, linear)


def patched(self, j_dir, lg, column_dir):
    f = exact_correction(self, j_dir, lg, column_dir)  # at every solver wavelength (probe step 10)
    if CTX["mode"] == "exact" or f.shape[-1] == 0:
        return f
    return candidate(CTX["mode"], np.ascontiguousarray(f[CTX["idx"]]))


ms._SphericalTransport.correction = patched
modes = args[1].split(",") if len(args) > 1 else ["linear", "loglin", "map", "tauR", "tauT", "tauTO", "tauRA", "tauROA"]
for name in args[0].split(","):
    a, e = name.split(":"); sc = bt.Scene(a, float(e), "/nonexistent"); prof = sc.atm.optical_profile(list(wl))
    views, dirs, keep = scene_views(sc, bt.SUN_AZIMUTH)
    s = replace(QUALITIES["final"].settings, spherical_probe_step_nm=10.0)
    ws = settings_solver_wavelengths(wl, s)
    idx = spread_indices(ws, QUALITIES["final"].settings.spherical_probe_step_nm)
    pw = sc.atm.optical_profile(list(ws))
    tau = {"R": pw.vertical_optical_depth(pw.rayleigh_scattering), "O": pw.vertical_optical_depth(pw.ozone_absorption),
           "A": pw.vertical_optical_depth(pw.aerosol_scattering + pw.aerosol_absorption)}
    tau["T"] = tau["R"] + tau["O"] + tau["A"]
    CTX.update(wl=ws, idx=idx, tau=tau, lin=linear_interp_matrix(ws[idx], ws),
               map=SolverSpectrumMap(ws[idx], ws, tau["O"]).log)
    out = {}
    for mode in ["exact"] + modes:
        CTX["mode"] = mode
        t = time.perf_counter()
        try:
            out[mode] = SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s).radiance(dirs).radiance
        except FloatingPointError as err:
            print(f"  {name} {mode:7s}: {err}", flush=True); continue
        if mode == "exact":
            print(f"{name}: exact {time.perf_counter() - t:.1f} s, probes {ws[idx]} nm", flush=True); continue
        rel = out[mode][keep] / out["exact"][keep] - 1
        i, j = np.unravel_index(np.abs(rel).argmax(), rel.shape)
        xyz = np.abs((out[mode] @ cmf)[keep] / (out["exact"] @ cmf)[keep] - 1).max(0) * 100
        print(f"  {name} {mode:7s}: median {np.median(np.abs(rel)) * 100:.3f} %, worst {rel[i, j] * 100:+.3f} % "
              f"({wl[j]:.0f} nm, {views[keep][i]}); XYZ max {np.round(xyz, 3)}", flush=True)
