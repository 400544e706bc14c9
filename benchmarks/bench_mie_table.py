"""Benchmark: the one-off build of the Mie lookup (skymodel/data/generated/mie_lookup.npz).

Times :func:`skymodel.optics.mie_lookup.build_tables` component by component on the full grids
(81 wavelengths x 385 scattering angles) and checks that the result equals the checked-in
table (so the time is the time of *that* table, not of a cheaper one).

    python benchmarks/bench_mie_table.py [--components soot sulfate ...] [--write]

Without ``--components`` every component is built (about a quarter of an hour on 2 cores).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import command_line, git_revision, machine, update_section  # noqa: E402

from skymodel.optics import mie_lookup  # noqa: E402
from skymodel.data import load_npz  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--components", nargs="+", default=None)
    ap.add_argument("--write", action="store_true", help="update docs/benchmarks.md")
    args = ap.parse_args(argv)
    table = load_npz(str(mie_lookup.DEFAULT_LOOKUP))
    names = [str(n) for n in table["components"]]
    todo = args.components or names
    rows, total = [], 0.0
    for name in todo:
        t0 = time.perf_counter()
        new = mie_lookup.build_tables([name])
        dt = time.perf_counter() - t0
        total += dt
        c = names.index(name)
        worst = max(float(np.max(np.abs(new[k][0] / table[k][c] - 1.0))) for k in ("ext", "sca", "g", "phase"))
        rows.append((name, dt, worst))
        print(f"{name:26s} {dt:7.1f} s  max rel. difference from the checked-in table {worst:.1e}", flush=True)
    lines = ["| component | build time (s) | max rel. difference from the checked-in table |", "|---|---|---|"]
    lines += [f"| {n} | {dt:.1f} | {w:.1e} |" for n, dt, w in rows]
    body = "\n".join([
        f"Machine: {machine()}. Revision {git_revision()}.",
        f"Command: `{command_line()}` (one build per component, 81 wavelengths x 385 angles).",
        "",
        *lines,
        "",
        f"Total: **{total:.0f} s** for {len(rows)} of {len(names)} components.",
    ])
    print(body)
    if args.write:
        update_section(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "benchmarks.md"),
                       "## Mie lookup table: the one-off build", body)


if __name__ == "__main__":
    main()
