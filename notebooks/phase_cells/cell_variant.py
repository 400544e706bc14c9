"""notebooks/truth_misses/variant.py with the solver's phase matrix averaged over each incoming
node's cell instead of sampled at its centre (a prototype of the change measured in this notebook).
CELL_SUB="k_mu,k_phi" sub-samples per cell (default 4,4); CELL_SUB=0 leaves the matrix as it is.
usage: CELL_SUB=4,4 python notebooks/phase_cells/cell_variant.py scenes tag ['field=value,...'] [preset]"""
import os
import runpy

import numpy as np

import skymodel.render.multiple_scattering as ms

SUB = os.environ.get("CELL_SUB", "4,4")


def cell_edges_mu(grid):
    """Edges of the mu cells: the cumulative Gauss weights from -1 (each hemisphere sums to 1)."""
    return np.concatenate([[-1.0], -1.0 + np.cumsum(grid.mu_weights)])


def cell_phase_matrix(phase_function, grid, pair_cosines, k_mu=4, k_phi=4):
    edges = cell_edges_mu(grid)
    frac = (np.arange(k_mu) + 0.5) / k_mu
    mu_sub = edges[:-1, None] + (edges[1:] - edges[:-1])[:, None] * frac[None, :]  # (n_mu, k_mu)
    dphi = (np.arange(k_phi) + 0.5) / k_phi - 0.5  # in units of the azimuth step
    mu_d, sin_d, phi_d = grid.dir_mu, grid.dir_sin, grid.dir_phi
    acc = None
    for a in range(k_mu):
        mu_in = np.repeat(mu_sub[:, a], grid.n_phi)  # (n_dir,)
        sin_in = np.sqrt(np.clip(1 - mu_in ** 2, 0, None))
        for b in range(k_phi):
            phi_in = phi_d + dphi[b] * grid.phi_weight
            cp = mu_d[:, None] * mu_in[None, :] + sin_d[:, None] * sin_in[None, :] * np.cos(phi_d[:, None] - phi_in[None, :])
            cm = mu_d[:, None] * mu_in[None, :] + sin_d[:, None] * sin_in[None, :] * np.cos(phi_d[:, None] + phi_in[None, :])
            term = phase_function(cp) + phase_function(cm)
            acc = term if acc is None else acc + term
    wq = (np.repeat(grid.mu_weights, grid.n_phi) * grid.phi_weight)[None, :]
    pm = acc / (k_mu * k_phi) * wq[..., None]
    pm = pm / pm.sum(axis=1, keepdims=True)
    return np.ascontiguousarray(np.moveaxis(pm, -1, 0))


if SUB != "0":
    km, kp = (int(x) for x in SUB.split(","))
    # the solver builds its phase modes with phase_modes_of (one circulant column, since f9b6fcd);
    # the cell-averaged matrix goes through the dense route
    ms.phase_modes_of = lambda f, grid: ms.phase_modes(cell_phase_matrix(f, grid, None, km, kp), grid)
    print(f"phase matrix averaged over {km} x {kp} points per cell", flush=True)
runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "truth_misses", "variant.py"),
               run_name="__main__")
