"""Sky models side by side: one camera, one exposure, one PNG, and the luminance errors.

:func:`compare` asks every model of :mod:`skymodel.models` for the same directions (the
pixels of a fisheye camera looking up, plus a fixed set of sample directions), turns each
answer into CIE XYZ and then linear Rec.709, and tone-maps every panel with **one**
exposure, the one :func:`skymodel.render.image_io.tonemap` picks for our full model
(log-average luminance to middle grey), so brighter or darker skies look brighter or darker.
Models that give only relative luminance (the CIE standard skies, Blender's Preetham and
Hosek-Wilkie) are drawn as D65 grey scaled so that their zenith luminance equals ours.

Luminance errors are taken at the sample directions :data:`VIEW_ZENITH_DEG` x
:data:`VIEW_RELATIVE_AZIMUTH_DEG` (zenith angle, azimuth from the sun; the zenith
counted once), leaving out directions closer than :data:`SUN_EXCLUSION_DEG` to the sun
(no model here draws the disc and its aureole the same way). For each model:

* ``vs_ours_abs``: ``L / L_ours - 1`` (absolute models only), luminance in cd m^-2;
* ``vs_ours_rel`` and ``vs_cie12_rel``: ``(L / L_zenith) / (L_ref / L_ref,zenith) - 1``,
  the shape of the luminance distribution against ours and against the CIE standard clear
  sky (type 12);

each summarised as the RMS and the largest magnitude over the sample directions, as
fractions (0.1 = 10 %).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from skymodel import scene
from skymodel.errors import SkymodelInputError, check_range

#: View zenith angles (degrees) of the sample directions.
VIEW_ZENITH_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 85.0)
#: Azimuths from the sun (degrees) of the sample directions.
VIEW_RELATIVE_AZIMUTH_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
#: Sample directions closer than this to the sun (degrees) are left out of the errors.
SUN_EXCLUSION_DEG = 10.0
#: Models compared by default.
DEFAULT_MODELS = ("ours", "ours_single", "preetham", "openspace_earth", "cie12", "blender_multiple")
#: Height of the label strip above each panel, pixels.
LABEL_HEIGHT = 18


@dataclass
class Comparison:
    """The result of :func:`compare`: per-model luminance at the sample directions and the
    error summaries, the composed image and what was skipped (name -> reason)."""

    models: list
    sample_zenith_deg: np.ndarray
    sample_relative_azimuth_deg: np.ndarray
    luminance: dict  # name -> (n_sample,) cd m^-2, or L/L_zenith for relative models
    metrics: dict  # name -> {...}
    image: np.ndarray | None  # uint8 (H, W, 3)
    skipped: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"models": list(self.models), "skipped": dict(self.skipped),
                "sample_directions": {"view_zenith_deg": self.sample_zenith_deg.tolist(),
                                      "relative_azimuth_deg": self.sample_relative_azimuth_deg.tolist(),
                                      "sun_exclusion_deg": SUN_EXCLUSION_DEG},
                "luminance": {k: np.asarray(v).tolist() for k, v in self.luminance.items()},
                "metrics": self.metrics, "info": self.info}


def sample_directions(sun_elevation_deg: float, sun_azimuth_deg: float = scene.default("sun_azimuth")):
    """``(directions (N, 3), view zenith deg, relative azimuth deg)`` of the error samples:
    the zenith first, then the grid, without directions within SUN_EXCLUSION_DEG of the sun."""
    from skymodel.render.rays import direction_from_angles, sun_direction

    zen = [0.0]
    rel = [0.0]
    for z in VIEW_ZENITH_DEG:
        if z == 0.0:
            continue
        for a in VIEW_RELATIVE_AZIMUTH_DEG:
            zen.append(z)
            rel.append(a)
    zen = np.asarray(zen)
    rel = np.asarray(rel)
    d = np.asarray(direction_from_angles(zen, (sun_azimuth_deg + rel) % 360.0), float).reshape(-1, 3)
    s = np.asarray(sun_direction(sun_elevation_deg, sun_azimuth_deg), float)
    keep = np.degrees(np.arccos(np.clip(d @ s, -1.0, 1.0))) >= SUN_EXCLUSION_DEG
    keep[0] = True  # the zenith is the normalisation point (kept even with the sun overhead)
    return d[keep], zen[keep], rel[keep]


def _error_summary(values: np.ndarray) -> dict:
    v = np.asarray(values, float)
    return {"rms": float(np.sqrt(np.mean(v * v))), "max_abs": float(np.max(np.abs(v)))}


def luminance_metrics(lum: dict, kinds: dict) -> dict:
    """Error summaries of every model against ``ours`` and ``cie12`` (see the module doc);
    ``lum[name]`` is (N,) with the zenith first, ``kinds[name]`` the ModelRadiance kind."""
    out = {}
    ours = lum.get("ours")
    cie = lum.get("cie12")
    for name, L in lum.items():
        L = np.asarray(L, float)
        m = {"kind": kinds[name]}
        rel = L / L[0] if L[0] > 0 else np.full_like(L, np.nan)
        if kinds[name] != "relative":
            m["zenith_luminance_cd_m2"] = float(L[0])
        if ours is not None:
            rel_ours = ours / ours[0]
            if kinds[name] != "relative":
                m["vs_ours_abs"] = _error_summary(L / ours - 1.0)
            m["vs_ours_rel"] = _error_summary(rel / rel_ours - 1.0)
        if cie is not None:
            m["vs_cie12_rel"] = _error_summary(rel / (cie / cie[0]) - 1.0)
        out[name] = m
    return out


def _label_strip(text: str, width: int, height: int = LABEL_HEIGHT) -> np.ndarray:
    """A (height, width, 3) uint8 strip with ``text`` in white (matplotlib), or a plain
    dark strip when matplotlib is not installed."""
    strip = np.full((height, width, 3), 32, np.uint8)
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - matplotlib is optional
        return strip
    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=(32 / 255,) * 3)
    canvas = FigureCanvasAgg(fig)
    # points that fit: a character is ~0.6 em wide, 1 pt = dpi / 72 px
    pts = min(0.5 * height, 0.95 * width / (0.6 * max(len(text), 1) * dpi / 72.0))
    fig.text(0.5, 0.5, text, color="white", ha="center", va="center", fontsize=max(3.0, pts))
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())[:height, :width, :3]
    strip[:rgba.shape[0], :rgba.shape[1]] = rgba
    return strip


def compare(atmosphere, sun_elevation_deg: float, sun_azimuth_deg: float = scene.default("sun_azimuth"),
            models=DEFAULT_MODELS, size: int = scene.default("compare_size"), quality: str | None = None,
            wavelength_step_nm: float = scene.default("compare_wavelength_step"), render_image: bool = True,
            progress=None) -> Comparison:
    """Render ``models`` (names or a comma-separated string) for ``atmosphere`` and the sun,
    side by side. Models that cannot run here (Blender's without ``bpy``) are skipped and
    listed in ``Comparison.skipped``; ``ours`` and ``cie12`` are always evaluated (they are
    the references of the errors) but drawn only when asked for.

    Parameters
    ----------
    atmosphere : :class:`~skymodel.optics.atmosphere.Atmosphere`.
    sun_elevation_deg, sun_azimuth_deg : the sun [deg] (azimuth clockwise from north).
    models : model names (``skymodel.models.model_names()``) or a comma-separated string.
    size : panel size [px] (fisheye).
    quality : the marcher's quality preset; None: the default quality (:mod:`skymodel.scene`).
    wavelength_step_nm : spectral sampling [nm].
    render_image : compose the PNG panels (False: the errors only).
    progress : ``progress(text)`` for one line per model, or None.
    """
    from skymodel.colorimetry import K_M, xyz_to_rgb_matrix
    from skymodel.models import SkyScene, parse_model_list
    from skymodel.models import blender_sky
    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera
    from skymodel.wavelengths import default_wavelengths

    say = progress or (lambda text: None)
    elev = scene.check("sun_elevation", sun_elevation_deg)
    quality = scene.check("quality", scene.default("quality") if quality is None else quality)
    size_p, step_p = scene.parameter("compare_size"), scene.parameter("compare_wavelength_step")
    size = int(check_range("size", size, size_p.minimum, size_p.maximum, "pixels"))
    wanted = parse_model_list(models)
    wl = default_wavelengths(check_range("wavelength_step", wavelength_step_nm, step_p.minimum, step_p.maximum, "nm"))
    sky_scene = SkyScene(atmosphere, elev, float(sun_azimuth_deg), wl, quality)
    d_samp, zen, rel = sample_directions(elev, sun_azimuth_deg)
    cam = make_camera("fisheye", size, n_wavelengths=wl.size) if render_image else None
    if cam is not None:
        dirs, valid = cam.directions()
        d_pix = dirs.reshape(-1, 3)[valid.ravel()]
    else:
        valid = None
        d_pix = np.zeros((0, 3))
    d_all = np.concatenate([d_samp, d_pix]) if d_pix.size else d_samp
    n_s = d_samp.shape[0]
    from skymodel.models import get_model

    todo = list(wanted) + [get_model(n) for n in ("ours", "cie12") if get_model(n) not in wanted]
    blender_sky.PANORAMA_WIDTH = max(64, 2 * size)
    lum, kinds, xyz_pix, skipped, timings, infos = {}, {}, {}, {}, {}, {}
    for m in todo:
        if not m.available():
            skipped[m.name] = f"needs the {m.requires} module (pip install {m.requires}); skipped"
            say(f"{m.name}: {skipped[m.name]}")
            continue
        t0 = time.perf_counter()
        try:
            res = m(sky_scene, d_all)
        except SkymodelInputError as exc:  # e.g. Preetham with the sun below the horizon
            skipped[m.name] = str(exc)
            say(f"{m.name}: skipped: {exc}")
            continue
        timings[m.name] = time.perf_counter() - t0
        say(f"{m.name}: {timings[m.name]:.1f} s")
        L = res.luminance()
        lum[m.name] = L[:n_s]
        kinds[m.name] = res.kind
        infos[m.name] = {k: v for k, v in res.info.items() if isinstance(v, (int, float, str, bool, tuple))}
        xyz_pix[m.name] = res.xyz()[n_s:]
    metrics = luminance_metrics(lum, kinds)
    for name, t in timings.items():
        metrics[name]["seconds"] = round(t, 2)
    shown = [m.name for m in wanted if m.name in lum]
    image = None
    if render_image and shown:
        to_rgb = xyz_to_rgb_matrix("rec709")
        ref_name = "ours" if "ours" in lum else shown[0]
        zen_y = float(lum[ref_name][0]) / K_M if kinds[ref_name] != "relative" else 1.0
        panels = {}
        for name in dict.fromkeys(shown + [ref_name]):
            xyz = xyz_pix[name] * (zen_y if kinds[name] == "relative" else 1.0)
            rgb = np.zeros(valid.shape + (3,))
            rgb[valid] = xyz @ to_rgb.T
            panels[name] = rgb
        avg = image_io.auto_exposure_luminance(panels[ref_name], valid)
        tiles = []
        for name in shown:
            tile = image_io.tonemap(panels[name], valid=valid, average_luminance=avg)
            label = name + (" (relative)" if kinds[name] == "relative" else "")
            tiles.append(np.concatenate([_label_strip(label, size), tile], axis=0))
            tiles.append(np.zeros((size + LABEL_HEIGHT, 2, 3), np.uint8))
        image = np.concatenate(tiles[:-1], axis=1)
    info = {"sun_elevation_deg": elev, "sun_azimuth_deg": float(sun_azimuth_deg), "size": size, "quality": quality,
            "wavelength_step_nm": float(wavelength_step_nm), "atmosphere": _jsonable(
                atmosphere.optical_profile([550.0]).metadata), "model_info": infos,
            "exposure": "one exposure for all panels: tonemap() auto exposure of 'ours'",
            "relative_models": "D65 grey, zenith luminance set equal to ours"}
    return Comparison(shown, zen, rel, lum, metrics, image, skipped, info)


def _jsonable(d: dict) -> dict:
    return {k: (float(v) if isinstance(v, (np.floating, float)) else v) for k, v in d.items()
            if isinstance(v, (int, float, str, bool, np.floating)) or v is None}


def format_table(cmp: Comparison) -> str:
    """The metrics as a plain-text table (percentages)."""
    lines = [f"{'model':18s} {'zenith cd/m2':>12s} {'vs ours abs rms/max %':>22s} "
             f"{'vs ours rel rms/max %':>22s} {'vs CIE12 rel rms/max %':>23s} {'time s':>7s}"]

    def pair(m, key):
        if key not in m:
            return "-"
        return f"{100 * m[key]['rms']:.1f} / {100 * m[key]['max_abs']:.1f}"

    for name, m in cmp.metrics.items():
        zl = f"{m['zenith_luminance_cd_m2']:.0f}" if "zenith_luminance_cd_m2" in m else "relative"
        lines.append(f"{name:18s} {zl:>12s} {pair(m, 'vs_ours_abs'):>22s} {pair(m, 'vs_ours_rel'):>22s} "
                     f"{pair(m, 'vs_cie12_rel'):>23s} {m.get('seconds', float('nan')):7.1f}")
    for name, why in cmp.skipped.items():
        lines.append(f"{name:18s} skipped: {why}")
    lines.append(f"samples: view zenith {list(VIEW_ZENITH_DEG)} deg x azimuth from the sun "
                 f"{list(VIEW_RELATIVE_AZIMUTH_DEG)} deg, none within {SUN_EXCLUSION_DEG:g} deg of the sun "
                 f"({len(cmp.sample_zenith_deg)} directions)")
    return "\n".join(lines)
