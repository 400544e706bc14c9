"""The interpolation models tried for the solver's spectra (notebooks/solver_spectrum/README.md), each
against a solve at every 5-nm render wavelength.

    python notebooks/solver_spectrum/variants.py desert:0,rural:-4,rural:20 2,4,8

The second argument: solver wavelengths every k-th render wavelength (2: 10 nm, 4: 20 nm, 8: 40 nm).
Models, in ln S over a stencil of solver wavelengths (least squares, residuals at the interval's ends
added linearly): terms 1, x (wavelength), q (x^2), t (ozone optical depth), L (ln wavelength), Q
(L^2); the number is the stencil."""
import sys, time
from dataclasses import replace
import numpy as np
sys.path[:0] = [str(__import__("pathlib").Path(__file__).resolve().parents[2] / "benchmarks")]
import bench_truth as bt
from _setup import LinearMap, scene_views, sub_solution
from skymodel.render.marcher import SkyMarcher, solve_sky
from skymodel.render.quality import QUALITIES
from skymodel.numerics import linear_interp_matrix
from skymodel.wavelengths import default_wavelengths
from skymodel.colorimetry import cmf_weights


def log_weights(src, dst, tau, basis="1xt", width=4):
    """(n_src, n_dst) weights on log values; exact at the nodes."""
    n = src.size
    W = np.zeros((n, dst.size))
    ts = np.interp(src, dst, tau) if tau is not None else None
    scale = max(np.ptp(tau), 1e-30) if tau is not None else 1.0
    for j, lam in enumerate(dst):
        i = int(np.clip(np.searchsorted(src, lam, side="right") - 1, 0, n - 2))
        f = (lam - src[i]) / (src[i + 1] - src[i])
        lin = np.zeros(n); lin[i] = 1 - f; lin[i + 1] = f
        if basis == "log":
            W[:, j] = lin; continue
        lo = i - (width // 2 - 1)
        S = np.arange(max(0, lo), min(n, lo + width))
        h = src[i + 1] - src[i]
        def phi(l, t):
            x = (l - src[i]) / h
            L = np.log(l / src[i]) / np.log(src[i + 1] / src[i])
            cols = {"1": np.ones_like(x), "x": x, "q": x * x, "t": t / scale, "L": L, "Q": L * L}
            return np.stack([cols[c] for c in basis], -1)
        Phi = phi(src[S], ts[S])
        P = np.linalg.pinv(Phi, rcond=1e-6)
        w_model = phi(np.array([lam]), np.array([tau[j]]))[0] @ P  # over S
        resid = np.eye(S.size) - Phi @ P
        li = np.array([lin[k] for k in S])
        w = w_model + li @ resid
        W[S, j] = w
    return W


class LogInterp:
    def __init__(self, W, Wlin):
        self.W, self.Wlin = W, Wlin
    def __call__(self, x):
        x = np.asarray(x)
        pos = np.all(x > 0, axis=-1, keepdims=True)
        lx = np.log(np.where(x > 0, x, 1.0))
        return np.where(pos, np.exp(lx @ self.W), x @ self.Wlin)




wl = default_wavelengths(5.0)
KS = [int(v) for v in sys.argv[2].split(",")] if len(sys.argv) > 2 else [2, 4]
for name in sys.argv[1].split(","):
    a, e = name.split(":")
    sc = bt.Scene(a, float(e), "/nonexistent")
    prof = sc.atm.optical_profile(list(wl))
    tau_o3 = prof.vertical_optical_depth(prof.ozone_absorption)
    VIEWS, dirs, keep = scene_views(sc, bt.SUN_AZIMUTH)
    s = replace(QUALITIES["final"].settings, ms_wavelength_step_nm=5.0, ms_wavelength_outer_step_nm=0.0)
    t = time.perf_counter(); sol = solve_sky(prof, s); ts = time.perf_counter() - t
    print(f"{name}: solve {ts:.1f} s", flush=True)
    def render(solution):
        return SkyMarcher(prof, sc.elev, bt.SUN_AZIMUTH, 0.0, s, solution=solution).radiance(dirs).radiance
    full = render(sol)
    cmf = cmf_weights(wl)
    Yf = full @ cmf
    for k in KS:
        idx = np.arange(0, wl.size, k)
        src = wl[idx]
        Wl = linear_interp_matrix(src, wl)
        variants = {"lin": LinearMap(Wl)}
        for b, wd in (("log", 4), ("1t", 4), ("1xt", 4), ("1xqt", 4), ("1Lt", 4), ("1Lt", 6), ("1LQt", 6),
                      ("1LQt", 8)):
            variants[f"{b}{wd}"] = LogInterp(log_weights(src, wl, tau_o3, b, wd), Wl)
        for vn, W in variants.items():
            r = render(sub_solution(sol, prof, idx, W))
            rel = r[keep] / full[keep] - 1
            relY = (r @ cmf)[keep] / Yf[keep] - 1
            print(f"  {5*k}nm {vn:6s} spectral |rel| median {np.median(np.abs(rel))*100:.3f} % max {np.abs(rel).max()*100:.2f} % "
                  f"(at {wl[np.unravel_index(np.abs(rel).argmax(), rel.shape)[1]]:.0f} nm, dir {np.round(VIEWS[keep][np.unravel_index(np.abs(rel).argmax(), rel.shape)[0]],1)}) XYZ median "
                  + "/".join(f"{v:.3f}" for v in np.median(np.abs(relY), 0) * 100) + " max "
                  + "/".join(f"{v:.3f}" for v in np.abs(relY).max(0) * 100), flush=True)
