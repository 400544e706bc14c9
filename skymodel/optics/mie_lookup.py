"""Size-integrated Mie optics of the aerosol components, tabulated once and read at run time.

``python -m skymodel.optics.mie_lookup build [--out PATH] [--components NAME ...] [--wavelengths NM ...]``
writes ``skymodel/data/generated/mie_lookup.npz`` (the default), holding for every component of
``skymodel/data/presets/aerosols/components.toml``, on the default wavelength grid (380-780 nm every 5 nm) and the
scattering-angle grid :func:`default_angles_deg`:

* ``ext``, ``sca`` (n_comp, n_wl): extinction and scattering cross section per particle, m^2, i.e.
  ``C = integral C(r) n(r) dr`` over the component's lognormal normalised to one particle;
* ``g`` (n_comp, n_wl): asymmetry parameter of the size-integrated phase function;
* ``phase`` (n_comp, n_angle, n_wl): size-integrated phase function, sr^-1, normalised to 1 over 4 pi
  with the quadrature of :func:`phase_integral` (piecewise linear in angle, the interpolation the
  renderers use);
* ``phase_norm_raw`` (n_comp, n_wl): the 4 pi integral of the phase function *before* that
  renormalisation - how well the angle grid samples it (1 within ~1e-3 is good);
* ``angles_deg``, ``wavelengths_nm``, ``components`` (names), ``r_mod_um``, ``sigma``, ``n``/``k``
  (the refractive index used at each wavelength).

Size integration
----------------
The integral over the lognormal is done with the trapezoid rule on nodes that are even in a smooth
coordinate: even in ``ln r`` for small particles (``XS_POINTS_PER_SIGMA`` nodes per ``ln sigma``),
even in ``r`` for large ones (a size-parameter step ``XS_STEP_X`` at 380 nm, so that the interference
structure of Q(x), period ~ pi / (n - 1), is sampled many times per period), see :func:`size_grid`.
The grid runs from ``ln r_mod - 5 ln sigma`` to ``ln r_mod + 6 ln sigma`` (the area-weighted
distribution, which carries the extinction of large particles, is shifted by ``+2 ln sigma`` and is
then covered to +4 of its sigma), raised for components of small particles (where scattering weighs
r^6, a shift of +6 ln sigma) to at least ``min(r_mod sigma^9, 3 um)``. Q(x) is cheap, so the grid is
fine enough that the cross sections converge to ~1e-5 even for the (nearly) non-absorbing components
whose ripple resonances are sampled, not resolved; :func:`convergence_report` checks it (refining twice
and widening the range; ``python -m skymodel.optics.mie_lookup check``). The phase function, whose cost grows
with the number of angles, uses a coarser size grid (``PHASE_POINTS_PER_SIGMA``, ``PHASE_STEP_X``)
and is renormalised.

The Mie series itself is :mod:`skymodel.optics.mie` (vectorised Lorentz-Mie; ``m = n + ik``, ``k >= 0``).
Refractive indices are interpolated linearly in wavelength between the rows of the component's CSV.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from skymodel.optics import mie
from skymodel.data import DATA_DIR, csv_columns, load_toml
from skymodel.errors import SkymodelInputError
from skymodel.wavelengths import default_wavelengths

#: Default location of the lookup table.
DEFAULT_LOOKUP = Path("generated") / "mie_lookup.npz"

#: Size grid of the cross sections and ``g``: nodes per ln(sigma) where the grid is even in ln r,
#: and the radius step (um) where it is even in r (``XS_STEP_X`` in size parameter at 380 nm).
XS_POINTS_PER_SIGMA = 1024
XS_STEP_X = 0.25
#: Coarser size grid of the phase function (its 4 pi integral is renormalised anyway).
PHASE_POINTS_PER_SIGMA = 96
PHASE_STEP_X = 2.0
#: Shortest wavelength (nm) the radius step is referred to.
REFERENCE_WAVELENGTH_NM = 380.0
#: Lower end of the size grid, in units of ln(sigma) below ln(r_mod).
LOWER_SIGMAS = 5.0
#: Upper end of the size grid, in units of ln(sigma) above ln(r_mod) (see module docstring).
UPPER_SIGMAS = 6.0
#: For components of small particles the upper end reaches at least min(r_mod sigma^9, 3 um).
UPPER_SIGMAS_SMALL = 9.0
SMALL_PARTICLE_LIMIT_UM = 3.0


def default_angles_deg() -> np.ndarray:
    """Scattering-angle grid, degrees (385 angles): 0, then steps growing with the angle,
    ``d theta = 0.015 + 0.016 theta`` (0.015 deg at the forward peak, which is ~0.1-1 deg wide
    for the coarse modes; ~0.1 deg at 5 deg), until the step reaches 1 deg (near 61 deg), then
    every degree to 180. With the linear interpolation in angle used downstream, the
    un-renormalised 4 pi integral of every component is 1 within 4e-4 (``phase_norm_raw``)."""
    th = [0.0]
    while 0.015 + 0.016 * th[-1] < 1.0:
        th.append(th[-1] + 0.015 + 0.016 * th[-1])
    return np.concatenate([th, np.arange(np.floor(th[-1]) + 1.0, 180.5, 1.0)])


def phase_integral(phase, angles_deg, axis: int = 0) -> np.ndarray:
    """``2 pi * integral p(theta) sin(theta) dtheta`` for ``p`` piecewise linear in theta on
    ``angles_deg`` (exact for that interpolant), along ``axis``."""
    th = np.radians(np.asarray(angles_deg, dtype=float))
    p = np.moveaxis(np.asarray(phase, dtype=float), axis, 0)
    t0, t1 = th[:-1], th[1:]
    d = t1 - t0
    # integral over [t0, t1] of (p0 (t1 - t) + p1 (t - t0)) / d * sin t dt, from the antiderivatives
    # of (t1 - t) sin t, -(t1 - t) cos t - sin t, and of (t - t0) sin t, -(t - t0) cos t + sin t
    w0 = (d * np.cos(t0) + np.sin(t0) - np.sin(t1)) / d
    w1 = (np.sin(t1) - np.sin(t0) - d * np.cos(t1)) / d
    shape = (-1,) + (1,) * (p.ndim - 1)
    total = (p[:-1] * w0.reshape(shape) + p[1:] * w1.reshape(shape)).sum(axis=0)
    return 2.0 * np.pi * total


def components_table() -> dict[str, dict]:
    """``skymodel/data/presets/aerosols/components.toml`` -> {name: entry}."""
    return dict(load_toml("presets/aerosols/components.toml")["components"])


def refractive_index(component: str, wavelengths_nm) -> np.ndarray:
    """Complex index ``n + ik`` (k >= 0) of ``component`` at ``wavelengths_nm`` (linear interpolation)."""
    return refractive_index_file(components_table()[component]["refractive_index"], wavelengths_nm)


def refractive_index_file(filename: str, wavelengths_nm) -> np.ndarray:
    """Complex index ``n + ik`` (k >= 0) of ``sources/refractive_index/<filename>`` at ``wavelengths_nm``."""
    cols = csv_columns("sources/refractive_index/" + filename)
    wl = np.asarray(wavelengths_nm, dtype=float)
    lo, hi = cols["wavelength_nm"][0], cols["wavelength_nm"][-1]
    if np.any(wl < lo) or np.any(wl > hi):
        raise SkymodelInputError("wavelengths", wl.tolist(), f"wavelengths in [{lo:g}, {hi:g}] nm for {filename}")
    n = np.interp(wl, cols["wavelength_nm"], cols["n"])
    k = np.interp(wl, cols["wavelength_nm"], cols["k"])
    return n + 1j * k


def lognormal_area_tail(r_mod_um: float, sigma: float, r_um: float) -> float:
    """Geometric cross section (m^2 per particle) of the particles larger than ``r_um`` in a
    lognormal normalised to one particle: ``integral_{r}^inf pi r'^2 n(r') dr'`` =
    ``pi r_mod^2 exp(2 ln^2 sigma) erfc((ln(r / r_mod) - 2 ln^2 sigma) / (sqrt 2 ln sigma)) / 2``."""
    from math import erfc, exp, log, pi, sqrt

    ls = log(sigma)
    return 0.5 * pi * (r_mod_um * 1e-6) ** 2 * exp(2.0 * ls * ls) * erfc((log(r_um / r_mod_um) - 2.0 * ls * ls)
                                                                        / (sqrt(2.0) * ls))


def size_grid(r_mod_um: float, sigma: float, points_per_sigma: float = XS_POINTS_PER_SIGMA,
              step_x: float = XS_STEP_X, lower_sigmas: float = LOWER_SIGMAS, upper_sigmas: float = UPPER_SIGMAS,
              r_max_um: float | None = None):
    """Radii (um) and weights ``w`` such that ``sum w f(r)`` approximates
    ``integral f(r) dN/dln r dln r`` for the lognormal normalised to one particle.

    The nodes are even in a coordinate ``s`` with ``ds/du = sqrt(a^2 + (e^u / dr)^2)``, ``u = ln r``,
    ``a = points_per_sigma / ln sigma``, ``dr = step_x * 380 nm / (2 pi)``: even in ln r for small
    particles, even in r (size-parameter step ``step_x`` at 380 nm, resolving the interference
    structure of Q(x)) for large ones, with a smooth transition; the trapezoid rule in ``s`` keeps
    its accuracy for smooth integrands. ``r_max_um`` (um) ends the grid there if it would go further
    (the rest of the distribution is then :func:`lognormal_area_tail`'s).
    """
    ls = np.log(sigma)
    u_mod = np.log(r_mod_um)
    u_lo = u_mod - lower_sigmas * ls
    u_hi = max(u_mod + upper_sigmas * ls, np.log(min(r_mod_um * sigma**UPPER_SIGMAS_SMALL, SMALL_PARTICLE_LIMIT_UM)))
    if r_max_um is not None:
        u_hi = min(u_hi, np.log(r_max_um))
    a = points_per_sigma / ls
    b = 2.0 * np.pi / (step_x * REFERENCE_WAVELENGTH_NM * 1e-3)  # 1 / dr, um^-1
    uf = np.linspace(u_lo, u_hi, 400_001)
    q = np.sqrt(a * a + (b * np.exp(uf)) ** 2)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (q[1:] + q[:-1]) * np.diff(uf))])
    n = int(np.ceil(s[-1])) + 1
    sn = np.linspace(0.0, s[-1], n)
    un = np.interp(sn, s, uf)
    un[0], un[-1] = u_lo, u_hi
    qn = np.sqrt(a * a + (b * np.exp(un)) ** 2)
    pdf = np.exp(-0.5 * ((un - u_mod) / ls) ** 2) / (np.sqrt(2.0 * np.pi) * ls)
    w = pdf / qn * (sn[1] - sn[0])
    w[0] *= 0.5
    w[-1] *= 0.5
    return np.exp(un), w


def integrate_component(m, wavelengths_nm, r_mod_um: float, sigma: float, angles_deg=None,
                        points_per_sigma: float = XS_POINTS_PER_SIGMA, step_x: float = XS_STEP_X,
                        lower_sigmas: float = LOWER_SIGMAS, upper_sigmas: float = UPPER_SIGMAS,
                        phase_points_per_sigma: float = PHASE_POINTS_PER_SIGMA,
                        phase_step_x: float = PHASE_STEP_X, r_max_um: float | None = None) -> dict:
    """Size-integrated cross sections ``ext``, ``sca`` (m^2 per particle) and asymmetry ``g`` for
    the refractive indices ``m`` (one per wavelength), and, if ``angles_deg`` is given, the
    size-integrated phase function ``phase`` (n_angle, n_wl), sr^-1, on a coarser size grid.

    ``r_max_um``: particles larger than this (um) keep the efficiencies, asymmetry and phase function
    of a sphere of radius ``r_max_um`` (the large-particle limit, Q_ext -> 2: at x = 2 pi r / lambda
    >= 400 the change of Q_ext beyond is below ~1 %), weighted by their exact geometric cross
    section (:func:`lognormal_area_tail`). None (the components of components.toml): no limit."""
    wl = np.atleast_1d(np.asarray(wavelengths_nm, dtype=float))
    m = np.broadcast_to(np.asarray(m, dtype=complex), wl.shape)
    r_um, w = size_grid(r_mod_um, sigma, points_per_sigma, step_x, lower_sigmas, upper_sigmas, r_max_um)
    tail = 0.0 if r_max_um is None else lognormal_area_tail(r_mod_um, sigma, r_max_um)  # m^2 per particle
    geo_w = np.pi * (r_um * 1e-6) ** 2 * w  # m^2 per particle
    ext = np.empty(wl.size)
    sca = np.empty(wl.size)
    g = np.empty(wl.size)
    phase = None
    if angles_deg is not None:
        mu = np.clip(np.cos(np.radians(np.asarray(angles_deg, dtype=float))), -1.0, 1.0)
        r_p, w_p = size_grid(r_mod_um, sigma, phase_points_per_sigma, phase_step_x, lower_sigmas, upper_sigmas,
                             r_max_um)
        geo_p = np.pi * (r_p * 1e-6) ** 2 * w_p
        phase = np.empty((mu.size, wl.size))
    for j, (lam, mj) in enumerate(zip(wl, m)):
        eff = mie.efficiencies(mj, 2.0 * np.pi * r_um / (lam * 1e-3))
        csca = eff.qsca * geo_w
        ext[j] = np.sum(eff.qext * geo_w)
        sca[j] = np.sum(csca)
        g[j] = np.sum(eff.g * csca)
        if tail > 0.0:
            x_max = np.array([2.0 * np.pi * r_max_um / (lam * 1e-3)])
            eff_t = mie.efficiencies(mj, x_max)
            ext[j] += float(eff_t.qext[0]) * tail
            sca[j] += float(eff_t.qsca[0]) * tail
            g[j] += float(eff_t.g[0] * eff_t.qsca[0]) * tail
        g[j] /= sca[j]
        if phase is not None:
            x_p = 2.0 * np.pi * r_p / (lam * 1e-3)
            csca_p = mie.efficiencies(mj, x_p).qsca * geo_p
            num = csca_p @ mie.phase_function(mj, x_p, mu)
            den = np.sum(csca_p)
            if tail > 0.0:
                c_t = float(eff_t.qsca[0]) * tail
                num = num + c_t * mie.phase_function(mj, x_max, mu)[0]
                den = den + c_t
            phase[:, j] = num / den
    return {"ext": ext, "sca": sca, "g": g, "phase": phase}


def build_tables(components=None, wavelengths_nm=None, angles_deg=None, verbose: bool = False) -> dict:
    """Compute the lookup arrays (see module docstring) for ``components`` (default: all)."""
    table = components_table()
    names = list(table) if components is None else [str(c) for c in components]
    for name in names:
        if name not in table:
            raise SkymodelInputError("components", name, "names in components.toml: " + ", ".join(table))
    wl = default_wavelengths() if wavelengths_nm is None else np.atleast_1d(np.asarray(wavelengths_nm, float))
    ang = default_angles_deg() if angles_deg is None else np.asarray(angles_deg, dtype=float)
    out = {k: [] for k in ("ext", "sca", "g", "phase", "phase_norm_raw", "n", "k")}
    for name in names:
        t0 = time.perf_counter()
        e = table[name]
        m = refractive_index(name, wl)
        res = integrate_component(m, wl, float(e["r_mod_um"]), float(e["sigma"]), ang)
        norm = phase_integral(res["phase"], ang, axis=0)
        out["ext"].append(res["ext"])
        out["sca"].append(res["sca"])
        out["g"].append(res["g"])
        out["phase"].append(res["phase"] / norm)
        out["phase_norm_raw"].append(norm)
        out["n"].append(m.real)
        out["k"].append(m.imag)
        if verbose:
            print(f"  {name:24s} {time.perf_counter() - t0:7.1f} s   max |norm-1| = {np.max(np.abs(norm - 1)):.1e}",
                  file=sys.stderr, flush=True)
    arrays = {k: np.asarray(v) for k, v in out.items()}
    arrays.update(
        components=np.array(names),
        wavelengths_nm=wl,
        angles_deg=ang,
        r_mod_um=np.array([float(table[n]["r_mod_um"]) for n in names]),
        sigma=np.array([float(table[n]["sigma"]) for n in names]),
        points_per_sigma=np.array([XS_POINTS_PER_SIGMA, PHASE_POINTS_PER_SIGMA], dtype=float),
        step_x=np.array([XS_STEP_X, PHASE_STEP_X]),
    )
    return arrays


def _merge(old: dict, new: dict) -> dict:
    """Replace/append ``new``'s components in ``old`` (grids must agree)."""
    if not (np.array_equal(old["wavelengths_nm"], new["wavelengths_nm"])
            and np.array_equal(old["angles_deg"], new["angles_deg"])):
        return new
    names = list(old["components"])
    merged = {k: list(old[k]) for k in ("ext", "sca", "g", "phase", "phase_norm_raw", "n", "k", "r_mod_um", "sigma")}
    for i, name in enumerate(new["components"]):
        if name in names:
            j = names.index(name)
        else:
            names.append(str(name))
            j = len(names) - 1
            for k in merged:
                merged[k].append(None)
        for k in merged:
            merged[k][j] = new[k][i]
    out = {k: np.asarray(v) for k, v in merged.items()}
    out.update(components=np.array(names), wavelengths_nm=new["wavelengths_nm"], angles_deg=new["angles_deg"],
               points_per_sigma=new["points_per_sigma"], step_x=new["step_x"])
    return out


def build(out=None, components=None, wavelengths_nm=None, verbose: bool = True) -> Path:
    """Build and write the lookup (``out`` default ``skymodel/data/generated/mie_lookup.npz``). When only some
    components are built and ``out`` already holds a table on the same grids, the others are kept."""
    path = Path(out) if out is not None else DATA_DIR / DEFAULT_LOOKUP
    t0 = time.perf_counter()
    arrays = build_tables(components, wavelengths_nm, verbose=verbose)
    if components is not None and path.exists():
        with np.load(path, allow_pickle=False) as z:
            arrays = _merge({k: z[k] for k in z.files}, arrays)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(path)
    if verbose:
        print(f"wrote {path} ({len(arrays['components'])} components) in {time.perf_counter() - t0:.1f} s",
              file=sys.stderr)
    return path


# ------------------------------------------------------------- the paper's model (Eq. 11)

#: Lookup of the paper's model: one entry per (size distribution, refractive index) a type needs.
PAPER_LOOKUP = Path("generated") / "mie_lookup_paper.npz"
#: Its wavelength grid, nm: 380-780 every 20 nm (size-integrated optics of these broad
#: distributions are smooth in wavelength; linear interpolation between the nodes, see
#: skymodel/data/presets/aerosols/README.md for the measured interpolation error).
PAPER_WAVELENGTHS_NM = np.arange(380.0, 781.0, 20.0)
#: Radius (um) above which a sphere's optics are held at their value at this radius (large-particle
#: limit, see integrate_component): x = 827 at 380 nm, 403 at 780 nm. Only the paper's coarse modes
#: (desert 10.8 um, polar 4.3 um median radius) reach it.
PAPER_R_MAX_UM = 50.0
#: Size grids of the paper's entries (coarser than the components' XS_*/PHASE_*: the paper's modes are
#: broad, sigma >= 1.45, which smooths the ripple of Q(x); the regeneration and miepython tests check
#: them): nodes per ln sigma and size-parameter step at 380 nm.
PAPER_XS_GRID = (256, 0.5)
PAPER_PHASE_GRID = (48, 4.0)
#: A mode's grid ends where the geometric cross section of its larger particles falls below this
#: fraction of the whole distribution's (those particles keep the optics of the last node: an error
#: of at most about this fraction); at most PAPER_R_MAX_UM.
PAPER_TAIL_FRACTION = 1e-6


def paper_table() -> dict:
    """``skymodel/data/presets/aerosols/paper.toml``."""
    return load_toml("presets/aerosols/paper.toml")


def paper_entry_name(distribution: str, index: str) -> str:
    """Name of a lookup entry: ``"<distribution>:<refractive index>"``."""
    return f"{distribution}:{index}"


def paper_entries() -> dict[str, dict]:
    """The lookup entries the paper's types need: ``{name: {"distribution", "index", "modes"}}``,
    modes as ``(n_cm3, r_mod_um, sigma)`` (radius = half the tabulated diameter)."""
    t = paper_table()
    out = {}
    for ty in t["types"].values():
        dist = ty["distribution"]
        for comp in ty["table1"]:
            index = t["component_index"][comp]["index"]
            modes = [(float(md["n_cm3"]), 0.5 * float(md["d_um"]), 10.0 ** float(md["log10_sigma"]))
                     for md in t["distributions"][dist]["modes"]]
            out[paper_entry_name(dist, index)] = {"distribution": dist, "index": index, "modes": modes}
    return dict(sorted(out.items()))


def integrate_modes(m, wavelengths_nm, modes, angles_deg=None, r_max_um: float | None = PAPER_R_MAX_UM) -> dict:
    """Size-integrated optics of a sum of lognormals (``modes``: ``(n, r_mod_um, sigma)``), per
    particle of the sum: ``ext``, ``sca`` (m^2), ``g`` and ``phase`` (sr^-1, unnormalised sum of the
    modes' :func:`integrate_component` phase functions weighted by their scattering)."""
    from math import exp, log

    n_tot = sum(n for n, _, _ in modes)
    area = sum(n / n_tot * (r * 1e-6) ** 2 * np.pi * exp(2.0 * log(s) ** 2) for n, r, s in modes)
    ext = sca = g_num = ph_num = 0.0
    for n, r_mod, sigma in modes:
        r_cut = r_max_um
        if r_cut is not None:  # shorten the grid where the rest of the mode does not matter
            lo, hi = r_mod, r_cut
            if n / n_tot * lognormal_area_tail(r_mod, sigma, hi) < PAPER_TAIL_FRACTION * area:
                for _ in range(60):  # bisection in ln r
                    mid = (lo * hi) ** 0.5
                    if n / n_tot * lognormal_area_tail(r_mod, sigma, mid) < PAPER_TAIL_FRACTION * area:
                        hi = mid
                    else:
                        lo = mid
                r_cut = hi
        res = integrate_component(m, wavelengths_nm, r_mod, sigma, angles_deg, r_max_um=r_cut,
                                  points_per_sigma=PAPER_XS_GRID[0], step_x=PAPER_XS_GRID[1],
                                  phase_points_per_sigma=PAPER_PHASE_GRID[0], phase_step_x=PAPER_PHASE_GRID[1])
        f = n / n_tot
        ext = ext + f * res["ext"]
        sca = sca + f * res["sca"]
        g_num = g_num + f * res["sca"] * res["g"]
        if angles_deg is not None:
            ph_num = ph_num + f * res["sca"][None, :] * res["phase"]
    return {"ext": ext, "sca": sca, "g": g_num / sca, "phase": None if angles_deg is None else ph_num / sca[None, :]}


def _paper_entry(args) -> dict:
    name, entry, wl, ang = args
    t0 = time.perf_counter()
    m = refractive_index_file(entry["index"] + ".csv", wl)
    res = integrate_modes(m, wl, entry["modes"], ang)
    norm = phase_integral(res["phase"], ang, axis=0)
    return {"name": name, "ext": res["ext"], "sca": res["sca"], "g": res["g"], "phase": res["phase"] / norm,
            "phase_norm_raw": norm, "n": m.real, "k": m.imag, "seconds": time.perf_counter() - t0}


def build_paper_tables(entries=None, wavelengths_nm=None, angles_deg=None, workers: int = 1,
                       verbose: bool = False) -> dict:
    """The paper-model lookup arrays (as :func:`build_tables`, one row per entry of
    :func:`paper_entries`, or of ``entries``) on ``wavelengths_nm`` (default
    :data:`PAPER_WAVELENGTHS_NM`), computed in ``workers`` processes."""
    table = paper_entries()
    names = list(table) if entries is None else [str(e) for e in entries]
    for name in names:
        if name not in table:
            raise SkymodelInputError("entries", name, "entries of paper_entries(): " + ", ".join(table))
    wl = PAPER_WAVELENGTHS_NM if wavelengths_nm is None else np.atleast_1d(np.asarray(wavelengths_nm, float))
    ang = default_angles_deg() if angles_deg is None else np.asarray(angles_deg, dtype=float)
    jobs = [(n, table[n], wl, ang) for n in names]
    if workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers) as pool:
            results = list(pool.map(_paper_entry, jobs))
    else:
        results = [_paper_entry(j) for j in jobs]
    if verbose:
        for r in results:
            print(f"  {r['name']:36s} {r['seconds']:7.1f} s   max |norm-1| = {np.max(np.abs(r['phase_norm_raw'] - 1)):.1e}",
                  file=sys.stderr, flush=True)
    arrays = {k: np.asarray([r[k] for r in results]) for k in ("ext", "sca", "g", "phase", "phase_norm_raw", "n", "k")}
    arrays.update(components=np.array(names), wavelengths_nm=wl, angles_deg=ang,
                  r_max_um=np.array(PAPER_R_MAX_UM), tail_fraction=np.array(PAPER_TAIL_FRACTION),
                  points_per_sigma=np.array([PAPER_XS_GRID[0], PAPER_PHASE_GRID[0]], dtype=float),
                  step_x=np.array([PAPER_XS_GRID[1], PAPER_PHASE_GRID[1]]))
    return arrays


def build_paper(out=None, workers: int = 2, verbose: bool = True) -> Path:
    """Build and write the paper-model lookup (default ``skymodel/data/generated/mie_lookup_paper.npz``)."""
    path = Path(out) if out is not None else DATA_DIR / PAPER_LOOKUP
    t0 = time.perf_counter()
    arrays = build_paper_tables(workers=workers, verbose=verbose)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(path)
    if verbose:
        print(f"wrote {path} ({len(arrays['components'])} entries) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return path


def convergence_report(component: str, wavelengths_nm=(380.0, 550.0, 780.0)) -> dict:
    """Relative change of ext/sca/g when the size grid is refined twice (node density doubled,
    radius step halved) and widened by 2 ln sigma at both ends: the convergence quoted in
    skymodel/data/presets/aerosols/README.md."""
    e = components_table()[component]
    m = refractive_index(component, wavelengths_nm)
    base = integrate_component(m, wavelengths_nm, float(e["r_mod_um"]), float(e["sigma"]))
    fine = integrate_component(m, wavelengths_nm, float(e["r_mod_um"]), float(e["sigma"]),
                               points_per_sigma=2 * XS_POINTS_PER_SIGMA, step_x=XS_STEP_X / 2,
                               lower_sigmas=LOWER_SIGMAS + 2, upper_sigmas=UPPER_SIGMAS + 2)
    return {k: np.abs(base[k] / fine[k] - 1.0) for k in ("ext", "sca", "g")}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m skymodel.optics.mie_lookup", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="compute and write the lookup table")
    b.add_argument("--out", default=None, help="output .npz (default skymodel/data/generated/mie_lookup.npz)")
    b.add_argument("--components", nargs="+", default=None, help="subset of components.toml (default: all)")
    b.add_argument("--wavelengths", nargs="+", type=float, default=None, help="nm (default 380-780 every 5)")
    bp = sub.add_parser("build-paper", help="compute and write the paper model's lookup (mie_lookup_paper.npz)")
    bp.add_argument("--out", default=None, help="output .npz (default skymodel/data/generated/mie_lookup_paper.npz)")
    bp.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    c = sub.add_parser("check", help="size-integration convergence of some components")
    c.add_argument("components", nargs="*", default=None)
    args = parser.parse_args(argv)
    if args.command == "build":
        build(args.out, args.components, args.wavelengths)
    elif args.command == "build-paper":
        build_paper(args.out, args.workers)
    else:
        for name in args.components or list(components_table()):
            rep = convergence_report(name)
            print(name, {k: float(np.max(v)) for k, v in rep.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
