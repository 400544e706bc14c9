"""Peak memory of the image writers alone: :func:`skymodel.render.image_io.save_outputs`
(EXR + PNG, as ``skymodel render --out sky.exr`` calls it) on a synthetic image of the
renderer's output shape, each case in its own child process.

    python benchmarks/bench_writers.py                       # 4096x2048, float64 and float32 input
    python benchmarks/bench_writers.py --sizes 1024,4096 --dtypes float64

The child builds a smooth synthetic CIE XYZ image (H, W, 3) of ``dtype`` (the colour render,
:func:`skymodel.render.sky.render_sky_reduced`, returns float64), notes its resident memory
(``ru_maxrss``, KiB on Linux) after the image exists and colour-science is imported (the
render imports it before the writers), calls ``save_outputs(out=..exr,
png=..png, xyz=image, camera=equirectangular)`` and notes the peak again; the writers'
own cost is the difference. Output: Markdown rows (docs/benchmarks.md)."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

CHILD = r"""
import os, resource, sys, time
import numpy as np
from skymodel.render import image_io
from skymodel.colorimetry import xyz_to_rgb_matrix
from skymodel.render.cameras import make_camera

xyz_to_rgb_matrix("rec709")  # imports colour-science (0.1 GiB), as the render itself has done before the writers

w, dtype, folder = int(sys.argv[1]), sys.argv[2], sys.argv[3]
h = w // 2
cam = make_camera("equirectangular", w, n_wavelengths=3)
zen = np.linspace(0.0, np.pi, h)
az = np.sin(np.linspace(0.0, 2.0 * np.pi, w))[:, None]
xyz = np.empty((h, w, 3), dtype=dtype)
for r in range(h):  # row by row, so the peak before the writers is the image itself
    xyz[r] = np.array([0.0095, 0.01, 0.012]) * (1.2 + np.cos(zen[r]) + 0.3 * az * np.sin(zen[r]))
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
image_io.save_outputs(out=os.path.join(folder, "sky.exr"), png=os.path.join(folder, "sky.png"), xyz=xyz,
                      wavelengths=None, camera=cam)
wall = time.perf_counter() - t
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(before, after, wall)
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="4096", help="image widths (equirectangular, height = width / 2)")
    ap.add_argument("--dtypes", default="float64,float32")
    args = ap.parse_args(argv)
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    print("| size | input dtype | before the writers (GiB) | peak (GiB) | writers add (GiB) | wall s |")
    print("|---|---|---|---|---|---|")
    for w in (int(x) for x in args.sizes.split(",")):
        for dtype in args.dtypes.split(","):
            with tempfile.TemporaryDirectory() as tmp:
                p = subprocess.run([sys.executable, "-c", CHILD, str(w), dtype, tmp], capture_output=True, text=True,
                                   cwd=root)
                if p.returncode != 0:
                    print(f"| {w}x{w // 2} | {dtype} | failed: {p.stderr.strip().splitlines()[-1:]} | | | |")
                    continue
                before, after, wall = p.stdout.split()
                b, a = int(before) / 2**20, int(after) / 2**20
                print(f"| {w}x{w // 2} | {dtype} | {b:.2f} | {a:.2f} | {a - b:.2f} | {float(wall):.1f} |", flush=True)


if __name__ == "__main__":
    main()
