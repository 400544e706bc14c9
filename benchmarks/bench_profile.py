"""Benchmark: building an 81-wavelength optical profile from the checked-in Mie lookups.

Target (issue 2): <= 50 ms per profile build. Two measurements:

* cold: every computed cache of the core is cleared before each build (the Mie lookup
  interpolated to the grid, the mixtures, the ozone climatology columns, the profile
  itself); only the raw files stay read (``skymodel.data`` caches the parsed tables);
* warm: only the per-atmosphere profile cache is cleared (what a session that changes
  one parameter sees).

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

    from skymodel.optics import atmosphere as atm_mod
    from skymodel.optics.atmosphere import Atmosphere
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths()
    rows = []
    import functools

    from skymodel import sun
    from skymodel.optics import aerosols, ozone

    def clear_computed_caches():
        for mod in (aerosols, ozone, sun, atm_mod):
            for obj in vars(mod).values():
                # only caches of computed results defined in the module itself (imported
                # file readers of skymodel.data keep the parsed tables)
                if isinstance(obj, functools._lru_cache_wrapper) and obj.__module__ == mod.__name__:
                    obj.cache_clear()

    for loc, kw in [("rural", {}), ("urban", {}), ("desert", {"aod550": 0.5}), ("maritime", {}),
                    ("antarctic", {"stratospheric": "volcanic"})]:
        def cold():
            clear_computed_caches()
            return Atmosphere(location=loc, month=6, **kw).optical_profile(wl)

        def warm():
            atm_mod._build_profile.cache_clear()
            return Atmosphere(location=loc, month=6, **kw).optical_profile(wl)

        c_med, c_lo, c_hi, prof = timeit(cold, repeat=args.repeat)
        w_med, _, _, _ = timeit(warm, repeat=args.repeat)
        rows.append((loc, kw, c_med, c_lo, c_hi, w_med, prof.altitudes_m.size))
    table = ["| atmosphere | altitudes x wavelengths | cold median (ms) | cold min–max (ms) | warm median (ms) | target |",
             "|---|---|---|---|---|---|"]
    for loc, kw, med, lo, hi, w_med, n_alt in rows:
        extra = ", ".join(f"{k}={v}" for k, v in kw.items())
        table.append(f"| {loc}{' (' + extra + ')' if extra else ''} | {n_alt} x {wl.size} | {med * 1e3:.1f} | "
                     f"{lo * 1e3:.1f}–{hi * 1e3:.1f} | {w_med * 1e3:.1f} | <= 50 ms: {'met' if med <= 0.05 else 'NOT met'} |")
    body = "\n".join([
        f"Machine: {machine()}. Revision {git_revision()}.",
        f"Command: `{command_line()}` ({args.repeat} repeats after one warm-up, medians).",
        "",
        *table,
    ])
    print(body)
    if args.write:
        update_section(os.path.join(os.path.dirname(__file__), "..", "docs", "benchmarks.md"),
                       "## Optical profile build (81 wavelengths)", body)


if __name__ == "__main__":
    main()
