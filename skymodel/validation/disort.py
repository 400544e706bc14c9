"""The marcher against DISORT: run DISORT (through ``pydisort``) on the plane-parallel
layers of an optical profile, and the marcher on the same directions, shaped alike.

DISORT (Stamnes et al. 1988; the C version 2.1.3 inside ``pydisort``) solves the
plane-parallel radiative transfer equation by discrete ordinates. It is handed the
atmosphere the marcher renders, cut into homogeneous layers
(:func:`skymodel.validation.plane_parallel.plane_parallel_layers`), and gives the
downward diffuse radiance at the ground. ``benchmarks/validate_disort.py`` runs the full
comparison and writes its tables into the docs; ``tests/test_disort.py`` a small one.

``pydisort`` (which pulls torch) is not a dependency of the project: it is imported only
inside :func:`run_disort`, so this module imports without it.

Conventions (checked by the tests): DISORT's ``umu`` < 0 is light travelling downward,
i.e. a ground observer looking up at zenith angle acos(-umu); its azimuth
``phi - phi0`` = 0 is light travelling in the beam's azimuth, i.e. the observer looking
toward the sun, which is our relative azimuth 0. ``fbeam`` is the solar irradiance on a
plane normal to the beam (our top-of-atmosphere solar irradiance), and DISORT's
intensities come out in the units of ``fbeam`` per steradian.

References
----------
Stamnes, K., Tsay, S.-C., Wiscombe, W., Jayaweera, K. (1988). Numerically stable algorithm
for discrete-ordinate-method radiative transfer in multiple scattering and emitting
layered media. Applied Optics 27(12), 2502-2509.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

__all__ = ["run_disort", "plane_parallel_single_scattering", "run_marcher", "scattering_angles_deg", "moment_check"]


def run_disort(layers, sun_zenith_deg, view_zenith_deg, relative_azimuth_deg, n_streams: int = 32,
               n_moments: int | None = None, intensity_correction: bool = True) -> np.ndarray:
    """Downward diffuse radiance at the ground from DISORT, shaped
    (n_sun, n_view_zenith, n_relative_azimuth, n_wl), in the units of
    ``layers.solar_irradiance`` per steradian. One DISORT run per wavelength (each has its
    own total optical depth, where the output level lies); the sun positions are batched
    as DISORT columns."""
    import torch
    from pydisort import Disort, DisortOptions

    sun_zen = np.atleast_1d(np.asarray(sun_zenith_deg, float))
    vz = np.atleast_1d(np.asarray(view_zenith_deg, float))
    phi = np.atleast_1d(np.asarray(relative_azimuth_deg, float))
    n_mom = layers.moments.shape[1] - 1 if n_moments is None else int(n_moments)
    n_mom = max(n_mom, n_streams)
    # downward-travelling light has umu < 0; DISORT wants umu increasing
    order = np.argsort(-np.cos(np.radians(vz)))
    umu = -np.cos(np.radians(vz[order]))
    flags = "usrtau,usrang,lamber,quiet"
    if intensity_correction:
        flags += ",intensity_correction,old_intensity_correction"
    ncol = sun_zen.size
    out = np.empty((ncol, vz.size, phi.size, layers.wavelengths_nm.size))
    f64 = dict(dtype=torch.float64)
    for k in range(layers.wavelengths_nm.size):
        op = DisortOptions().flags(flags)
        op.ds().nlyr = layers.n_layers
        op.ds().nstr = int(n_streams)
        op.ds().nmom = n_mom
        op.ds().nphase = int(n_streams)
        tau_k = layers.optical_depth[:, k]
        # radiance at the ground: the bottom level (a hair inside, against round-off)
        op.user_tau(np.array([float(np.cumsum(tau_k)[-1]) * (1.0 - 1e-12)]))
        op.user_mu(umu)
        op.user_phi(phi)
        op.nwave(1)
        op.ncol(ncol)
        op.accur(0.0)
        solver = Disort(op)
        prop = np.zeros((1, ncol, layers.n_layers, 2 + n_mom))
        prop[..., 0] = tau_k
        prop[..., 1] = np.minimum(layers.single_scattering_albedo[:, k], 1.0 - 1e-9)
        m = min(n_mom, layers.moments.shape[1] - 1)
        prop[..., 2:2 + m] = layers.moments[:, 1:m + 1, k]
        bc = {
            "umu0": torch.tensor(np.cos(np.radians(sun_zen)), **f64),
            "phi0": torch.zeros(ncol, **f64),
            "fbeam": torch.full((1, ncol), float(layers.solar_irradiance[k]), **f64),
            "albedo": torch.full((1, ncol), float(layers.ground_albedo[k]), **f64),
            "fluor": torch.zeros((1, ncol), **f64),
            "fisot": torch.zeros((1, ncol), **f64),
        }
        solver.forward(torch.tensor(prop, **f64), **bc)
        rad = solver.gather_rad().numpy()  # (1, ncol, nphi, ntau=1, numu)
        res = np.moveaxis(rad[0, :, :, 0, :], 2, 1)  # (ncol, numu, nphi), umu order
        out[..., k][:, order, :] = res
    return out


def plane_parallel_single_scattering(profile, layers, sun_zenith_deg, view_zenith_deg, relative_azimuth_deg):
    """Exact single-scattered downward radiance at the ground of the plane-parallel layers
    (closed form per homogeneous layer, the full phase tables, no Legendre series), shaped
    like :func:`run_disort`'s output: the reference for the marcher's first order, which
    separates the geometry (spherical vs plane-parallel) from the multiple scattering."""
    sz = np.radians(np.atleast_1d(np.asarray(sun_zenith_deg, float)))[:, None, None]
    vz = np.radians(np.asarray(view_zenith_deg, float))[None, :, None]
    ph = np.radians(np.asarray(relative_azimuth_deg, float))[None, None, :]
    mu0, mu = np.cos(sz), np.cos(vz)
    shape = np.broadcast_shapes(sz.shape, vz.shape, ph.shape)
    cos_theta = np.broadcast_to(mu0 * mu + np.sin(sz) * np.sin(vz) * np.cos(ph), shape)
    lay = profile.layered(edges_m=layers.edges_m[::-1])
    dz = np.diff(lay.edges_m)[:, None]
    ray = (lay.rayleigh_scattering * dz)[::-1]  # top first, (n_layer, W)
    aer = (lay.aerosol_scattering_by_regime * dz[None])[:, ::-1]  # (R, n_layer, W)
    p_ray = profile.rayleigh_phase(cos_theta)  # (S, V, P, W)
    p_aer = profile.aerosol_phase_at(cos_theta)  # (R, S, V, P, W)
    tau = layers.optical_depth  # (n_layer, W)
    top = np.concatenate([np.zeros((1, tau.shape[1])), np.cumsum(tau, axis=0)[:-1]])
    bottom = top + tau
    total = bottom[-1]
    a = (1.0 / mu0 - 1.0 / mu)[..., None, None]  # (S, V, 1, 1, 1)
    # integral over the layer of exp(-t / mu0 - (total - t) / mu) dt / mu
    with np.errstate(divide="ignore", invalid="ignore"):
        seg = np.where(np.abs(a) > 1e-12,
                       (np.exp(-a * top) - np.exp(-a * bottom)) / np.where(np.abs(a) > 1e-12, a, 1.0),
                       tau * np.exp(-a * top))
    seg = seg * np.exp(-total / mu[..., None, None]) / mu[..., None, None]  # (S, V, 1, n_layer, W)
    scat = ray[None, None, None] * p_ray[..., None, :] + np.einsum("rlw,rsvpw->svplw", aer, p_aer)
    tau_s = ray + aer.sum(axis=0)  # the profile's scattering optical depths give the mixing weights
    p_mix = scat / np.where(tau_s > 0, tau_s, 1.0)
    return layers.solar_irradiance * (seg * layers.single_scattering_albedo * p_mix).sum(axis=-2)


def run_marcher(profile, sun_elevation_deg, view_zenith_deg, relative_azimuth_deg, quality="reference",
                orders=None):
    """Marcher sky radiance (no sun disc), shaped like :func:`run_disort`'s output;
    ``orders=1`` gives single scattering alone."""
    from skymodel.render.marcher import SkyMarcher
    from skymodel.render.rays import direction_from_angles
    from skymodel.render.sky import QUALITY

    settings = replace(QUALITY[quality], exact=True, orders=orders)
    vz = np.asarray(view_zenith_deg, float)
    phi = np.asarray(relative_azimuth_deg, float)
    zz, aa = np.meshgrid(vz, phi, indexing="ij")
    sun_az = 180.0
    out = []
    for elev in np.atleast_1d(sun_elevation_deg):
        d = direction_from_angles(zz.ravel(), (sun_az + aa.ravel()) % 360.0)
        res = SkyMarcher(profile, float(elev), sun_az, 0.0, settings).radiance(d)
        out.append(res.radiance.reshape(vz.size, phi.size, -1))
    return np.stack(out)


def scattering_angles_deg(sun_elevation_deg, view_zenith_deg, relative_azimuth_deg) -> np.ndarray:
    """Angle between view and sun, (n_sun, n_view_zenith, n_relative_azimuth)."""
    sz = np.radians(90.0 - np.asarray(sun_elevation_deg, float))[:, None, None]
    vz = np.radians(np.asarray(view_zenith_deg, float))[None, :, None]
    ph = np.radians(np.asarray(relative_azimuth_deg, float))[None, None, :]
    c = np.cos(sz) * np.cos(vz) + np.sin(sz) * np.sin(vz) * np.cos(ph)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def moment_check(profile, n_moments: int, lo_deg: float, hi_deg: float) -> float:
    """Largest relative error of the aerosol phase tables rebuilt from ``n_moments``
    Legendre moments, over scattering angles lo..hi degrees (all regimes, wavelengths)."""
    from skymodel.optics.legendre import phase_from_moments, tabulated_moments

    ang = profile.aerosol_phase_angles_deg
    chi = tabulated_moments(ang, np.moveaxis(profile.aerosol_phase, 1, 0), n_moments)
    sel = (ang >= lo_deg) & (ang <= hi_deg)
    rebuilt = phase_from_moments(chi, np.cos(np.radians(ang[sel])))  # (A, R, W)
    table = np.moveaxis(profile.aerosol_phase, 1, 0)[sel]
    return float(np.max(np.abs(rebuilt / table - 1.0)))
