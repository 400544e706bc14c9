"""notebooks/truth_misses/variant.py with the solver's first-order radiance averaged over each
node's azimuth cell (L1_SUB sub-azimuths, default 4) instead of taken at the node: is the
azimuth-node aliasing of the sun's forward lobe in L1 what moves the sky with table_phi?
usage: L1_SUB=4 python notebooks/phase_cells/l1_cells.py scenes tag ['field=value,...'] [preset]"""
import dataclasses
import os
import runpy

import numpy as np

import skymodel.render.multiple_scattering as ms

K = int(os.environ.get("L1_SUB", "4"))
_orig = ms.first_order_radiance


def cell_first_order(profile, medium, sun_table, grid, *args, **kw):
    acc = None
    for d in (np.arange(K) + 0.5) / K - 0.5:
        g = dataclasses.replace(grid, phi_nodes=np.abs(grid.phi_nodes + d * grid.phi_weight))
        part = _orig(profile, medium, sun_table, g, *args, **kw).astype(np.float64)
        acc = part if acc is None else acc + part
    return (acc / K).astype(np.float32)


if K > 1:
    ms.first_order_radiance = cell_first_order
    print(f"first-order radiance averaged over {K} azimuths per cell", flush=True)
runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "truth_misses", "variant.py"),
               run_name="__main__")
