"""Prototype (study, not the renderer): the delta-M direct beam near a low sun with the
peak-scattered light's bent paths. Adds to the sun table's delta-M media (1, 2) an
optical-depth correction so that exp(-tau*_eff) = exp(-tau) + H_bent, the direct beam
plus the light scattered (first time) into the cut peak at a point Q on a line that
reaches P from elevation e_sun + x (x over the peak projected on the elevation axis),
seen from Q's sun through the true extinction and from Q to P through the scaled one.
Delta-M's own value (the straight line, x = 0) is exp(-tau*) exactly."""
import numpy as np
from skymodel.numerics import linear_interp_matrix
from skymodel.render.medium import factor_medium
from skymodel.render.peak_diffuse import peak_of, projected_kernel
from skymodel.render import marcher as _marcher
from skymodel.render.marcher import solver_wavelengths

STATE = {}
PROBES_NM = (440.0, 500.0, 550.0, 600.0, 660.0)
MAX_ELEV_DEG = 25.0
MAX_H_M = 15000.0
X_STEP_DEG = 0.5
N_S = 160


def halo_depth_correction(st, profile, cutoff_deg):
    wl = np.asarray(profile.wavelengths_nm, float)
    probes = np.array([wl[np.argmin(np.abs(wl - p))] for p in PROBES_NM])
    probes = np.unique(probes)
    pi = [int(np.argmin(np.abs(wl - p))) for p in probes]
    med = factor_medium(profile, cutoff_deg)
    regs = [r for r in range(len(med.aerosol)) if np.any(med.forward_fraction[r] > 0)]
    peaks = peak_of(profile, med)
    xs_deg = np.arange(-12.5, 12.5 + 1e-9, X_STEP_DEG)
    kern = []
    for r in regs:
        x, k = projected_kernel(profile.aerosol_phase_angles_deg, peaks[r])
        kk = np.stack([np.interp(np.radians(xs_deg), x, k[:, w], left=0, right=0) for w in pi], 1)
        kern.append(kk / np.where(kk.sum(0) > 0, kk.sum(0), 1.0))  # (n_x, P)
    R = st.R
    hh, xx = np.meshgrid(st.h_nodes, st.x_nodes, indexing="ij")
    mu = st._mu_from_x(hh, xx)
    e = np.degrees(np.arcsin(mu))
    mask = (hh < MAX_H_M) & (e < MAX_ELEV_DEG) & (e > -3.0)
    corr = np.zeros(hh.shape + (probes.size,))
    s = np.concatenate([[0.0], np.geomspace(20.0, 800e3, N_S - 1)])
    w0 = st.weights[0][:, pi]
    w1 = None
    for (i, j) in zip(*np.nonzero(mask)):
        h0, es = hh[i, j], e[i, j]
        r0 = R + h0
        tau0 = st.basis_depths(np.array([h0]), np.array([mu[i, j]]), (0,))[0] @ w0
        vis = st.visible_fraction(np.array([h0]), np.array([mu[i, j]]))[0]
        if vis < 1e-6:
            continue
        taus = st.basis_depths(np.array([h0]), np.array([mu[i, j]]), (2,))[0] @ st.weights[2][:, pi]
        ee = np.radians(es + xs_deg)[:, None]  # (n_x, 1)
        qx = s[None, :] * np.cos(ee)
        qz = r0 + s[None, :] * np.sin(ee)
        rq = np.hypot(qx, qz)
        hq = rq - R
        sun = np.array([np.cos(np.radians(es)), np.sin(np.radians(es))])
        muq = (qx * sun[0] + qz * sun[1]) / rq
        below = hq < 0
        alive = np.cumsum(below, axis=1) == 0
        inside = alive & (hq <= st.top)
        hqc = np.clip(hq, 0, st.top)
        tq = np.exp(-(st.basis_depths(hqc, muq, (0,))[0] @ w0)) * st.visible_fraction(hqc, muq)[..., None]
        exs = med.extinction_scaled.at(hqc.ravel())[:, pi].reshape(hq.shape + (-1,))
        cum = np.concatenate([np.zeros((xs_deg.size, 1, exs.shape[-1])),
                              np.cumsum(0.5 * (exs[:, 1:] + exs[:, :-1]) * np.diff(s)[None, :, None], axis=1)], axis=1)
        bent = np.zeros(probes.size)
        for r, kk in zip(regs, kern):
            sp = (med.aerosol[r].at(hqc.ravel()) - med.aerosol_scaled[r].at(hqc.ravel()))[:, pi].reshape(hq.shape + (-1,))
            f = sp * tq * np.exp(-cum) * inside[..., None]
            line = np.trapz(f, s, axis=1)  # (n_x, P)
            bent += (kk * line).sum(0)
        t_eff = np.exp(-tau0[0]) + bent / vis
        corr[i, j] = np.maximum(-np.log(np.maximum(t_eff, 1e-300)), 0.0) - taus[0]
    return probes, corr


def patched_factory(orig):
    """The sun table with the prototype's columns in both delta-M media (the solver's and the
    marcher's); the marcher reads the peak aureole's beam without them (``straight=``), as the
    renderer's own version does (before it, this prototype kept a copy of the medium for that:
    HALO_AUREOLE_STRAIGHT=0 gave the aureole the corrected beam)."""
    def make(media, R, top, *a, **k):
        st = orig(media, R, top, *a, **k)
        prof = STATE["profile"]
        probes, corr = halo_depth_correction(st, prof, STATE["cutoff"])
        STATE["corr"] = (probes, corr, st.h_nodes, st.x_nodes)
        wl_full = np.asarray(prof.wavelengths_nm, float)
        wl_ms = solver_wavelengths(wl_full, STATE["ms_step"])
        for w, wl in ((1, wl_ms), (2, wl_full)):
            st.add_depth_columns(w, corr, linear_interp_matrix(probes, wl))
        return st
    return make


def install(profile, settings):
    STATE.update(profile=profile, cutoff=settings.delta_m_cutoff_deg, ms_step=settings.ms_wavelength_step_nm)
    if not getattr(_marcher, "_halo_patched", False):
        _marcher.SunTransmittance = patched_factory(_marcher.SunTransmittance)
        _marcher._halo_patched = True
