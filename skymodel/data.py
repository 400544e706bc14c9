"""Locating and reading the data tables in ``presets/``.

The tables are plain TOML, CSV and NPZ files; each names its source in a header or a
``source`` key. Readers here are cached because the tables never change at run time.
"""

from __future__ import annotations

import functools
import os
import tomllib
from pathlib import Path

import numpy as np

#: The folder holding the data tables. ``SKYMODEL_PRESETS`` overrides it (tests, add-on).
PRESETS_DIR = Path(os.environ.get("SKYMODEL_PRESETS", Path(__file__).resolve().parent.parent / "presets"))


def preset_path(*parts: str) -> Path:
    return PRESETS_DIR.joinpath(*parts)


@functools.lru_cache(maxsize=None)
def load_toml(name: str) -> dict:
    """Read ``presets/<name>`` as TOML."""
    with open(preset_path(name), "rb") as f:
        return tomllib.load(f)


@functools.lru_cache(maxsize=None)
def load_csv(name: str) -> tuple[tuple[str, ...], np.ndarray]:
    """Read ``presets/<name>``: lines starting with ``#`` are comments (the source),
    the first other line is the header; returns (column names, float array [rows, cols])."""
    with open(preset_path(name), encoding="utf-8") as f:
        lines = [ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    header = tuple(h.strip() for h in lines[0].split(","))
    data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=float)
    data.setflags(write=False)
    return header, data


def csv_columns(name: str) -> dict[str, np.ndarray]:
    """Read a preset CSV as a dict of column name -> 1-D array."""
    header, data = load_csv(name)
    return {h: data[:, i] for i, h in enumerate(header)}


@functools.lru_cache(maxsize=None)
def load_npz(name: str) -> dict[str, np.ndarray]:
    with np.load(preset_path(name), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
