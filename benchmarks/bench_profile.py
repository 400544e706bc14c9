"""Benchmark: building an 81-wavelength optical profile from the checked-in Mie lookups.

Target (issue 2): <= 50 ms per profile build. The build is timed without the
per-Atmosphere cache (a new Atmosphere each call... and the cache cleared), after a warm-up
that loads the data tables once (they are cached for the life of the process, as in use).

    python benchmarks/bench_profile.py [--write]
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from common import command_line, git_revision, machine, timeit, update_section  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="update docs/benchmarks.md")
    ap.add_argument("--repeat", type=int, default=21)
    args = ap.parse_args(argv)

    from skymodel import atmosphere as atm_mod
    from skymodel.atmosphere import Atmosphere
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths()
    rows = []
    for loc, kw in [("rural", {}), ("urban", {}), ("desert", {"aod550": 0.5}), ("maritime", {}),
                    ("antarctic", {"stratospheric": "volcanic"})]:
        def build():
            atm_mod._build_profile.cache_clear()
            return Atmosphere(location=loc, month=6, **kw).optical_profile(wl)

        med, lo, hi, prof = timeit(build, repeat=args.repeat)
        rows.append((loc, kw, med, lo, hi, prof.altitudes_m.size))
    table = ["| atmosphere | altitudes x wavelengths | median (ms) | min–max (ms) | target |",
             "|---|---|---|---|---|"]
    for loc, kw, med, lo, hi, n_alt in rows:
        extra = ", ".join(f"{k}={v}" for k, v in kw.items())
        table.append(f"| {loc}{' (' + extra + ')' if extra else ''} | {n_alt} x {wl.size} | {med * 1e3:.1f} | "
                     f"{lo * 1e3:.1f}–{hi * 1e3:.1f} | <= 50 ms: {'met' if med <= 0.05 else 'NOT met'} |")
    body = "\n".join([
        f"Machine: {machine()}. Revision {git_revision()}.",
        f"Command: `{command_line()}` ({args.repeat} repeats after one warm-up; the data tables stay cached "
        "between builds, the per-atmosphere profile cache is cleared before each).",
        "",
        *table,
    ])
    print(body)
    if args.write:
        update_section(os.path.join(os.path.dirname(__file__), "..", "docs", "benchmarks.md"),
                       "## Optical profile build (81 wavelengths)", body)


if __name__ == "__main__":
    main()
