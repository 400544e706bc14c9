"""Make the coarse land/sea mask ``land_mask_0p1deg.npz`` that the location rule reads.

Source: the ``global-land-mask`` package (PyPI, MIT licence; Todd Karin), which ships a 1 km
(30 arc-second) land/ocean mask derived from the NOAA GLOBE digital elevation model (GLOBE Task
Team 1999, "The Global Land One-kilometer Base Elevation (GLOBE) Digital Elevation Model, v1.0",
NOAA NGDC): ``globe_combined_mask_compressed.npz``, 21600 x 43200 booleans, row 0 at 90 N,
column 0 at 180 W, True = ocean.

This script averages it over 12 x 12 blocks (0.1 degree cells) and calls a cell land when at least
half of its 1 km pixels are land, then stores the 1800 x 3600 booleans bit-packed
(``np.packbits`` along the longitude axis) with the grid description. The result is about 0.1 MB,
so skymodel needs neither the 1.8 MB package nor its data at run time; the package is only needed
to regenerate (``pip install global-land-mask``)::

    python skymodel/data/generated/make_land_mask.py                     # -> next to this script
    python skymodel/data/generated/make_land_mask.py --output /tmp/mask.npz

tests/test_location_rule.py regenerates it (when the package is installed) and compares.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

OUTPUT_NAME = "land_mask_0p1deg.npz"
#: Cell size, degrees, and block of 1 km pixels per cell.
CELL_DEG = 0.1
BLOCK = 12


def make(output: Path) -> Path:
    import importlib.util

    spec = importlib.util.find_spec("global_land_mask")  # located, not imported: its import loads the mask too
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError("global_land_mask (pip install global-land-mask==1.0.0)")
    src = Path(spec.origin).parent / "globe_combined_mask_compressed.npz"
    with np.load(src) as z:
        ocean = z["mask"]
    assert ocean.shape == (21600, 43200), ocean.shape
    ny, nx = ocean.shape[0] // BLOCK, ocean.shape[1] // BLOCK
    cells = np.empty((ny, nx), dtype=bool)
    for i in range(ny):  # one strip of 12 rows at a time: no full-size copy of the 0.9 GB mask
        n_ocean = ocean[i * BLOCK:(i + 1) * BLOCK].reshape(BLOCK, nx, BLOCK).sum(axis=(0, 2), dtype=np.int32)
        cells[i] = n_ocean <= BLOCK * BLOCK // 2  # land: at least half of the 144 pixels are land
    np.savez_compressed(
        output,
        land_bits=np.packbits(cells, axis=1),
        shape=np.array(cells.shape),
        cell_deg=np.array(CELL_DEG),
        north_deg=np.array(90.0),
        west_deg=np.array(-180.0),
        source=np.array("global-land-mask 1.0.0 (GLOBE 1 km DEM, NOAA NGDC 1999), 12x12 block majority"),
    )
    return output


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=Path(__file__).with_name(OUTPUT_NAME))
    args = parser.parse_args(argv)
    print(make(args.output))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
