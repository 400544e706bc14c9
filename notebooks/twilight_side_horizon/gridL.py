"""The solver's grid radiance L_n(e) near the horizon (what the peak term reads), per order."""
import os
import sys
import numpy as np
sys.path[:0] = ["benchmarks"]
import bench_truth as bt
from skymodel.render import peak_diffuse as pdm
from skymodel.render.marcher import solve_sky
from skymodel.render.quality import QUALITIES
cap = []
orig = pdm.PeakDiffuse.add_source
def add(self, radiance, target):
    g = self.grid
    cap.append((np.array(radiance, copy=True).reshape(g.n_wl, g.n_mu, g.n_phi, g.n_h, g.n_mus), g))
    return orig(self, radiance, target)
pdm.PeakDiffuse.add_source = add
sc = bt.Scene("desert", -4.0, os.environ.get("TRUTH_CACHE", ".cache/truth"))
prof = sc.atm.optical_profile(list(bt.MARCH_WAVELENGTHS_NM))
sol = solve_sky(prof, QUALITIES["final"].settings)


def near_horizon(L, g, hi):
    """L at 650 nm, the azimuth node nearest 90 deg, the sun node nearest -4 deg and altitude node
    ``hi``, on the zenith nodes within 11 deg of the horizon; and the nodes' (w, p, s, elevations)."""
    w = int(np.argmin(np.abs(g.wavelengths_nm - 650)))
    p = int(np.argmin(np.abs(np.degrees(g.phi_nodes) - 90)))
    s = int(np.argmin(np.abs(g.mus_nodes - np.sin(np.radians(-4)))))
    e = np.degrees(np.arcsin(g.mu_nodes))
    sel = np.flatnonzero(np.abs(e) < 11)
    return L[w, sel, p, hi, s], (w, p, s, e[sel])


for n, (L, g) in enumerate(cap[:3]):
    _, (w, p, s, e) = near_horizon(L, g, 0)
    print(f"order {n+1} field, {g.wavelengths_nm[w]:.0f} nm, phi {np.degrees(g.phi_nodes[p]):.1f}, sun {np.degrees(np.arcsin(g.mus_nodes[s])):.2f} deg")
    print("  e:   " + " ".join(f"{x:7.2f}" for x in e))
    for hi in (0, 1, 2, 3, 4, 5, 6):
        v = near_horizon(L, g, hi)[0]
        print(f"  h {g.h_nodes[hi]:5.0f}: " + " ".join(f"{x / v[-1]:7.3f}" for x in v))
print("total over the captured orders (each at its grid's phi nearest 90), ratio to e=8.63:")
for hi in (0, 1, 3, 4, 5):
    tot = sum(near_horizon(L, g, hi)[0] for L, g in cap)
    print(f"  h {g.h_nodes[hi]:5.0f}: " + " ".join(f"{x / tot[-1]:7.3f}" for x in tot))
print("orders captured", len(cap))
