"""The solver's first-order radiance on its grid (the input of the second order) against the tracer's
max_bounces=1 radiance seen from the grid node: rural AOD 0.2, the delta-M medium itself (as orders.py's
`dm`), final's tables, the sun at the sun-angle node nearest 5 degrees, altitude nodes 0 and 3, the zenith
nodes within |mu| < 0.35 at three azimuth nodes; 100 000 paths (seed 3), about 2.5 min.
usage: PYTHONPATH=$PWD python notebooks/truth_misses/node_first_order.py ["field=value,..." [paths]]
(a variant of final's MarchSettings, bench_truth's syntax, e.g. "sun_table_altitudes=384"; paths default 100000)"""
import sys, numpy as np
from dataclasses import replace
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
import skymodel.render.multiple_scattering as ms
from skymodel.render.medium import factor_medium
from skymodel.render.sun_transmittance import SunTransmittance
from skymodel.render.quality import QUALITIES
from skymodel.validation.delta_m_medium import delta_m_profile
from skymodel.validation.montecarlo import trace_radiance
from skymodel.validation.truth import view_directions
s = replace(QUALITIES["final"].settings, **bt._parse_variant(sys.argv[1] if len(sys.argv) > 1 else ""))
n_paths = int(sys.argv[2]) if len(sys.argv) > 2 else 100000
prof = bt.atmosphere("rural").optical_profile(list(bt.MC_WAVELENGTHS_NM))
prof = delta_m_profile(prof, 12.0)
prof = replace(prof, solar_irradiance=np.ones(3))
med = factor_medium(prof, 12.0)
st = SunTransmittance([med.extinction, med.extinction_scaled], prof.planet_radius_m, prof.top_altitude_m,
                      s.sun_table_altitudes, s.sun_table_x, s.sun_table_steps)
grid = ms.build_table_grid(prof, med, n_altitudes=s.table_altitudes, n_mu=s.table_mu, n_phi=s.table_phi, n_mus=s.table_mus)
rays = ms.trace_grid_rays(grid, med, prof.planet_radius_m, prof.top_altitude_m, s.table_steps)
rs = ms.transport_row_scale(grid, rays, med)
M = ms.column_transport_matrix(grid, rays, rs)
G = ms.ground_transmittance_vector(rays)
L1 = ms.first_order_radiance(prof, med, st, grid, rays, M, G, spherical=True)  # (wl, dir, h, mus)
elev = np.degrees(np.arcsin(grid.mus_nodes))
ks = int(np.argmin(np.abs(elev - 5.0)))
print("sun node elev", elev[ks], "h nodes", grid.h_nodes[:6])
mu = grid.mu_nodes; phi = np.degrees(grid.phi_nodes)
for ih in (0, 3):
    sel = []
    for im in range(grid.n_mu):
        if abs(mu[im]) < 0.35:
            for ip in (0, grid.n_phi // 2, grid.n_phi - 1):
                sel.append((im, ip))
    views = np.array([[np.degrees(np.arccos(mu[im])), phi[ip]] for im, ip in sel])
    dirs = view_directions(views, bt.SUN_AZIMUTH)
    res = trace_radiance(prof, dirs, elev[ks], bt.SUN_AZIMUTH, observer_altitude_m=grid.h_nodes[ih], n_paths=n_paths,
                         max_bounces=1, seed=3)
    sol = np.array([L1[:, im * grid.n_phi + ip, ih, ks] for im, ip in sel])
    rel = sol / res.radiance - 1
    print(f"h {grid.h_nodes[ih]:.0f} m: mean rel " + "/".join(f"{100*x:+.2f}" for x in rel.mean(0)))
    for (im, ip), v, r, se, m in zip(sel, views, rel, res.stderr / res.radiance, res.radiance):
        print(f"  {v[0]:.1f}/{v[1]:.0f}: " + "/".join(f"{100*x:+.2f}" for x in r) + "  se " + "/".join(f"{100*x:.2f}" for x in se))
