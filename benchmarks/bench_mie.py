"""Benchmark: vectorised Mie efficiencies (skymodel.optics.mie) against a scalar loop over miepython.

Target (Mie issue): ``skymodel.optics.mie.efficiencies`` on a set of size parameters is at least
10x faster than calling the oracle's scalar function once per point for the same set.

Points: ``--n-points`` (2000) size parameters log-spaced over [1e-2, 1e3], one refractive
index ``--m`` (1.5+0.01j in BH's n + ik convention; miepython gets its conjugate). Timed:

* ``skymodel.optics.mie.efficiencies(m, x)`` — one vectorised call;
* ``miepython.efficiencies_mx(m, x_i)`` in a Python loop over the points (the target's
  baseline), and miepython's own array call ``efficiencies_mx(m_array, x)`` — both with
  miepython's default backend (pure Python/numpy; miepython 3 only uses numba when
  ``MIEPYTHON_USE_JIT=1`` is set before import);
* the same two miepython calls with ``MIEPYTHON_USE_JIT=1``, in a subprocess (the backend
  is chosen at import). The first call of each, which triggers numba's compilation, is
  timed separately and excluded from the medians.

Every method gets one untimed warm-up call, then ``--repeat`` (>= 5) timed calls; medians
are reported. The results of the loop are compared with ours (max relative difference).

    python benchmarks/bench_mie.py [--write] [--repeat 5] [--n-points 2000] [--no-jit]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from common import command_line, git_revision, machine, timeit, update_section  # noqa: E402

import numpy as np  # noqa: E402

HEADING = "## Mie: vectorised vs scalar oracle"


def _points(n_points: int) -> np.ndarray:
    return np.geomspace(1e-2, 1e3, n_points)


def _time_miepython(m_bh: complex, x: np.ndarray, repeat: int) -> dict:
    """Time miepython's scalar loop and array call in this process (whatever backend it chose)."""
    import miepython

    m_mp = np.conj(m_bh)
    m_arr = np.full(x.shape, m_mp)

    def loop():
        out = np.empty((x.size, 4))
        for i, xi in enumerate(x):
            out[i] = miepython.efficiencies_mx(m_mp, float(xi))
        return out

    def array_call():
        return np.array(miepython.efficiencies_mx(m_arr, x)).T

    t0 = time.perf_counter()
    miepython.efficiencies_mx(m_mp, 1.0)  # first call: numba compiles here when the JIT is on
    first_scalar = time.perf_counter() - t0
    t0 = time.perf_counter()
    miepython.efficiencies_mx(m_arr[:2], x[:2])
    first_array = time.perf_counter() - t0
    loop_t = timeit(loop, repeat=repeat)
    arr_t = timeit(array_call, repeat=repeat)
    return {
        "use_jit": bool(getattr(miepython, "USE_JIT", False)),
        "version": getattr(miepython, "__version__", "?"),
        "first_scalar_s": first_scalar,
        "first_array_s": first_array,
        "loop": loop_t[:3],
        "array": arr_t[:3],
        "qext_loop": loop_t[3][:, 0].tolist(),
    }


def _jit_worker(args) -> None:
    t0 = time.perf_counter()
    import miepython  # noqa: F401  (with MIEPYTHON_USE_JIT=1 its numba kernels compile/load here)

    import_s = time.perf_counter() - t0
    res = _time_miepython(complex(args.m), _points(args.n_points), args.repeat)
    res["import_s"] = import_s
    print(json.dumps(res))


def _run_jit_subprocess(args) -> dict | None:
    env = dict(os.environ, MIEPYTHON_USE_JIT="1")
    cmd = [sys.executable, os.path.abspath(__file__), "--jit-worker", "--repeat", str(args.repeat),
           "--n-points", str(args.n_points), "--m", str(args.m)]
    try:
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, timeout=1800)
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired, OSError) as exc:
        print(f"(numba-JIT miepython run failed: {exc})", file=sys.stderr)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def _machine_lines() -> list[str]:
    u = platform.uname()
    try:
        nproc = len(os.sched_getaffinity(0))
    except AttributeError:
        nproc = os.cpu_count()
    try:
        import numba

        numba_v = numba.__version__
    except ImportError:
        numba_v = "not installed"
    import miepython
    import scipy

    return [
        f"Machine: {machine()}.",
        f"`uname -a`: `{u.system} {u.node} {u.release} {u.version} {u.machine}`; nproc: {nproc}.",
        f"Versions: Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"miepython {getattr(miepython, '__version__', '?')}, numba {numba_v}. Revision {git_revision()}.",
    ]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="update docs/benchmarks.md")
    ap.add_argument("--repeat", type=int, default=5, help="timed repeats per method (>= 5)")
    ap.add_argument("--n-points", type=int, default=2000)
    ap.add_argument("--m", type=complex, default=1.5 + 0.01j, help="refractive index n+ik (k >= 0)")
    ap.add_argument("--no-jit", action="store_true", help="skip the numba-JIT miepython subprocess")
    ap.add_argument("--jit-worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.repeat < 5:
        ap.error("--repeat must be at least 5")
    if args.jit_worker:
        _jit_worker(args)
        return

    from skymodel.optics import mie

    if os.environ.get("MIEPYTHON_USE_JIT", "0") == "1":
        ap.error("run without MIEPYTHON_USE_JIT=1; the JIT backend is timed in a subprocess")

    x = _points(args.n_points)
    m = complex(args.m)
    ours_med, ours_lo, ours_hi, ours = timeit(lambda: mie.efficiencies(m, x), repeat=args.repeat)
    py = _time_miepython(m, x, args.repeat)
    jit = None if args.no_jit else _run_jit_subprocess(args)

    diff = float(np.max(np.abs(ours.qext - np.array(py["qext_loop"])) / ours.qext))
    rows = [("skymodel.optics.mie.efficiencies (one vectorised call)", ours_med, ours_lo, ours_hi)]
    rows.append(("miepython.efficiencies_mx, Python loop over points (pure-Python backend)", *py["loop"]))
    rows.append(("miepython.efficiencies_mx(m_array, x) (pure-Python backend)", *py["array"]))
    if jit is not None:
        rows.append(("miepython.efficiencies_mx, Python loop over points (numba JIT)", *jit["loop"]))
        rows.append(("miepython.efficiencies_mx(m_array, x) (numba JIT)", *jit["array"]))
    table = ["| method | median (ms) | min–max (ms) | per point (µs) | time / ours |", "|---|---|---|---|---|"]
    for name, med, lo, hi in rows:
        table.append(f"| {name} | {med * 1e3:.1f} | {lo * 1e3:.1f}–{hi * 1e3:.1f} | "
                     f"{med / x.size * 1e6:.1f} | {med / ours_med:.1f}x |")
    ratio = py["loop"][0] / ours_med
    ratio_min = py["loop"][1] / ours_lo
    notes = [
        "",
        f"Speed-up over the scalar-loop oracle (pure-Python miepython, its default): **{ratio:.1f}x** "
        f"from the medians, {ratio_min:.1f}x from the fastest runs (target >= 10x: "
        f"{'met' if min(ratio, ratio_min) >= 10 else 'NOT met'}).",
    ]
    if jit is not None:
        notes.append(
            f"With numba (`MIEPYTHON_USE_JIT=1`, separate process): miepython declares its kernels with explicit "
            f"signatures (`cache=True`), so they are compiled (or loaded from numba's cache) at import, which took "
            f"{jit['import_s']:.1f} s; the first calls then took {jit['first_scalar_s'] * 1e3:.1f} ms (scalar) and "
            f"{jit['first_array_s'] * 1e3:.1f} ms (array). Import and first calls are excluded from the timings. "
            f"The compiled scalar loop takes {jit['loop'][0] / ours_med:.2f}x our time "
            f"(skymodel.optics.mie stays pure numpy: no numba in skymodel/).")
    notes.append(f"Max relative difference of Q_ext, ours vs the miepython loop, over the {x.size} points: "
                 f"{diff:.1e} (miepython truncates the series at int(x + 4.05 x^(1/3) + 2) and uses Wiscombe's "
                 "small-sphere expansion for |m|x < 0.1).")
    body = "\n".join([
        *_machine_lines(),
        f"Command: `{command_line()}`.",
        f"Work: Q_ext, Q_sca, Q_back, g for {x.size} size parameters log-spaced over [1e-2, 1e3], "
        f"m = {m.real:g} + {m.imag:g}i. Each method: one untimed warm-up call, then {args.repeat} timed "
        "calls; medians reported.",
        "",
        *table,
        *notes,
    ])
    print(body)
    if args.write:
        update_section(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "benchmarks.md"),
                       HEADING, body)


if __name__ == "__main__":
    main()
