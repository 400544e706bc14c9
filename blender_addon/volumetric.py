"""Volumetric mode: the atmosphere as stacked, non-overlapping Cycles volumes around the planet.

Geometry
    The planet (radius R = 6360 km, the core's) is centred at (0, 0, -R): the scene origin
    is on the ground, +Z up, the camera near the origin. The layered profile of the core
    (``skymodel.optics.shells.volume_shells``, on the edges of its ``layer_edges``: equal shares of the
    column of ``extinction(550 nm) ** 0.3``, which keeps the sunlit upper air of twilight in
    thin layers; per-layer mean coefficients) becomes

    * one Cycles volume object per layer, and **no two of them overlap**: the lowest layer is a
      closed **ball** (radius R + its top edge; the camera is inside it), every layer above is a
      closed **shell** (an outer sphere and an inward-facing inner sphere). Each holds its
      layer's whole medium: every scattering species and the absorption. Their surfaces sit
      ``SHELL_INSET_M`` (20 m) inside the layer's edges, because coincident boundaries render
      wrong, and the coefficients are scaled by thickness / (thickness - insets) so each layer
      keeps its vertical optical depth; the 40 m gaps at the edges hold nothing, and
      :func:`rgb_model_profile` models them as empty layers, so the marcher's comparison medium
      is exactly what Cycles holds.

      Why not nested balls carrying coefficient differences (overlapping Cycles volumes add,
      which was the first design): where several volumes overlap, Cycles merges their equal
      phase closures (``volume_shader_merge_closures``), and with more than one kind of phase
      closure per volume (Rayleigh + two aerosol HG lobes) the merged mixture came out wrong
      (measured, 64x32 single scattering: with two HG lobes g = 0.6 and 0 in two nested balls,
      +12 % on the sun side; the same lobes given g differing by 1e-3 between the balls, so
      nothing merges, or put in non-overlapping shells: within 0.6 %). With the rural aerosol
      and 8 layers the nested balls rendered 5-11 % dark. Non-overlapping volumes never merge,
      hold at most 5 closures at a point (under Cycles' 8 phase closures) and need no
      non-negative split of the coefficients.
    * the **ground**: a sphere of radius R with a diffuse BSDF of the ground albedo,
      lowered by ``GROUND_DROP_M`` (1 cm) so it does not z-fight a ground plane at z = 0.

    All spheres share one angular tessellation (so they never cross), built with numpy:
    the pole above/below the camera, ring spacing dtheta(theta) = sqrt(8 max(s0, f R
    theta) / R) with s0 = 0.5 m and f = 1e-4, i.e. the chord sag is at most 0.5 m within
    ~5 km of the camera and at most 1e-4 of the distance beyond (10 m at 100 km), and
    ``SEGMENTS`` = 256 around (azimuthal sag 7.5e-5 of the distance: 0.37 m at the first
    ring, 5 km away). See :func:`sag_report`.

Media (Volume Coefficients nodes, Blender >= 4.5)
    Per layer: molecules with the RAYLEIGH phase (scatter = the layer's Rayleigh coefficient,
    absorption = its ozone + aerosol absorption), and per aerosol
    regime (troposphere, stratosphere) two Henyey-Greenstein lobes from the core's
    double-HG fit (:func:`skymodel.optics.phase_fit.fit_phase`, first moment kept exactly) of
    the regime's phase table averaged over wavelength with the weights below.

RGB projection
    Cycles is RGB. A spectral coefficient sigma(lambda) becomes, per channel c,
    ``sigma_c = sum(w_c sigma) / sum(w_c)`` with ``w_c(lambda) = E_sun(lambda) *
    rbar_c(lambda) * dlambda``, ``rbar_c`` the Rec.709 colour-matching functions
    (``M_709 @ (xbar, ybar, zbar)``, negative lobes included) and E_sun the
    extraterrestrial solar spectrum: exact for optically thin single scattering of
    sunlight (sky radiance per channel = E_c sigma_c p), approximate once transmittance
    along long paths matters (low sun). The sun lamp carries the *extraterrestrial*
    irradiance (strength E_Y, colour RGB(E) / E_Y): Cycles attenuates it through the
    volumes. The error of this projection against the spectral renderer is measured by
    ``benchmarks/bench_blender.py`` (docs/blender.md).

    Where species overlap, Cycles mixes their phase functions with one weight per closure in
    all channels, so each layer's scattering is split between the closures with one share per
    species (:func:`closure_split`), luminance-weighted; :func:`rgb_model_profile` holds the
    same split, and ``tests/test_addon_crossval.py`` checks Cycles against the marcher on it.
"""

from __future__ import annotations

import math
import time

import numpy as np

from skymodel.colorimetry import cmf_weights, xyz_to_rgb_matrix
from skymodel.errors import SkymodelInputError
from skymodel.optics.phase_fit import fit_phase, hg
from skymodel.optics.profile import LayeredProfile
# the shells' edges and the twilight floor have one home in the core (the planner reads them too)
from skymodel.optics.shells import EDGE_EXPONENT, TWILIGHT_MIN_LAYERS, layer_edges, volume_shells  # noqa: F401
from skymodel.render.environment import environment_camera
from skymodel.render.exposure import display_exposure
from skymodel.render.sky import render_sky
from skymodel.wavelengths import default_wavelengths

from .physics import LUMA_709, SkyResult, fit_into_gamut, spectrum_rgb, sun_lamp

#: Spectral grid of the projection (nm).
WAVELENGTH_STEP_NM = 10.0
#: Sag tolerances of the sphere tessellation: absolute near the camera, relative beyond.
SAG_ABS_M = 0.5
SAG_REL = 1e-4
SEGMENTS = 256
#: Volume surfaces sit this far inside their layer's edges (at most a tenth of the layer), so
#: no two surfaces coincide; 40x the float32 spacing of vertex coordinates at the planet radius.
SHELL_INSET_M = 20.0
#: The ground sphere is lowered by this much (no z-fighting with a plane at z = 0).
GROUND_DROP_M = 0.01
#: Cycles evaluates at most 8 phase closures at a point (MAX_VOLUME_CLOSURE); one volume holds
#: 1 (Rayleigh) + 2 lobes per aerosol regime.
MAX_PHASE_CLOSURES = 8
#: Volume spheres: the apex of the top triangle fan sits this fraction of the first ring's
#: polar angle off the Z axis (see :func:`sphere_arrays`).
APEX_OFFSET = 0.3
#: Size of the core render that sets the exposure in this mode.
EXPOSURE_IMAGE_WIDTH = 128


# --------------------------------------------------------------------------- geometry


def ring_angles(radius_m: float, sag_abs_m: float = SAG_ABS_M, sag_rel: float = SAG_REL) -> np.ndarray:
    """Polar angles (rad, from the pole above the camera, 0..pi) of the rings."""
    th = [0.0]
    while th[-1] < math.pi:
        t = th[-1]
        d = math.sqrt(8.0 * max(sag_abs_m, sag_rel * radius_m * t) / radius_m)
        d = min(d, math.pi / 32)
        th.append(min(math.pi, t + d))
        if math.pi - th[-1] < 0.25 * d:  # avoid a sliver ring at the far pole
            th[-1] = math.pi
    return np.asarray(th)


def sag_report(radius_m: float = 6_360_000.0) -> dict:
    """Chord sags of the tessellation (metres) near the camera and at a few distances."""
    th = ring_angles(radius_m)
    dth = np.diff(th)
    ring_sag = radius_m * (1 - np.cos(dth / 2))
    dphi = 2 * math.pi / SEGMENTS
    out = {"rings": int(th.size), "segments": SEGMENTS, "faces": int((th.size - 1) * SEGMENTS)}
    for km in (0, 5, 20, 100, 1000):
        t = km * 1000.0 / radius_m
        k = int(np.clip(np.searchsorted(th, t, side="right") - 1, 0, dth.size - 1))
        az_sag = radius_m * math.sin(max(t, th[1])) * (1 - math.cos(dphi / 2))
        out[f"sag_at_{km}km_m"] = float(max(ring_sag[k], az_sag if km else 0.0))
    return out


def sphere_arrays(radius_m: float, centre_z: float, thetas: np.ndarray, segments: int = SEGMENTS,
                  inward: bool = False, apex_off_axis: bool = False):
    """Vertices (n, 3) float64 and polygons (triangle fans at the poles, quads between) of
    a sphere with its first pole at the top (above the camera).

    ``apex_off_axis``: the apex of the top fan is moved off the Z axis, onto the sphere at
    ``APEX_OFFSET`` of the first ring's polar angle and half a segment in azimuth, so that a
    ray going straight up from a point on the axis meets the inside of one triangle, never
    the vertex shared by all ``segments`` fan triangles. Cycles finds the volumes that
    contain the camera with such a ray (a probe along +Z from the camera); through the
    shared vertex the probe missed balls, and near the zenith whole fan sectors rendered
    without the lowest layer (measured: -29 % in the top row of a 128x64 panorama; see
    docs/blender.md). Used for every volume surface; the ground keeps its pole under the camera."""
    inner = thetas[1:-1]
    phi = np.arange(segments) * (2 * math.pi / segments)
    st, ct = np.sin(inner)[:, None], np.cos(inner)[:, None]
    ring = np.stack([radius_m * st * np.cos(phi), radius_m * st * np.sin(phi),
                     np.broadcast_to(radius_m * ct, (inner.size, segments))], axis=-1).reshape(-1, 3)
    if apex_off_axis:
        ta, pa = APEX_OFFSET * thetas[1], math.pi / segments
        top = radius_m * np.array([[math.sin(ta) * math.cos(pa), math.sin(ta) * math.sin(pa), math.cos(ta)]])
    else:
        top = np.array([[0.0, 0.0, radius_m]])
    bottom = np.array([[0.0, 0.0, -radius_m]])
    verts = np.concatenate([top, ring, bottom])
    verts[:, 2] += centre_z
    n_r = inner.size
    idx = 1 + np.arange(n_r * segments).reshape(n_r, segments)
    nxt = np.roll(idx, -1, axis=1)
    # quads between ring k and k+1, outward winding (counter-clockwise seen from outside)
    quads = np.stack([idx[:-1], idx[1:], nxt[1:], nxt[:-1]], axis=-1).reshape(-1, 4)
    top_tris = np.stack([np.zeros(segments, int), idx[0], nxt[0]], axis=-1)
    last = verts.shape[0] - 1
    bot_tris = np.stack([np.full(segments, last), nxt[-1], idx[-1]], axis=-1)
    if inward:
        quads = quads[:, ::-1]
        top_tris = top_tris[:, ::-1]
        bot_tris = bot_tris[:, ::-1]
    return verts, top_tris, quads, bot_tris


# --------------------------------------------------------------------------- media


def rgb_weights(wavelengths_nm, solar_irradiance) -> np.ndarray:
    """(n_wl, 3) projection weights, each column summing to 1 (see module doc)."""
    W = cmf_weights(wavelengths_nm) @ xyz_to_rgb_matrix("rec709").T  # (n_wl, 3)
    w = np.asarray(solar_irradiance, float)[:, None] * W
    return w / w.sum(axis=0, keepdims=True)


def project(coeff, weights) -> np.ndarray:
    """Spectral coefficients (..., n_wl) -> RGB (..., 3)."""
    return np.asarray(coeff, float) @ weights


def closure_split(species, channel_weights) -> list:
    """Per-closure scatter coefficients that Cycles' phase mixing renders right in luminance.

    Cycles mixes the phase functions of all scatter closures at a point with one weight per
    closure, the mean of its RGB coefficient (its "sample weight"), the same in every
    channel; the channel's total scattering coefficient is kept. Measured (docs/blender.md):
    Rayleigh + a stratospheric HG lobe in one ball render like the marcher on a medium whose
    aerosol share of scattering is mean(sigma_aer) / mean(sigma_s) in all three channels, not
    sigma_aer,c / sigma_s,c per channel (-9 % in R, +3 % in B near the sun without this).

    So each layer's species ``species`` (list of (n_layer, 3) coefficients) are re-split: the
    total ``sigma_s,c`` stays per channel, and species k gets ``f_k sigma_s,c`` with the one
    share ``f_k = sum_c u_c sigma_k,c / sum_c u_c sigma_s,c``, ``u = channel_weights`` (the
    luminance weights times the sun's RGB): single scattering of sunlight then has the right
    luminance at every scattering angle (optically thin limit), and the per-channel share is
    what Cycles mixes anyway, so the marcher's RGB model (:func:`rgb_model_profile`) and
    Cycles hold the same medium. The chroma of the aureole is what the split cannot keep."""
    sp = [np.maximum(np.asarray(c, float), 0.0) for c in species]
    total = sum(sp)
    u = np.asarray(channel_weights, float)
    den = total @ u
    out = []
    for c in sp:
        share = np.where(den > 0, (c @ u) / np.where(den > 0, den, 1.0), 0.0)
        out.append(share[:, None] * total)
    return out


def regime_phase_fits(profile, weights, column_scattering_by_regime):
    """(n_regime) list of (w, g1, g2) double-HG lobes, or None for an empty regime."""
    fits = []
    for r in range(profile.aerosol_phase.shape[0]):
        col = column_scattering_by_regime[r]  # (n_wl,)
        wsum = (weights * col[:, None]).sum(axis=1)  # weight of each wavelength
        if not np.any(col > 0) or not wsum.sum() > 0:
            fits.append(None)
            continue
        wl_w = np.maximum(wsum, 0.0)
        wl_w = wl_w / wl_w.sum()
        table = profile.aerosol_phase[r] @ wl_w  # (n_angle,)
        f = fit_phase(profile.aerosol_phase_angles_deg, table[:, None])
        fits.append({"w": float(f.dhg_w[0]), "g1": float(f.dhg_g1[0]), "g2": float(f.dhg_g2[0]),
                     "g": float(f.g[0]), "hg_error": float(f.hg_error[0]), "dhg_error": float(f.dhg_error[0])})
    return fits


def layer_volumes(edges_m) -> list:
    """Surfaces of the per-layer volumes (metres above the ground): for each layer
    ``(bottom_m, top_m, scale)``, ``bottom_m`` None for the lowest (a ball), the surfaces inset by
    ``SHELL_INSET_M`` (at most a tenth of the layer) and ``scale`` = thickness / inset thickness,
    which keeps the layer's vertical optical depth."""
    e = np.asarray(edges_m, float)
    out = []
    for i in range(e.size - 1):
        lo, hi = float(e[i]), float(e[i + 1])
        inset = min(SHELL_INSET_M, 0.1 * (hi - lo))
        bottom = None if i == 0 else lo + inset
        top = hi - inset
        out.append((bottom, top, (hi - lo) / (top - (lo if bottom is None else bottom))))
    return out


#: Measured layering error in twilight (sun -4 degrees, rural, June, 64x32 sky above the horizon):
#: layers -> (rms, worst pixel) relative luminance, with ``skymodel.optics.shells.EDGE_EXPONENT`` edges.
TWILIGHT_LAYER_ERROR = {8: (0.137, 0.297), 16: (0.057, 0.089), 24: (0.033, 0.087)}


def twilight_warning(sun_elevation_deg: float, n_layers: int) -> str:
    """A sentence for the panel when the layers cannot carry this sun within 10 % ("" if they can)."""
    if sun_elevation_deg >= 0.0 or int(n_layers) >= TWILIGHT_MIN_LAYERS:
        return ""
    known = [n for n in sorted(TWILIGHT_LAYER_ERROR) if n <= int(n_layers)]
    if known:
        rms, worst = TWILIGHT_LAYER_ERROR[known[-1]]
        err = f"about {100 * rms:.0f} % rms, {100 * worst:.0f} % worst at {known[-1]} layers"
    else:
        err = "more than 30 % worst"
    return (f"Twilight: {int(n_layers)} layers carry the sunlit upper air with {err} (sun -4°); use "
            f"{TWILIGHT_MIN_LAYERS}+ layers or Environment mode")


def volume_layers(sky, n_layers: int):
    """One volume per layer (plain dicts, radii in metres above the ground; see the module doc)
    and the spectral pieces the projection used."""
    wl = default_wavelengths(WAVELENGTH_STEP_NM)
    prof = sky.profile(wl)
    lay = volume_shells(prof, int(n_layers))
    weights = rgb_weights(wl, prof.solar_irradiance)
    edges = np.asarray(lay.edges_m, float)
    ray = project(lay.rayleigh_scattering, weights)
    # a channel can come out slightly negative where the colour-matching functions are
    # (ozone in blue: -6e-9 m^-1); negative absorption is not physical: clip at 0
    absn = np.maximum(project(lay.ozone_absorption + lay.aerosol_absorption, weights), 0.0)
    aer = [project(a, weights) for a in lay.aerosol_scattering_by_regime]
    column = [lay.vertical_optical_depth(a) for a in lay.aerosol_scattering_by_regime]
    fits = regime_phase_fits(prof, weights, column)
    sun_rgb = spectrum_rgb(prof.solar_irradiance, wl)
    mixed = closure_split([ray] + aer, LUMA_709 * sun_rgb)
    species = [("rayleigh", mixed[0])] + [(f"aerosol{r}", mixed[1 + r]) for r in range(len(aer))]
    phases = {"rayleigh": {"phase": "RAYLEIGH"}}
    for r, f in enumerate(fits):
        phases[f"aerosol{r}"] = None if f is None else dict(f, lobes=2)
    volumes = []
    for i, (bottom, top, scale) in enumerate(layer_volumes(edges)):
        scatter = {name: [float(v * scale) for v in c[i]] for name, c in species
                   if np.any(c[i] > 0) and (name == "rayleigh" or phases[name])}
        volumes.append({"layer": i, "bottom_m": bottom, "top_m": top, "scale": scale,
                        "absorption": [float(v * scale) for v in absn[i]], "scatter": scatter})

    def closures(v):
        return sum(1 if k == "rayleigh" else phases[k]["lobes"] for k in v["scatter"])

    most = max(closures(v) for v in volumes)
    if most > MAX_PHASE_CLOSURES:  # cannot happen with two regimes; kept as the contract
        raise SkymodelInputError(
            "n_layers", n_layers, f"{most} phase closures in one volume; Cycles evaluates at most {MAX_PHASE_CLOSURES}")
    albedo = spectrum_rgb(prof.ground_albedo * prof.solar_irradiance, wl) / np.maximum(
        spectrum_rgb(prof.solar_irradiance, wl), 1e-30)
    return {
        "edges_m": [float(e) for e in edges],
        "volumes": volumes,
        "phases": phases,
        "ground_albedo_rgb": [float(np.clip(a, 0.0, 1.0)) for a in albedo],
        "closures_per_volume": most,
        # per-layer scatter coefficient of each closure species (R, G, B), after closure_split,
        # before the inset scaling
        "closure_scattering": {name: c for name, c in species},
        "weights": weights,
        "profile": prof,
        "layered": lay,
    }


#: Pseudo-wavelengths of :func:`rgb_model_profile` (B, G, R order) and the index that reorders to R, G, B.
PSEUDO_WL = np.array([450.0, 550.0, 650.0])
TO_RGB = [2, 1, 0]


def rgb_model_profile(vol):
    """The medium the Cycles volumes hold, as a core ``LayeredProfile`` on three pseudo-wavelengths
    (``PSEUDO_WL``, standing for B, G, R: reorder a result with ``[..., TO_RGB]``): every volume's
    projected RGB coefficients as its material carries them (scattering split between the species
    by :func:`closure_split`, inset-scaled, absorption clipped at 0), the empty gaps between the
    volumes as layers of their own, Rayleigh without depolarisation (Cycles' RAYLEIGH phase), the
    fitted aerosol lobes and the RGB extraterrestrial sun. The core's marcher renders it for a
    like-for-like comparison with Cycles (``tests/test_addon_crossval.py``, ``benchmarks/bench_blender.py``)."""
    lay, prof = vol["layered"], vol["profile"]
    n_regime = lay.aerosol_scattering_by_regime.shape[0]
    names = ["rayleigh"] + [f"aerosol{r}" for r in range(n_regime)]
    edges = [0.0]
    coeff = {k: [] for k in names + ["absorption"]}
    for v in vol["volumes"]:
        if v["bottom_m"] is not None:  # the gap below this volume: empty
            edges.append(v["bottom_m"])
            for k in coeff:
                coeff[k].append(np.zeros(3))
        edges.append(v["top_m"])
        for k in names:
            coeff[k].append(np.asarray(v["scatter"].get(k, (0.0, 0.0, 0.0)), float))
        coeff["absorption"].append(np.asarray(v["absorption"], float))
    edges.append(float(lay.top_altitude_m))  # the gap under the top of the atmosphere
    for k in coeff:
        coeff[k].append(np.zeros(3))
    c = {k: np.stack(val)[:, TO_RGB] for k, val in coeff.items()}

    angles = prof.aerosol_phase_angles_deg
    mu = np.cos(np.radians(angles))
    tables = []
    for r in range(n_regime):
        f = vol["phases"].get(f"aerosol{r}")
        if f is None:
            t = np.full(angles.shape, 1 / (4 * np.pi))
        else:
            t = f["w"] * hg(mu, f["g1"]) + (1 - f["w"]) * hg(mu, f["g2"])
        tables.append(np.repeat(t[:, None], 3, axis=1))
    sun_rgb = spectrum_rgb(prof.solar_irradiance, prof.wavelengths_nm)
    return LayeredProfile(
        wavelengths_nm=PSEUDO_WL, rayleigh_depolarization=np.zeros(3), aerosol_phase_angles_deg=angles,
        aerosol_phase=np.stack(tables), ground_albedo=np.asarray(vol["ground_albedo_rgb"])[TO_RGB],
        solar_irradiance=sun_rgb[TO_RGB], planet_radius_m=prof.planet_radius_m, top_altitude_m=lay.top_altitude_m,
        edges_m=np.asarray(edges), rayleigh_scattering=c["rayleigh"], ozone_absorption=c["absorption"],
        aerosol_scattering_by_regime=np.stack([c[f"aerosol{r}"] for r in range(n_regime)]),
        aerosol_absorption=np.zeros_like(c["absorption"]))


def compute(sky, cache_dir=None, progress=None) -> SkyResult:
    """Everything the volumetric scene needs (no bpy)."""
    t0 = time.perf_counter()
    p = sky.params
    if progress:
        progress(f"layered profile: {p.n_layers} layers, RGB projection")
    vol = volume_layers(sky, p.n_layers)
    prof = vol["profile"]
    wl = prof.wavelengths_nm
    strength, colour = sun_lamp(prof.solar_irradiance, wl)  # extraterrestrial: Cycles attenuates it
    # exposure: the same rule as Environment mode, from a small core render of the same sky
    if progress:
        progress("small spectral render for the exposure")
    cam = environment_camera(EXPOSURE_IMAGE_WIDTH, n_wavelengths=wl.size)
    img = render_sky(prof, cam, sky.sun_elevation_deg, sky.sun_azimuth_deg, 0.0, "preview", include_sun=False)
    rgb = fit_into_gamut(spectrum_rgb(img.radiance, wl))
    s_obs, _ = sun_lamp(img.sun_irradiance, wl)
    meter = display_exposure(rgb, cam, s_obs, sky.sun_elevation_deg)
    e_h = meter["horizontal_illuminance_Y"]
    res = SkyResult(mode="VOLUMETRIC", sun_elevation_deg=sky.sun_elevation_deg,
                    sun_azimuth_deg=sky.sun_azimuth_deg, sun_strength=strength, sun_colour=colour,
                    sun_angle_deg=sky.sun_angular_diameter_deg(), exposure=meter["exposure"])
    res.layers = vol
    res.ground_albedo_rgb = tuple(vol["ground_albedo_rgb"])
    h = rgb.shape[0]
    luma = rgb @ np.array([0.2126, 0.7152, 0.0722])
    res.info = {"compute_s": time.perf_counter() - t0, "volumes": len(vol["volumes"]),
                "zenith_Y_core": float(luma[0].mean()), "horizon_Y_core": float(luma[h // 2 - 1].mean()),
                "sun_observer_Y": s_obs, "horizontal_illuminance_Y": e_h, "phases": vol["phases"],
                "exposure_incident": meter["exposure_incident"], "exposure_sky": meter["exposure_sky"],
                "sag": sag_report(prof.planet_radius_m)}
    warn = twilight_warning(sky.sun_elevation_deg, p.n_layers)
    if warn:
        res.info["warnings"] = [warn]
        if progress:
            progress("warning: " + warn)
    return res


# --------------------------------------------------------------------------- scene


def _mesh_from_arrays(tx, name, verts, top, quads, bot):
    import bpy  # noqa: F401

    me = tx.new("meshes", name)
    n_poly = top.shape[0] + quads.shape[0] + bot.shape[0]
    loops = np.concatenate([top.ravel(), quads.ravel(), bot.ravel()]).astype(np.int32)
    sizes = np.concatenate([np.full(top.shape[0], 3), np.full(quads.shape[0], 4), np.full(bot.shape[0], 3)])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    me.vertices.add(verts.shape[0])
    me.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    me.loops.add(loops.size)
    me.loops.foreach_set("vertex_index", loops)
    me.polygons.add(n_poly)
    me.polygons.foreach_set("loop_start", starts)
    me.update(calc_edges=True)
    return me


def _join_arrays(a, b):
    """Two sphere surfaces (outer, inner inverted) into one closed shell mesh."""
    va, ta, qa, ba = a
    vb, tb, qb, bb = b
    off = va.shape[0]
    return (np.concatenate([va, vb]), np.concatenate([ta, tb + off]), np.concatenate([qa, qb + off]),
            np.concatenate([ba, bb + off]))


def _volume_material(tx, name, absorption, scatter: dict, phases: dict):
    mat = tx.new("materials", name)
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    closures = []
    y = 0

    def coeff_node(label, phase, g=0.0, sca=(0, 0, 0), ab=(0, 0, 0)):
        nonlocal y
        n = nt.nodes.new("ShaderNodeVolumeCoefficients")
        n.label = label
        n.location = (0, y)
        y -= 320
        n.phase = phase
        if phase == "HENYEY_GREENSTEIN":
            n.inputs["Anisotropy"].default_value = float(g)
        n.inputs["Scatter Coefficients"].default_value = tuple(float(v) for v in sca)
        n.inputs["Absorption Coefficients"].default_value = tuple(float(v) for v in ab)
        closures.append(n.outputs[0])

    ray = scatter.get("rayleigh", (0.0, 0.0, 0.0))
    coeff_node("Molecules (Rayleigh) + absorption", "RAYLEIGH", sca=ray, ab=absorption or (0.0, 0.0, 0.0))
    for key in ("aerosol0", "aerosol1"):
        if key in scatter and phases.get(key):
            f = phases[key]
            s = np.asarray(scatter[key])
            coeff_node(f"{key}: forward lobe g={f['g1']:.3f}", "HENYEY_GREENSTEIN", f["g1"], s * f["w"])
            if f.get("lobes", 2) == 2 and f["w"] < 1.0:
                coeff_node(f"{key}: backward lobe g={f['g2']:.3f}", "HENYEY_GREENSTEIN", f["g2"], s * (1 - f["w"]))
    acc = closures[0]
    for k, sock in enumerate(closures[1:]):
        add = nt.nodes.new("ShaderNodeAddShader")
        add.location = (300, -160 * k)
        nt.links.new(acc, add.inputs[0])
        nt.links.new(sock, add.inputs[1])
        acc = add.outputs[0]
    nt.links.new(acc, out.inputs["Volume"])
    return mat


def _ground_material(tx, albedo_rgb):
    mat = tx.new("materials", "Skymodel Ground")
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*[float(a) for a in albedo_rgb], 1.0)
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    mat.diffuse_color = (*[float(a) for a in albedo_rgb], 1.0)
    return mat


def _object(tx, coll, name, mesh, material):
    obj = tx.new("objects", name, mesh)
    mesh.materials.append(material)
    obj.display_type = "WIRE" if name.endswith("Ground") else "BOUNDS"
    obj.hide_select = True
    tx.link_object(coll, obj)
    return obj


def apply(scene, world, settings, result, progress=None):
    """Volumetric mode scene: black world, sun lamp, one volume per layer, ground, Cycles settings
    (one :func:`builder.build`: all or nothing). Returns the build id."""
    from . import builder

    vol = result.layers
    R = float(vol["profile"].planet_radius_m)
    thetas = ring_angles(R)
    if progress:
        progress(f"meshes: {len(vol['volumes'])} layer volumes, ground "
                 f"({(thetas.size - 1) * SEGMENTS} faces a sphere)")

    def volumes_and_settings(tx, coll):
        for v in vol["volumes"]:
            name = f"Skymodel Atmosphere {v['layer']:02d}"
            outer = sphere_arrays(R + v["top_m"], -R, thetas, apex_off_axis=True)
            if v["bottom_m"] is None:
                arrays = outer
            else:
                arrays = _join_arrays(outer, sphere_arrays(R + v["bottom_m"], -R, thetas, inward=True,
                                                           apex_off_axis=True))
            me = _mesh_from_arrays(tx, name, *arrays)
            mat = _volume_material(tx, name, v["absorption"], v["scatter"], vol["phases"])
            obj = _object(tx, coll, name, me, mat)
            obj["skymodel_top_m"] = v["top_m"]
            if v["bottom_m"] is not None:
                obj["skymodel_bottom_m"] = v["bottom_m"]
        me = _mesh_from_arrays(tx, "Skymodel Ground", *sphere_arrays(R, -R - GROUND_DROP_M, thetas))
        _object(tx, coll, "Skymodel Ground", me, _ground_material(tx, result.ground_albedo_rgb))
        builder.black_world_nodes(tx, world)
        tx.set(scene.render, "engine", "CYCLES")
        cyc = scene.cycles
        nb = int(settings.volume_bounces)
        tx.set(cyc, "volume_bounces", nb)
        tx.set(cyc, "max_bounces", max(int(cyc.max_bounces), nb + 4))
        crossings = 4 * len(vol["volumes"]) + 16  # boundaries are transparent bounces
        tx.set(cyc, "transparent_max_bounces", max(int(cyc.transparent_max_bounces), crossings))
        if scene.camera is not None and scene.camera.type == "CAMERA":
            tx.set(scene.camera.data, "clip_end", max(float(scene.camera.data.clip_end), 2.0e7))

    return builder.build(scene, world, settings, result, volumes_and_settings)
