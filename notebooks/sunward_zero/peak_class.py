"""The truth's light of two or more peak turns and nothing else, against `final`'s aureole term.

The aureole term (skymodel/render/aureole.py) is the light that reaches the eye after n >= 2
turns inside the aerosols' cut forward peaks and no other scattering, counted along one line
in a uniform medium. The Monte Carlo tracer can count that light exactly: each air collision's
integrand splits into the cut peak, sum_k sig_k (p_k - min(p_k, p_k(cone))) inside the cone, and
the rest; a path's weight times the peak's share of the integrand at every turn it took (the
guided NEE's estimate is f / q for the whole integrand f, so each share is f_peak / f), and at its
next-event estimate the peak's part of the sun's phase term, scores the class "every turn a
peak turn"; from the second vertex on that is the aureole's light, the first vertex's is single
scattering. A ground bounce ends the class. strat2d.py says the one-line count is about 11 %
high 3 degrees above a sun on the horizon (desert AOD 0.5); this measures it.

usage: [ORDERS=k] [SPLIT=1] peak_class.py scene views paths [wavelengths_nm] [seed]
  e.g. peak_class.py desert:0 87/0,85/0,84/0,89/4.899 200000 550,650 11
Prints per view and wavelength the tracer's total and class radiance (per unit solar irradiance,
with standard errors), `final`'s total and its aureole term alone (decomp.py's hook, without the
first scattering's peak spread that the same gather adds: that goes with the rest) and their
ratios. ORDERS=k: also the class by its number of turns, 2 ... k and k + 1 or more, the tracer's
against the aureole term's (the Poisson terms of its one-line count, e^-tau tau^(m-1) / m! q^{*m}
for m turns, gathered as the term is). SPLIT=1: the sky split four ways, the tracer's against
`final`'s: the peak's single turn (the first vertex's; `final`'s delta-M first scattering's peak
part, through the true extinction), the pure peak chains (the class; the aureole term), exactly one
turn outside the cut peak with any number of peak turns (the tracer's paths weighed by the share of
one non-peak turn among their turns; `final`'s delta-M first scattering's capped part, through the
scaled extinction, plus its peak spread) and the rest (two or more non-peak turns and the ground;
`final`'s total less the three)."""
import os
import sys
import time

from math import factorial

import numpy as np

sys.path[:0] = [os.path.dirname(os.path.abspath(__file__))]
import _setup as su  # noqa: E402
from skymodel.render.marcher import SkyMarcher, peak_shape  # noqa: E402
from skymodel.render.medium import delta_m_cone_deg  # noqa: E402
from skymodel.render.rays import sun_direction  # noqa: E402
from skymodel.validation import montecarlo as mc  # noqa: E402


#: trace_radiance's default
MAX_BOUNCES = 64


def peak_cap(med, cone_deg):
    """Each regime's phase value at the cut (R, W) and the largest angle (deg) the cut peak
    reaches: the first tabulated angle at or beyond the cone, as aureole.peak_part cuts it."""
    ang = med.phase_deg
    j = min(max(int(np.searchsorted(ang, cone_deg)), 1), ang.size - 1)
    return med.phase_tab[:, j, :], float(ang[j])


def peak_phase(med, cos_t, w, cap, edge_deg):
    """(R, m): the cut peak of each regime's phase function at cos_t."""
    ph = med.aerosol_phase(cos_t, w)
    inside = np.degrees(np.arccos(np.clip(cos_t, -1.0, 1.0))) < edge_deg
    return np.where(inside[None, :], np.maximum(ph - cap[:, w], 0.0), 0.0)


def trace_classes(med, origin, dirs, w, sun, max_bounces, rng, alpha, table, cap, edge, n_orders=0):
    """mc._trace_batch with the sun guide (alpha > 0), the same steps, also scoring the class
    of paths whose every turn was a peak turn, from the second vertex on. Returns (n, 2), or with
    ``n_orders`` (n, 2 + n_orders): the class split by its number of turns, 2, 3, ... and the
    last column all from 1 + n_orders turns on (a score at the path's vertex b has b + 1 turns:
    b in the air, the last toward the sun). Columns 2 + n_orders and 3 + n_orders: the light of one
    peak turn only (the first vertex's peak single scattering) and of exactly one turn outside the
    cut peak with any number of peak turns (SPLIT below)."""
    n = dirs.shape[0]
    contrib = np.zeros((n, 4 + n_orders))
    one = 2 + n_orders  # the columns of the peak's single turn and of one non-peak turn
    p = np.broadcast_to(origin, dirs.shape).copy()
    r_obs = float(np.linalg.norm(origin))
    band = np.full(n, int(np.clip(np.searchsorted(med.band_r, r_obs, side="right") - 1, 0, med.n_bands - 1)))
    idx = np.arange(n)
    P, D, J, Wl = p, dirs.copy(), band, w
    beta = np.ones(n)
    chain = np.ones(n)  # the class's share of beta
    chain1 = np.zeros(n)  # the share of paths with exactly one non-peak turn so far
    for bounce in range(max_bounces):
        if idx.size == 0:
            break
        ev, P, J = mc._track(med, P, D, J, Wl, rng)
        nxt_D = D.copy()
        keep = ev != mc._ESCAPE
        ci, wc, sig_sc, sig_s, sig_t = mc._collision_coefficients(med, P, Wl, ev)
        if ci.size:
            Pc, Dc = P[ci], D[ci]
            mu_sun = Dc @ sun
            ph = np.concatenate([med.rayleigh_phase(mu_sun, wc)[None], med.aerosol_phase(mu_sun, wc)])
            t_sun = mc._sun_transmittance(med, Pc, wc, sun, rng, table) * med.e_sun[wc]
            contrib[idx[ci], 0] += beta[ci] * (sig_sc * ph).sum(axis=0) / sig_t * t_sun
            pk = peak_phase(med, mu_sun, wc, cap, edge)
            f_pk = (sig_sc[1:] * pk).sum(axis=0)
            f_np = (sig_sc * ph).sum(axis=0) - f_pk
            contrib[idx[ci], one + 1] += beta[ci] * (chain1[ci] * f_pk + chain[ci] * f_np) / sig_t * t_sun
            if bounce == 0:
                contrib[idx[ci], one] += beta[ci] * f_pk / sig_t * t_sun
            if bounce >= 1:
                cls = beta[ci] * chain[ci] * f_pk / sig_t * t_sun
                contrib[idx[ci], 1] += cls
                if n_orders:
                    contrib[idx[ci], 2 + min(bounce - 1, n_orders - 1)] += cls
            nxt_D[ci], wgt = mc._guided_direction(med, Dc, wc, sig_sc, sun, alpha, rng)
            beta[ci] *= sig_s / sig_t * wgt
            # the peak's share of the integrand at the turn taken
            mu_in = mc._rowdot(Dc, nxt_D[ci])
            f = sig_sc[0] * med.rayleigh_phase(mu_in, wc) + (sig_sc[1:] * med.aerosol_phase(mu_in, wc)).sum(axis=0)
            fp = (sig_sc[1:] * peak_phase(med, mu_in, wc, cap, edge)).sum(axis=0)
            share = np.where(f > 0, fp / np.where(f > 0, f, 1.0), 0.0)
            chain1[ci] = chain1[ci] * share + chain[ci] * (1.0 - share)
            chain[ci] *= share
        gi = np.flatnonzero(ev == mc._GROUND)
        if gi.size:
            Pg, wg = P[gi], Wl[gi]
            nrm, lit, nee = mc._ground_nee(med, Pg, wg, beta[gi], sun, rng, table)
            contrib[idx[gi[lit]], 0] += nee
            nxt_D[gi] = mc._ground_bounce(med, nrm, gi, wg, beta, sun, alpha, rng)
            J[gi] = 0
            chain[gi] = 0.0
            chain1[gi] = 0.0
        D = nxt_D
        keep &= beta > 0.0
        if bounce + 1 >= mc._RR_START:
            beta, keep = mc._roulette(med, beta, D, Wl, sun, alpha, keep, rng)
        idx, P, D, J, Wl, beta, chain = idx[keep], P[keep], D[keep], J[keep], Wl[keep], beta[keep], chain[keep]
        chain1 = chain1[keep]
    return contrib


def aureole_orders(m, n_orders):
    """The marcher's aureole table split by the number of turns: float32 tables for 2 ... n_orders
    turns and the rest (n_orders + 1 or more), on its (theta, tau) grid."""
    machine, _, qk = peak_shape(m.profile, m.medium, m.medium.cutoff_deg, m.top)
    theta_g, tau_g, table = m._aureole
    tabs = []
    for turns in range(2, n_orders + 1):
        t = np.zeros_like(table)
        for j, tau in enumerate(tau_g):
            if tau > 0:
                t[:, j] = machine._inverse(np.exp(-tau) * tau ** (turns - 1) / factorial(turns) * qk**turns, theta_g)
        tabs.append(t)
    tabs.append(table - sum(tabs))
    return [t.astype(np.float32) for t in tabs]


def main():
    scene, views, n_paths = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
    wls = [float(x) for x in (sys.argv[4] if len(sys.argv) > 4 else "550,650").split(",")]
    seed = int(sys.argv[5]) if len(sys.argv) > 5 else 11
    sc, prof, wl, _ = su.scene(scene)
    rows = sc.view_rows(views)
    alpha = sc.sun_guide
    if not alpha > 0:
        raise SystemExit("this script traces with the sun guide (desert scenes)")
    m = su.marcher(sc, prof)
    s = m.settings
    cone = delta_m_cone_deg(prof, s.delta_m_cutoff_deg, s.delta_m_mild_cutoff_deg, table_phi=s.table_phi)
    # final's split at the views (decomp.py's hook on the aureole gather)
    rec, rec_spread, rec_first = [], [], []
    orig = SkyMarcher._aureole_gather
    orig_first = SkyMarcher._delta_m_first_scattering

    def hook(self, *a, **k):  # the gather adds the first scattering's spread: the aureole alone without it
        out = orig(self, *a, **k)
        alone = orig(self, *a, **{**k, "spread": None}) if k.get("spread") is not None else out
        rec.append(alone)
        rec_spread.append(out - alone)
        return out

    def hook_first(self, cos_theta, dt, ray, regimes, aers, pa, p_cap, c_aer, trans_s, t_sun_s):
        # the delta-M first scattering: the peak's single turn (true extinction) and the rest
        out = orig_first(self, cos_theta, dt, ray, regimes, aers, pa, p_cap, c_aer, trans_s, t_sun_s)
        peak = sum(np.maximum(pa[reg] - p_cap[reg], 0.0) * c for reg, c in zip(regimes, c_aer))
        peak = self.profile.solar_irradiance * peak
        rec_first.append((out - peak, peak))
        return out

    SkyMarcher._aureole_gather = hook
    SkyMarcher._delta_m_first_scattering = hook_first
    n_orders = int(os.environ.get("ORDERS", "0"))
    order_tables = aureole_orders(m, n_orders) if n_orders else []
    mc_prof = sc.atm.optical_profile(wls)
    sun = sun_direction(sc.elev, su.bt.SUN_AZIMUTH).astype(float).reshape(3)
    origin = np.array([0.0, 0.0, float(mc_prof.planet_radius_m)])
    rng = np.random.default_rng(seed)
    print(f"{scene}: cone {cone:g} deg, sun guide {alpha:g}, {n_paths} paths per view and wavelength, seed {seed}")
    for i in rows:
        rec.clear()
        rec_spread.clear()
        rec_first.clear()
        r = m.radiance(sc.dirs[i:i + 1])
        aur = rec[0].reshape(-1, len(wl))[0]
        one_np = (rec_first[0][0] + rec_spread[0]).reshape(-1, len(wl))[0]  # one non-peak turn: capped first + spread
        one_pk = rec_first[0][1].reshape(-1, len(wl))[0]  # the peak's single turn
        full = m._aureole_table32
        aur_orders = []
        for t32 in order_tables:  # the aureole term's light of each number of turns
            m._aureole_table32 = t32
            rec.clear()
            m.radiance(sc.dirs[i:i + 1])
            aur_orders.append(rec[0].reshape(-1, len(wl))[0])
        m._aureole_table32 = full
        for k, lam in enumerate(wls):
            j = int(np.argmin(np.abs(wl - lam)))
            e0m = float(np.asarray(prof.solar_irradiance)[j])
            med = mc._Medium(mc_prof, np.array([k]))
            cap, edge = peak_cap(med, cone)
            table = mc._DepthTable(med) if sc.elev < mc._DARK_SUN_DEG else None
            t = time.perf_counter()
            chunks = []
            for p0 in range(0, n_paths, 20000):
                npc = min(20000, n_paths - p0)
                d = np.repeat(sc.dirs[i:i + 1], npc, axis=0)
                chunks.append(trace_classes(med, origin, d, np.zeros(npc, dtype=int), sun, MAX_BOUNCES, rng, alpha,
                                            table, cap, edge, n_orders))
            c = np.concatenate(chunks) / float(mc_prof.solar_irradiance[k])
            mean, se = c.mean(axis=0), c.std(axis=0, ddof=1) / np.sqrt(c.shape[0])
            fin_tot, fin_aur = r.radiance[0, j] / e0m, aur[j] / e0m
            if not mean[1] > 0:
                print(f"{su.bt.view_label(sc.views[i])} {lam:g} nm: MC total {mean[0]:.5g} ± {100 * se[0] / mean[0]:.2f} %, "
                      f"no path of the class; final total {fin_tot:.5g} ({100 * (fin_tot / mean[0] - 1):+.2f} %), "
                      f"aureole {fin_aur:.5g} [{time.perf_counter() - t:.0f} s]", flush=True)
                continue
            print(f"{su.bt.view_label(sc.views[i])} {lam:g} nm: MC total {mean[0]:.5g} ± {100 * se[0] / mean[0]:.2f} %, "
                  f"class {mean[1]:.5g} ± {100 * se[1] / mean[1]:.2f} % ({100 * mean[1] / mean[0]:.1f} % of it); "
                  f"final total {fin_tot:.5g} ({100 * (fin_tot / mean[0] - 1):+.2f} %), aureole {fin_aur:.5g} "
                  f"({100 * fin_aur / fin_tot:.1f} % of it); aureole / class {fin_aur / mean[1]:.3f} ± "
                  f"{fin_aur / mean[1] * se[1] / mean[1]:.3f}; final rest / MC rest "
                  f"{(fin_tot - fin_aur) / (mean[0] - mean[1]):.3f} [{time.perf_counter() - t:.0f} s]", flush=True)
            if os.environ.get("SPLIT"):
                o1 = 2 + n_orders
                parts = [("one peak turn", mean[o1], se[o1], one_pk[j] / e0m),
                         ("pure peak chains", mean[1], se[1], fin_aur),
                         ("one non-peak turn", mean[o1 + 1], se[o1 + 1], one_np[j] / e0m)]
                rest_mc = mean[0] - mean[1] - mean[o1] - mean[o1 + 1]
                rest_fin = fin_tot - fin_aur - (one_pk[j] + one_np[j]) / e0m
                parts.append(("two or more non-peak turns, ground", rest_mc, float("nan"), rest_fin))
                for name, mo, so, fo in parts:
                    print(f"    {name:>35}: MC {mo:.4g} ± {so:.2g} ({100 * mo / mean[0]:.1f} % of the sky), final "
                          f"{fo:.4g}, final / MC {fo / mo if mo > 0 else float('nan'):.3f}, (final - MC) / MC total "
                          f"{100 * (fo - mo) / mean[0]:+.2f} %", flush=True)
            for o, a_o in enumerate(aur_orders):
                turns = f"{o + 2}" if o + 1 < n_orders else f">={o + 2}"
                mo, so, ao = mean[2 + o], se[2 + o], a_o[j] / e0m
                print(f"    {turns:>4} turns: MC {mo:.4g} ± {so:.2g} ({100 * mo / mean[1]:.1f} % of the class), "
                      f"aureole {ao:.4g} ({100 * ao / fin_aur:.1f} %); aureole / MC "
                      f"{ao / mo if mo > 0 else float('nan'):.3f}", flush=True)


if __name__ == "__main__":
    main()
