"""The sky of every tropospheric aerosol type of both models at sun 5 deg (docs/img/aerosol_models_sun5.png).

    .venv/bin/python benchmarks/aerosol_model_skies.py [--size 128] [--out docs/img/aerosol_models_sun5.png]

Each panel is ``skymodel render --location rural --month 6 --sun-elevation 5 --sun-azimuth 180
--camera fisheye --quality preview --aerosol-model M --aerosol T`` (the type at its table amount,
stratospheric background, grass), tone-mapped by the CLI's PNG preview (each image at its own
display exposure, skymodel.render.exposure: the panels compare colour and the shape of the glow,
not absolute brightness). The title
gives the type's AOD550 and single-scattering albedo at 550 nm in that model. Needs matplotlib
(the ``plots`` extra). About 20 s a panel on 2 cores.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from skymodel.geometry import altitude_grid
from skymodel.optics import aerosols

ROOT = Path(__file__).resolve().parents[1]


def render(model: str, name: str, size: int, folder: Path) -> Path:
    png = folder / f"{model}_{name}.png"
    cmd = [sys.executable, "-m", "skymodel", "render", "--location", "rural", "--month", "6", "--sun-elevation", "5",
           "--sun-azimuth", "180", "--camera", "fisheye", "--size", str(size), "--quality", "preview",
           "--aerosol-model", model, "--aerosol", name, "--out", str(folder / f"{model}_{name}.exr"),
           "--png", str(png), "--quiet"]
    subprocess.run(cmd, check=True)
    return png


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "aerosol_models_sun5.png")
    args = p.parse_args(argv)
    models = list(aerosols.MODELS)
    rows = {m: aerosols.aerosol_types(m) for m in models}
    ncol = max(len(v) for v in rows.values())
    fig, axes = plt.subplots(len(models), ncol, figsize=(1.6 * ncol, 1.95 * len(models)), squeeze=False)
    h = altitude_grid()
    with tempfile.TemporaryDirectory() as tmp:
        for i, m in enumerate(models):
            for j in range(ncol):
                ax = axes[i, j]
                ax.axis("off")
                if j >= len(rows[m]):
                    continue
                name = rows[m][j]
                o = aerosols.aerosol_optics(name, h, [550.0], stratospheric="none", model=m)
                img = np.asarray(Image.open(render(m, name, args.size, Path(tmp))))
                ax.imshow(img)
                ax.set_title(f"{m}\n{name}\nAOD {o.aod550:.3g}, SSA {o.single_scattering_albedo[0]:.2f}", fontsize=6)
                print(f"{m:12s} {name:20s} done", file=sys.stderr, flush=True)
    fig.suptitle("sun 5 deg (south, at the bottom of each fisheye), rural site, June; each type at its table amount",
                 fontsize=7)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
