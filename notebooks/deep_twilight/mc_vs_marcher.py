"""The marcher against the Monte Carlo tracer in deep twilight: sun at -12, -15 and -18 degrees.

    nice -n 10 python notebooks/deep_twilight/mc_vs_marcher.py mc --minutes 30 &     # the MC, in chunks
    nice -n 10 python notebooks/deep_twilight/mc_vs_marcher.py marcher                # the marcher
    python notebooks/deep_twilight/mc_vs_marcher.py table                             # the README's table

Medium: ``Atmosphere(location="rural", month=6)`` at 450, 550 and 650 nm; observer on the
ground, sun azimuth 180 deg; views (zenith angle / azimuth from the sun): 0/0, 45/0,
80/0, 80/180. MC: ``trace_radiance(..., estimator="sunlit")`` (the plain estimator returns
0 here), all orders, traced in chunks of ``CHUNK`` paths per direction and band (seeds
1000, 1001, ...; scenes taken in turn until ``--minutes`` is spent), stored in
``--dir`` so the table can be rebuilt. Marcher: the presets preview, final, reference and
the validation's converged twilight settings (``CONVERGED_TWILIGHT`` of
benchmarks/validate_montecarlo.py; with ``--converged-bands`` only at those bands).
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.join(_HERE, "..", ".."), os.path.join(_HERE, "..", "..", "benchmarks")]

from skymodel import Atmosphere  # noqa: E402
from skymodel.render.rays import direction_from_angles  # noqa: E402

SUNS = (-12.0, -15.0, -18.0)
BANDS = np.array([450.0, 550.0, 650.0])
VIEWS = ((0.0, 0.0), (45.0, 0.0), (80.0, 0.0), (80.0, 180.0))
SUN_AZ = 180.0
CHUNK = 4000
PRESETS = ("preview", "final", "reference")


def profile():
    return Atmosphere(location="rural", month=6).optical_profile(BANDS)


def views():
    return direction_from_angles(np.array([v[0] for v in VIEWS]), SUN_AZ + np.array([v[1] for v in VIEWS]))


def run_mc(out, minutes):
    from skymodel.validation.montecarlo import trace_radiance

    prof, d = profile(), views()
    t_end = time.time() + 60.0 * minutes
    k = 0
    while time.time() < t_end:
        for el in SUNS:
            if time.time() >= t_end:
                break
            f = os.path.join(out, f"mc_{el:g}_{k:03d}.npz")
            if os.path.exists(f):
                continue
            mc = trace_radiance(prof, d, el, SUN_AZ, n_paths=CHUNK, seed=1000 + k, estimator="sunlit")
            np.savez(f, radiance=mc.radiance, stderr=mc.stderr, n=CHUNK, time_s=mc.time_s)
            print(f"sun {el:g} chunk {k}: {mc.time_s:.0f} s", flush=True)
        k += 1


def run_marcher(out, which, conv_bands):
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.quality import quality_settings
    from validate_montecarlo import CONVERGED_TWILIGHT

    d = views()
    for name in which:
        for el in SUNS:
            f = os.path.join(out, f"marcher_{name}_{el:g}.npz")
            if os.path.exists(f):
                continue
            if name == "converged":
                bands = BANDS if not conv_bands else np.array(conv_bands, float)
                prof = Atmosphere(location="rural", month=6).optical_profile(bands)
                s = CONVERGED_TWILIGHT
            else:
                bands, prof, s = BANDS, profile(), quality_settings(name)
            t = time.perf_counter()
            m = SkyMarcher(prof, el, SUN_AZ, 0.0, s).radiance(d).radiance
            dt = time.perf_counter() - t
            np.savez(f, radiance=m, bands=bands, time_s=dt)
            print(f"{name} sun {el:g}: {dt:.0f} s", flush=True)


def load_mc(out, el):
    runs = [np.load(f) for f in sorted(glob.glob(os.path.join(out, f"mc_{el:g}_*.npz")))]
    if not runs:
        return None
    mean = np.mean([r["radiance"] for r in runs], axis=0)
    se = np.sqrt(np.sum([r["stderr"] ** 2 for r in runs], axis=0)) / len(runs)
    return mean, se, len(runs) * CHUNK, sum(float(r["time_s"]) for r in runs)


def table(out):
    print("| sun (deg) | view | MC radiance 450/550/650 (W m-2 sr-1 nm-1) | MC se (%) | "
          + " | ".join(f"{p} (%)" for p in PRESETS + ("converged",)) + " |")
    print("|---|---|---|---|" + "---|" * (len(PRESETS) + 1))
    for el in SUNS:
        mc = load_mc(out, el)
        if mc is None:
            continue
        mean, se, n, secs = mc
        cols = {}
        for name in PRESETS + ("converged",):
            f = os.path.join(out, f"marcher_{name}_{el:g}.npz")
            if os.path.exists(f):
                z = np.load(f)
                bi = [int(np.argmin(np.abs(BANDS - b))) for b in z["bands"]]
                cols[name] = (z["radiance"], bi)
        for i, (zen, az) in enumerate(VIEWS):
            cells = []
            for name in PRESETS + ("converged",):
                if name not in cols:
                    cells.append("-")
                    continue
                m, bi = cols[name]
                rel = 100.0 * (m[i] / mean[i, bi] - 1.0)
                cells.append("/".join(f"{r:+.0f}" for r in rel))
            rad = "/".join(f"{v:.2e}" for v in mean[i])
            ses = "/".join(f"{100 * s / v:.1f}" for s, v in zip(se[i], mean[i]))
            print(f"| {el:g} | {zen:g}/{az:g} | {rad} | {ses} | " + " | ".join(cells) + " |")
        print(f"<!-- sun {el:g}: {n} paths per direction and band, {secs / 60:.1f} min of MC -->")
    print()
    print("| sun (deg) | paths | median MC se (%) | " + " | ".join(
        f"{p}: median / max abs. diff (%), > 3 se" for p in PRESETS + ("converged",)) + " |")
    print("|---|---|---|" + "---|" * (len(PRESETS) + 1))
    for el in SUNS:
        mc = load_mc(out, el)
        if mc is None:
            continue
        mean, se, n, _ = mc
        cells = []
        for name in PRESETS + ("converged",):
            f = os.path.join(out, f"marcher_{name}_{el:g}.npz")
            if not os.path.exists(f):
                cells.append("-")
                continue
            z = np.load(f)
            bi = [int(np.argmin(np.abs(BANDS - b))) for b in z["bands"]]
            d = z["radiance"] / mean[:, bi] - 1.0
            zs = np.abs(z["radiance"] - mean[:, bi]) / se[:, bi]
            cells.append(f"{100 * np.median(np.abs(d)):.0f} / {100 * np.abs(d).max():.0f}, {int((zs > 3).sum())}/{d.size}")
        print(f"| {el:g} | {n} | {100 * np.median(se / mean):.1f} | " + " | ".join(cells) + " |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("mc", "marcher", "table"))
    ap.add_argument("--dir", default="/tmp/deep_twilight_mc")
    ap.add_argument("--minutes", type=float, default=30.0, help="MC time budget (mc)")
    ap.add_argument("--settings", default="preview,final,reference,converged", help="marcher settings (marcher)")
    ap.add_argument("--converged-bands", default="", help="bands (nm) of the converged marcher, comma-separated")
    a = ap.parse_args(argv)
    os.makedirs(a.dir, exist_ok=True)
    if a.what == "mc":
        run_mc(a.dir, a.minutes)
    elif a.what == "marcher":
        cb = [float(x) for x in a.converged_bands.split(",") if x]
        run_marcher(a.dir, a.settings.split(","), cb)
    else:
        table(a.dir)


if __name__ == "__main__":
    main()
