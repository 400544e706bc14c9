"""Each phase's memory peak of one ``skymodel render`` (what the memory guard's constants in
:mod:`skymodel.render.memory` are fitted to): ``tracemalloc``'s peak during the tables' build
(``solve_sky``, of which the sun-transmittance table and the multiple-scattering solve), each
exact march (``SkyMarcher._exact``), the direct march of the pixels, the sky-view table's
lookup and the writers, as the traced bytes at the phase's peak and above its entry.

    python benchmarks/bench_memory_phases.py final 1024x512
    python benchmarks/bench_memory_phases.py preview 128x64 --spectral

Nested phases reset the peak of the phase around them (the sky-view table's build holds
exact marches), so read each row on its own. Traced bytes count ``np.empty`` pages that
are not yet touched, which the resident set does not (the 8192x4096 image allocated before
the solve); the guard is checked against the resident peak by ``bench_memory.py``."""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import tracemalloc

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

GIB = 1024**3


def _wrap(owner, name, label, record):
    f = getattr(owner, name)

    @functools.wraps(f)
    def traced(*a, **k):
        entry, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        try:
            return f(*a, **k)
        finally:
            now, peak = tracemalloc.get_traced_memory()
            r = record.setdefault(label, [0, 0, 0])
            r[0], r[1], r[2] = max(r[0], peak), max(r[1], peak - entry), r[2] + 1
    setattr(owner, name, traced)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("quality")
    ap.add_argument("size", help="WIDTHxHEIGHT")
    ap.add_argument("--spectral", action="store_true", help="keep the spectral cube (skymodel render --spectral)")
    a = ap.parse_args(argv)

    from skymodel.cli.main import main as cli
    from skymodel.render import image_io, marcher, sky, skyview

    record: dict = {}
    for owner, name, label in ((marcher, "solve_sky", "tables (solve_sky)"),
                               (marcher, "SunTransmittance", "  sun-transmittance table"),
                               (marcher, "solve_multiple_scattering", "  multiple-scattering solve"),
                               (marcher.SkyMarcher, "_exact", "exact march (one piece)"),
                               (sky, "_pixels", "pixels (march or lookup)"),
                               (skyview.SkyViewTable, "lookup", "sky-view lookup (one band)"),
                               (image_io, "save_outputs", "writers")):
        _wrap(owner, name, label, record)
    folder = tempfile.mkdtemp()
    argv = ["render", "--camera", "equirectangular", "--size", a.size, "--quality", a.quality, "--quiet",
            "--out", os.path.join(folder, "sky.exr")]
    if a.spectral:
        argv += ["--spectral", os.path.join(folder, "sky.npz")]
    tracemalloc.start()
    rc = cli(argv)
    print(f"{a.quality} {a.size}{' --spectral' if a.spectral else ''}: exit {rc}")
    print("| phase | traced at its peak GiB | above its entry GiB | calls |\n|---|---|---|---|")
    for label, (peak, above, calls) in record.items():
        print(f"| {label} | {peak / GIB:.3f} | {above / GIB:.3f} | {calls} |")
    return int(rc)


if __name__ == "__main__":
    raise SystemExit(main())
