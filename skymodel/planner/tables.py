"""The measured tables the planner reads, never guesses, and the look-ups in them.

* ``skymodel/data/presets/planner/effects.json`` (``benchmarks/bench_planner.py --write``):
  for sun elevations -6..90 degrees, the error of switching each effect off or
  simplifying it, for the sky seen directly (by view-elevation band, :data:`BANDS_DEG`)
  and for the sky as lighting, the aerial-perspective error vs distance, and each
  render's time (:class:`_EffectTable`);
* ``skymodel/data/presets/accuracy/measured.json`` (the renderer's accuracy benchmark),
  optional: its knob rows (wavelengths, orders, layers) against its own converged
  reference, as lighting and by view-elevation band, for three scenes interpolated
  linearly in their sun elevation (:class:`_AccuracyTable`).
"""

from __future__ import annotations

import functools
import json
import os

import numpy as np

from skymodel.data import DATA_DIR
from skymodel.geometry import VIEW_BANDS_DEG
from skymodel.planner.scene import SceneDescription

EFFECTS_PATH = str(DATA_DIR / "presets" / "planner" / "effects.json")
ACCURACY_PATH = str(DATA_DIR / "presets" / "accuracy" / "measured.json")

#: Metric names in the tables for each tolerance kind: (sky band key, lighting key, aerial key).
_METRIC = {"de2000": ("de2000_mean", "de2000", "de2000_max"),
           "radiance_rel": ("radiance_rel_mean", "illuminance_rel", "radiance_rel_max")}
#: View-elevation bands of the effect table and the accuracy table's knob rows, degrees.
BANDS_DEG = VIEW_BANDS_DEG
#: Wavelength counts of the accuracy table's ``wavelengths`` knob -> step on 380..780 nm.
_WL_COUNT_STEP = {81: 5.0, 41: 10.0, 21: 20.0, 11: 40.0}


@functools.lru_cache(maxsize=8)
def _load_json(path: str, mtime: float) -> dict:
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def load_table(path_or_dict):
    """A table given as a dict, a path, or None (-> None)."""
    if path_or_dict is None or isinstance(path_or_dict, dict):
        return path_or_dict
    p = os.fspath(path_or_dict)
    if not os.path.isfile(p):
        return None
    return _load_json(p, os.path.getmtime(p))


class _EffectTable:
    """Look-ups in ``skymodel/data/presets/planner/effects.json`` at a sun elevation."""

    def __init__(self, table: dict):
        self.table = table
        rows = sorted(table["rows"], key=lambda r: r["sun_elevation_deg"])
        if not rows:
            raise ValueError("effect table has no rows")
        self.rows = rows
        self.elev = np.array([r["sun_elevation_deg"] for r in rows], float)
        self._ratios: dict = {}

    def _interp(self, el, fn):
        vals = np.array([fn(r) for r in self.rows], float)
        return float(np.interp(el, self.elev, vals))

    def has(self, effect) -> bool:
        return all(effect in r["effects"] for r in self.rows)

    def error(self, effect, el, scene) -> float:
        band_key, light_key, _ = _METRIC[scene.tolerance_kind]
        bands = visible_bands(scene)

        def one(r):
            e = r["effects"][effect]
            light = e["lighting"][light_key]
            if not scene.sky_visible or not bands:
                return light
            return max([light] + [e["sky"][b][band_key] for b in bands])

        return max(0.0, self._interp(el, one))

    def time(self, effect, el) -> float:
        """Seconds of the table's render with ``effect`` at sun ``el``: the reference's time
        there times :meth:`time_ratio` (each row is one run on a shared machine, so a single
        row's ratio carries that moment's load; the median over the sun elevations does not)."""
        t_ref = self._interp(el, lambda r: r["reference"]["time_s"])
        return t_ref if effect == "reference" else t_ref * self.time_ratio(effect)

    def time_ratio(self, effect) -> float:
        """Median over the table's rows of the time with ``effect`` over the reference's time."""
        if effect not in self._ratios:
            self._ratios[effect] = float(np.median([r["effects"][effect]["time_s"] / r["reference"]["time_s"]
                                                    for r in self.rows]))
        return self._ratios[effect]

    def reference_orders(self, el) -> int:
        return int(round(self._interp(el, lambda r: r["reference"]["orders"])))

    def aerial_error(self, el, distance_m, kind) -> float:
        if distance_m <= 0:
            return 0.0
        key = _METRIC[kind][2]

        def one(r):
            ap = r["aerial_perspective"]
            d = np.array([x["distance_m"] for x in ap], float)
            v = np.array([x[key] for x in ap], float)
            # linear in log-distance inside the table; below its first distance the error
            # scales with the distance (optical depth ~ distance), beyond its last it is held
            if distance_m < d[0]:
                return float(v[0] * distance_m / d[0])
            return float(np.interp(np.log(distance_m), np.log(d), v))

        return self._interp(el, one)

    def knob_rows(self, prefix) -> dict:
        """{value: effect name} of the effects named ``prefix<value>`` (orders_2, layers_8...)."""
        out = {}
        for name in self.rows[0]["effects"]:
            if name.startswith(prefix) and self.has(name):
                try:
                    out[float(name[len(prefix):])] = name
                except ValueError:
                    pass
        return out


class _AccuracyTable:
    """Look-ups in ``skymodel/data/presets/accuracy/measured.json`` (issue 3's benchmark), interpolated
    linearly in the sun elevation of its scenes and held beyond the first and last."""

    def __init__(self, table: dict):
        self.table = table
        scenes = table.get("scenes", {})
        self.scenes = sorted(scenes, key=lambda s: float(scenes[s]["sun_elevation_deg"]))
        self.elev = np.array([float(scenes[s]["sun_elevation_deg"]) for s in self.scenes], float)

    def _interp(self, el, values: dict):
        names = [s for s in self.scenes if s in values]
        if not names:
            return None
        x = np.array([float(self.table["scenes"][s]["sun_elevation_deg"]) for s in names])
        y = np.array([float(values[s]) for s in names])
        return float(np.interp(el, x, y))

    def knob(self, knob, el, metric, bands=(), light_metric=None) -> dict:
        """{value: (error, time_s)} of one knob, interpolated to the sun elevation: the
        worst of the row's error as lighting (its ``lighting`` entry's ``light_metric``;
        rows measured without it: the whole sky's ``metric``, the stand-in) and its
        ``metric`` in the view-elevation ``bands`` the cameras see, as the effect table's
        errors are (:func:`_row_error`)."""
        by_value: dict = {}
        for r in self.table.get("rows", []):
            if r.get("knob") != knob:
                continue
            by_value.setdefault(r["value"], {})[r["scene"]] = r
        out = {}
        for value, per_scene in by_value.items():
            err = self._interp(el, {s: _row_error(r, metric, bands, light_metric) for s, r in per_scene.items()
                                    if r.get(metric) is not None})
            t = self._interp(el, {s: r["time_s"] for s, r in per_scene.items() if r.get("time_s") is not None})
            if err is not None:
                out[value] = (err, t)
        return out

    def time_ratio(self, knob, value, base):
        """Median over the scenes of the time of ``knob = value`` over that of ``knob = base``
        measured in the same scene (same run, size and load), or None when no scene has both."""
        per_scene: dict = {}
        for r in self.table.get("rows", []):
            if r.get("knob") == knob and r.get("value") in (value, base) and r.get("time_s"):
                per_scene.setdefault(r["scene"], {})[r["value"]] = float(r["time_s"])
        ratios = [v[value] / v[base] for v in per_scene.values() if value in v and base in v and v[base] > 0]
        return float(np.median(ratios)) if ratios else None

    def preset_time(self, preset, el):
        p = self.table.get("presets", {}).get(preset, {})
        return self._interp(el, {s: v["time_s"] for s, v in p.items() if "time_s" in v})


def _row_error(row: dict, metric: str, bands, light_metric=None) -> float:
    """A knob row's error for a scene lit by the sky whose cameras see ``bands``: the worst
    of its error as lighting (``row["lighting"][light_metric]``, the irradiance on a
    horizontal surface, measured since 2026-11-29; rows without it: the whole sky's
    ``metric``) and its ``metric`` in those bands (rows measured without bands: none)."""
    light = (row.get("lighting") or {}).get(light_metric) if light_metric else None
    by_band = row.get("bands") or {}
    return max([float(row[metric] if light is None else light)]
               + [float(by_band[b][metric]) for b in bands if b in by_band and by_band[b].get(metric) is not None])


def visible_bands(scene: SceneDescription) -> list[str]:
    """The effect table's view-elevation bands the cameras see."""
    lo, hi = scene.elevation_range_deg
    return [b for b, (a, z) in BANDS_DEG.items() if hi > a and lo < z] if scene.sky_visible else []
