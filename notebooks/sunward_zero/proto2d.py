"""Prototype: the last peak turn at each view point of light that arrived along bent lines
(2D small-angle), replacing the straight plane-wave aureole. usage: proto2d.py scene views"""
import inspect
import os
import sys
import numpy as np
sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
import skymodel.render.peak_paths as pp  # noqa: E402
from skymodel.wavelengths import spread_indices  # noqa: E402
from skymodel.render.peak_diffuse import peak_of  # noqa: E402
from skymodel.render.marcher import SkyMarcher  # noqa: E402

src = inspect.getsource(pp.bent_minus_straight)
src = src.replace("            d += np.einsum(\"nxp,xp->np\", line, k) - line[:, i0]",
                  "            d += np.einsum(\"nxp,xp->np\", line, k) - line[:, i0]\n            STASH.append((i.copy(), offsets, line))")
ns = dict(pp.__dict__); STASH = []; ns["STASH"] = STASH; ns["SOLVER_THREADS"] = 1
exec(src, ns)
bms = ns["bent_minus_straight"]

scene, views = sys.argv[1], sys.argv[2].split(",")
MODE = os.environ.get("MODE", "replace")
sc, prof, wl, _ = su.scene(scene)
m = su.marcher(sc, prof)
pi = spread_indices(wl, pp.PROBE_STEP_NM); probes = wl[pi]
med = m.medium
kern = pp._kernels(prof, med, pi, np.radians(np.arange(-13, 14) * 1.0))
regs = [r for r, _ in kern]
peaks = peak_of(prof, med)[:, :, pi]  # (R, A, P)
ang = np.asarray(prof.aerosol_phase_angles_deg, float)
STEP = 0.1
g = np.radians(np.arange(-25.0, 25.0 + 1e-9, STEP)); dg = np.radians(STEP)
xf = g[np.abs(g) <= np.radians(12.5)]
def qfun(r, p, x, y):
    return np.interp(np.degrees(np.hypot(x, y)), ang, peaks[r, :, p], right=0.0)
norm = {}
for r in regs:
    for p in range(pi.size):
        X, Y = np.meshgrid(g, g, indexing="ij")
        norm[r, p] = qfun(r, p, X, Y).sum() * dg * dg

rec = {}
orig = SkyMarcher._aureole_gather
def ag(self, *aa, **kk):
    out = orig(self, *aa, **kk); rec["aur"] = out; return out
SkyMarcher._aureole_gather = ag

truth, se, base = su.truth_and_base(sc)
sun = m.sun
for vname in views:
    i, d = su.view(sc, vname)
    res = m.radiance(d[None])
    tot = res.radiance[0][pi]; aur = rec["aur"].reshape(-1, wl.size)[0][pi]
    rings = m._rings(np.array([d[2]]))
    D = d[None, None, :]
    mus = m._sun_cosines(rings, D)[0, 0]
    h, dt, t, r_, xz = rings.h[0], rings.dt[0], rings.t[0], rings.r[0], rings.xz[0]
    e_sun = np.arcsin(np.clip(mus, -1, 1))
    e_v = np.arcsin(np.clip((t * (d[0] ** 2 + d[1] ** 2) + xz * d[2]) / r_, -1, 1))
    th = np.arccos(np.clip(d @ sun, -1, 1))
    vx = e_v - e_sun
    vy = np.sqrt(np.maximum(th ** 2 - vx ** 2, 0.0))
    ext = med.extinction.at(h)[:, pi]
    tau = np.cumsum(ext * dt[:, None], axis=0) - 0.5 * ext * dt[:, None]
    tv = np.exp(-tau)
    STASH.clear()
    keep = np.flatnonzero((h < 10_000.0) & (tv[:, -1] > 1e-12))  # peak_paths' altitude bound then
    bms(m.sun_table, prof, med, m.medium.cutoff_deg, h[keep], np.degrees(e_sun[keep])[:, None])
    S = h.size
    # lines per regime (S, X, P)
    lines = {}
    nreg = len(regs)
    for n, (idx, offs, line) in enumerate(STASH):
        r = regs[n % nreg]
        L = lines.setdefault(r, np.zeros((S, offs.size, pi.size)))
        L[keep[idx]] = line[:, :, :]
        lines[r, "off"] = offs
    A = np.zeros(pi.size)
    for s in np.flatnonzero(tv[:, -1] > 1e-12):
        if vy[s] > np.radians(24) and abs(vx[s]) > np.radians(24):
            continue
        for r2 in regs:
            sig2 = med.aerosol[r2].at(np.array([h[s]]))[0, pi] * med.forward_fraction[r2, pi]
            for r in regs:
                offs = lines[r, "off"]
                for p in range(pi.size):
                    lf = np.interp(xf, offs, lines[r][s, :, p], left=0.0, right=0.0)
                    if not np.any(lf):
                        continue
                    XX, YY = np.meshgrid(xf, g, indexing="ij")
                    w = (qfun(r2, p, vx[s] - XX, vy[s] - YY) / norm[r2, p] * qfun(r, p, XX, YY) / norm[r, p]).sum(axis=1) * dg
                    A[p] += dt[s] * tv[s, p] * sig2[p] * (lf * w).sum() * dg
    A *= prof.solar_irradiance[pi]
    new = tot - aur + A if MODE == "replace" else tot + A
    ratio = np.interp(su.bt.MC_WAVELENGTHS_NM, probes, new / tot)
    aurs = np.interp(su.bt.MC_WAVELENGTHS_NM, probes, aur / tot)
    As = np.interp(su.bt.MC_WAVELENGTHS_NM, probes, A / tot)
    relb = base[i] / truth[i] - 1; reln = base[i] * ratio / truth[i] - 1
    print(f"{vname}: base " + "/".join(f"{100*x:+.2f}" for x in relb) + "  new " + "/".join(f"{100*x:+.2f}" for x in reln)
          + "  (aur " + "/".join(f"{100*x:.1f}" for x in aurs) + " %, A " + "/".join(f"{100*x:.1f}" for x in As) + " % of total; se "
          + "/".join(f"{100*x:.2f}" for x in se[i] / truth[i]) + ")", flush=True)
