"""The Monte Carlo tracer's random stream is unchanged by sharing the scatterer choice
(`_sample_scatterer_cos`) between `_sample_scattering` and `_guided_direction`: traces made
with the two functions as they were before (kept below, verbatim from main at 52483e8) and
with today's are equal bit for bit, so cached Monte Carlo truths stay valid."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.render.rays import direction_from_angles
from skymodel.validation import montecarlo as mc
from skymodel.validation.montecarlo import _guide_pdf, _rotate, _rowdot, _sample_guide_cos, trace_radiance


def _sample_scattering_before(med, sig_sc, sig_s, sig_t, wl_idx, directions, rng):
    cum = np.cumsum(sig_sc, axis=0)
    comp_i = np.minimum((rng.random(wl_idx.size) * sig_s[None, :] >= cum).sum(axis=0), med.n_regime)
    cos_t = np.empty(wl_idx.size)
    wt = sig_s / sig_t
    m = comp_i == 0
    if np.any(m):
        cos_t[m] = med.sample_rayleigh_cos(wl_idx[m], rng)
    for rg in range(med.n_regime):
        m = comp_i == rg + 1
        if np.any(m):
            cos_t[m] = med.sample_aerosol_cos(rg, wl_idx[m], rng)
            wt[m] *= med.phase_mass[rg, wl_idx[m]]
    return wt, _rotate(directions, cos_t, rng)


def _guided_direction_before(med, d_in, w, sig_sc, sun, alpha, rng):
    m = d_in.shape[0]
    n_reg = med.n_regime
    sig_s = sig_sc.sum(axis=0)
    guided = rng.random(m) < alpha
    cos_t = np.empty(m)
    base = np.empty((m, 3))
    pi = np.flatnonzero(~guided)
    if pi.size:
        cum = np.cumsum(sig_sc[:, pi], axis=0)
        comp_i = np.minimum((rng.random(pi.size) * sig_s[pi][None, :] >= cum).sum(axis=0), n_reg)
        ct = np.empty(pi.size)
        mk = comp_i == 0
        if np.any(mk):
            ct[mk] = med.sample_rayleigh_cos(w[pi][mk], rng)
        for rg in range(n_reg):
            mk = comp_i == rg + 1
            if np.any(mk):
                ct[mk] = med.sample_aerosol_cos(rg, w[pi][mk], rng)
        cos_t[pi] = ct
        base[pi] = d_in[pi]
    gi = np.flatnonzero(guided)
    if gi.size:
        cos_t[gi] = _sample_guide_cos(med, w[gi], rng)
        base[gi] = sun
    d_new = _rotate(base, cos_t, rng)
    mu_in = _rowdot(d_in, d_new)
    mass = med.phase_mass[:, w]
    ph = med.aerosol_phase(mu_in, w)
    f = sig_sc[0] * med.rayleigh_phase(mu_in, w) + (sig_sc[1:] * ph).sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_phys = (sig_sc[0] * med.rayleigh_phase(mu_in, w)
                  + (sig_sc[1:] * ph / np.where(mass > 0, mass, 1.0)).sum(axis=0)) / sig_s
    q = (1.0 - alpha) * p_phys + alpha * _guide_pdf(med, d_new, w, sun)
    with np.errstate(divide="ignore", invalid="ignore"):
        wgt = np.where(q > 0.0, f / sig_s / np.where(q > 0.0, q, 1.0), 0.0)
    return d_new, wgt


@pytest.mark.parametrize("aerosol", ["rural", "desert"])
@pytest.mark.parametrize("sun_guide", [0.0, 0.3])
def test_traces_are_bit_identical_to_the_functions_before_sharing(monkeypatch, aerosol, sun_guide):
    from skymodel import Atmosphere

    prof = Atmosphere(location="rural", aerosol=aerosol, month=6).optical_profile([450.0, 550.0, 650.0])
    dirs = direction_from_angles([0.0, 60.0, 85.0, 95.0], [0.0, 90.0, 180.0, 270.0])

    def trace():
        r = trace_radiance(prof, dirs, 10.0, 120.0, n_paths=2000, seed=7, sun_guide=sun_guide)
        return np.concatenate([r.radiance.ravel(), r.stderr.ravel()])

    now = trace()
    monkeypatch.setattr(mc, "_sample_scattering", _sample_scattering_before)
    monkeypatch.setattr(mc, "_guided_direction", _guided_direction_before)
    before = trace()
    assert np.all(np.isfinite(now)) and np.any(now > 0)
    assert np.array_equal(now, before)  # bit for bit, not approximately
