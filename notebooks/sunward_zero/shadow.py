"""Magnitude test: sunlight turned into the aerosols' cut peak above the Earth's shadow and
reaching view points in the shadow (left out by peak_paths), first scattering at P."""
import inspect, os, sys
import numpy as np
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
import skymodel.render.peak_paths as pp  # noqa: E402
from skymodel.wavelengths import spread_indices  # noqa: E402
src = inspect.getsource(pp.bent_minus_straight)
src = src.replace("todo = np.nonzero(vis > 1e-6)", "todo = np.nonzero((vis <= 1e-6) & (ee > -14.0))")
src = src.replace("out[i, j] = d / vis[i, j][:, None]", "out[i, j] = d")
assert "ee > -14.0" in src and "out[i, j] = d\n" in src
ns = dict(pp.__dict__); exec(src, ns); bms = ns["bent_minus_straight"]
sc, prof, wl, _ = su.scene(sys.argv[1])
pi = spread_indices(wl, pp.PROBE_STEP_NM); probes = wl[pi]
m = su.marcher(sc, prof)
med = m.medium
truth, _, base = su.truth_and_base(sc)
for vname in sys.argv[2].split(","):
    i, d = su.view(sc, vname)
    rings = m._rings(np.array([d[2]]))
    mus = m._sun_cosines(rings, d[None, None, :])[0, 0]
    h, dt = rings.h[0], rings.dt[0]
    e_sun = np.degrees(np.arcsin(np.clip(mus, -1, 1)))
    ext = med.extinction.at(h)[:, pi]
    tv = np.exp(-(np.cumsum(ext * dt[:, None], axis=0) - 0.5 * ext * dt[:, None]))
    _, B = bms(m.sun_table, prof, med, m.medium.cutoff_deg, h, e_sun[:, None])
    B = B[:, 0, :]  # (S, P) bent beam in the shadow, per unit irradiance
    cos_t = float(d @ m.sun)
    p_cap = m._capped_aerosol_phase(np.array([[cos_t]]))[:, 0, 0][:, pi]  # (R, P) (1-f) p*
    pa = prof.aerosol_phase_at(np.array([[cos_t]]))[:, 0, 0][:, pi]
    ray = med.rayleigh.at(h)[:, pi] * prof.rayleigh_phase(np.array([[cos_t]]))[0, 0][pi]
    cap = ray.copy(); full = ray.copy()
    for r in range(len(med.aerosol)):
        sig = med.aerosol[r].at(h)[:, pi]
        cap += sig * p_cap[r]; full += sig * pa[r]
    w = (tv * dt[:, None] * B)
    add_cap = (w * cap).sum(axis=0); add_full = (w * full).sum(axis=0)
    b = base[i] * 1.0
    bi = np.interp(probes, su.bt.MC_WAVELENGTHS_NM, b)
    print(f"{vname}: base " + su.rel(base[i] / truth[i] - 1)
          + "  bent-into-shadow first scattering, % of base at " + ",".join(f"{p:.0f}" for p in probes) + " nm: capped "
          + "/".join(f"{100*x:.2f}" for x in add_cap / bi) + "  full phase " + "/".join(f"{100*x:.2f}" for x in add_full / bi), flush=True)
