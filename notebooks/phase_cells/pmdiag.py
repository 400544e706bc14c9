"""Row sums of the solver's phase matrix before its normalisation (rural AOD 0.2, 6-degree cone,
at 550 nm), for table_mu x table_phi from 32 x 8 to 96 x 32: how far the point-sampled quadrature
of each aerosol regime's truncated phase function (and Rayleigh's) is from 1.
usage: python notebooks/phase_cells/pmdiag.py"""
import os, sys
import numpy as np
sys.path[:0]=["benchmarks"]
import bench_truth as bt
from skymodel.render import multiple_scattering as ms
from skymodel.render.medium import factor_medium
sc = bt.Scene("rural", 5.0, os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile([450.0, 550.0, 650.0])
med = factor_medium(prof, 6.0)
for nmu, nphi in [(32,8),(32,12),(32,14),(32,16),(32,20),(32,24),(48,16),(64,24),(96,32)]:
    grid = ms.build_table_grid(prof, med, n_altitudes=8, n_mu=nmu, n_phi=nphi, n_mus=4)
    pair = ms.direction_pair_cosines(grid)
    cp, cm = pair
    wq = (np.repeat(grid.mu_weights, grid.n_phi) * grid.phi_weight)[None, :]
    out = []
    for reg in range(med.truncated_phase.shape[0]):
        f = ms.aerosol_phase_function(prof, med, reg)
        raw = ((f(cp) + f(cm)) * wq[..., None]).sum(axis=1)  # (n_dir, n_wl)
        out.append(f"reg{reg}: rowsum 550 min {raw[:,1].min():.3f} med {np.median(raw[:,1]):.3f} max {raw[:,1].max():.3f}")
    raw = ((prof.rayleigh_phase(cp) + prof.rayleigh_phase(cm)) * wq[..., None]).sum(axis=1)
    print(nmu, nphi, " | ".join(out), f"| ray {np.median(raw[:,1]):.4f}")
