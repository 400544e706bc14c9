"""The memory guard against the measured peak: ``skymodel render`` over a grid of
qualities x image sizes, each in its own child process, whose peak resident memory
(``ru_maxrss`` of the child, from ``os.wait4``) is compared with
:func:`skymodel.render.memory.estimate_render_memory`.

    python benchmarks/bench_memory.py                      # the grid, table on stdout
    python benchmarks/bench_memory.py --write              # ... and into docs/reliability.md
    python benchmarks/bench_memory.py --cases preview:128x64,final:512x256

The renders are real (EXR + PNG written to a temporary folder), so the grid takes
minutes; run it alone (one heavy process at a time)."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(1, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from common import command_line, git_revision, machine, update_section  # noqa: E402

GRID = ("preview:128x64,preview:512x256,preview:1024x512,final:128x64,final:512x256,final:1024x512,"
        "reference:128x64,reference:512x256")
STEP_NM = 5.0
DOC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "reliability.md")
HEADING = "## Memory guard: estimate against the measured peak"
HEADING_SPECTRAL = "## Memory guard: renders that keep the spectral cube (--spectral)"

CHILD = """
import sys
from skymodel.cli.main import main
rc = main(sys.argv[1:])
sys.exit(rc)
"""


def measure(quality: str, width: int, height: int, step_nm: float, folder: str, spectral: bool, camera=None):
    """(peak RSS bytes, seconds) of one ``skymodel render`` in a child process (with
    ``spectral``, ``--spectral``: the render that keeps the spectral cube; ``camera``: ``--camera``,
    None the CLI's default)."""
    out = os.path.join(folder, f"{quality}_{width}x{height}.exr")
    cmd = [sys.executable, "-c", CHILD, "render", "--quality", quality, "--size", f"{width}x{height}",
           "--wavelength-step", f"{step_nm:g}", "--max-memory", "4096", "--quiet", "--out", out]
    if spectral:
        cmd += ["--spectral", out[:-4] + ".npz"]
    if camera:
        cmd += ["--camera", camera]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace").strip()
    proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[3:])}: exit {proc.returncode}: {err[-400:]}")
    return usage.ru_maxrss * 1024, time.perf_counter() - t0  # ru_maxrss is in KiB on Linux


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=GRID, help="quality:WIDTHxHEIGHT,... (default: %(default)s)")
    ap.add_argument("--step", type=float, default=STEP_NM, help="wavelength step [nm] (default %(default)s)")
    ap.add_argument("--spectral", action="store_true",
                    help="renders that keep the spectral cube (--spectral); default: the CLI's colour render")
    ap.add_argument("--camera", default=None, help="skymodel render's --camera (default: the CLI's default)")
    ap.add_argument("--write", action="store_true", help="write the table into docs/reliability.md")
    args = ap.parse_args(argv)

    import numpy as np

    from skymodel import scene
    from skymodel.cli.render import REDUCED_BAND_PIXELS, REDUCED_DTYPE
    from skymodel.render.cameras import make_camera
    from skymodel.render.memory import GIB, estimate_render_memory
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(args.step)
    sun_deg = float(scene.default("sun_elevation"))  # skymodel render's sun without --time or --sun-elevation
    rows = ["| quality | image | wavelengths | estimate GiB (tables / bands / image / base) | peak RSS GiB | "
            "estimate / peak | render s |", "|---|---|---|---|---|---|---|"]
    ratios = []
    with tempfile.TemporaryDirectory(prefix="skymodel-bench-memory-") as folder:
        for case in args.cases.split(","):
            quality, size = case.split(":")
            w, h = (int(v) for v in size.split("x"))
            # as skymodel render estimates it: the cube only with --spectral, else 3 values a pixel
            camera = make_camera(args.camera or scene.default("camera"), w, h, n_wavelengths=1,
                                 max_memory_bytes=1 << 62)  # the render's camera (the guard counts its pixels)
            est = estimate_render_memory(w, h, wl.size, quality, wavelengths_nm=wl,
                                         image_channels=None if args.spectral else 3,
                                         band_pixels=None if args.spectral else REDUCED_BAND_PIXELS,
                                         image_value_bytes=8 if args.spectral else np.dtype(REDUCED_DTYPE).itemsize,
                                         sun_elevation_deg=sun_deg, camera=camera)
            peak, secs = measure(quality, w, h, args.step, folder, args.spectral, args.camera)
            ratio = est.total / peak
            ratios.append(ratio)
            rows.append(f"| {quality} | {w}x{h} | {wl.size} | {est.gib:.2f} ({est.tables / GIB:.2f} / "
                        f"{est.bands / GIB:.2f} / {est.image / GIB:.2f} / {est.base / GIB:.2f}) | "
                        f"{peak / GIB:.2f} | {ratio:.2f} | {secs:.0f} |")
            print(rows[-1], flush=True)
    summary = (f"Estimate / peak over {len(ratios)} renders: {min(ratios):.2f} .. {max(ratios):.2f} "
               f"(the guard's target: 0.75 .. 1.25).")
    body = "\n".join([
        f"`skymodel render{' --spectral' if args.spectral else ''}{' --camera ' + args.camera if args.camera else ''}` (EXR + PNG{' + NPZ' if args.spectral else ''}, "
        f"rural, sun {sun_deg:g} deg, the estimate given that sun) in a child process per row; the peak is the "
        "child's `ru_maxrss`; the estimate is `skymodel.render.memory.estimate_render_memory`, which "
        "`render_sky` and `skymodel render` compare with `--max-memory` (GiB, default "
        "4) before any work.", "",
        f"Machine: {machine()}; revision {git_revision()} (with the working tree); command: "
        f"`{command_line()}`.", "", *rows, "", summary, ""])
    print(summary)
    if args.write:
        update_section(DOC, HEADING_SPECTRAL if args.spectral else HEADING, body)
    return 0 if all(0.75 <= r <= 1.25 for r in ratios) else 1


if __name__ == "__main__":
    sys.exit(main())
