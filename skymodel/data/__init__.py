"""The package's data tables and their readers.

The tables ship inside the package (read with :mod:`importlib.resources`, so an installed
wheel has them) in three folders, each file naming its source in a header or a
``source`` key:

``sources/``
    measured tables as their authors publish them (ozone cross sections and climatology,
    limb darkening, refractive indices, peer models' coefficients);
``presets/``
    the choices a user picks by name (aerosol types and components, locations, surfaces)
    and the measured tables the planner reads (effects, accuracy);
``generated/``
    tables derived from the others by a script that sits beside them (the Mie lookup,
    the extracted solar spectrum), each reproduced by a test.

Names passed to the readers are paths relative to this folder
(``"skymodel/data/presets/locations.toml"``). Readers are cached: the tables never change at run time.
"""

from __future__ import annotations

import functools
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

#: The folder holding the data tables (inside the installed package).
DATA_DIR = Path(str(resources.files(__name__)))


def data_path(*parts: str) -> Path:
    """Path of a table under the data folder (``data_path("presets", "locations.toml")``)."""
    return DATA_DIR.joinpath(*parts)


@functools.lru_cache(maxsize=None)
def load_toml(name: str) -> dict:
    """Read the table ``name`` (relative to the data folder) as TOML."""
    with open(data_path(name), "rb") as f:
        return tomllib.load(f)


@functools.lru_cache(maxsize=None)
def load_csv(name: str) -> tuple[tuple[str, ...], np.ndarray]:
    """Read the CSV table ``name``: lines starting with ``#`` are comments (the source),
    the first other line is the header; returns (column names, float array [rows, cols])."""
    with open(data_path(name), encoding="utf-8") as f:
        lines = [ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")]
    header = tuple(h.strip() for h in lines[0].split(","))
    data = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=float)
    data.setflags(write=False)
    return header, data


def csv_columns(name: str) -> dict[str, np.ndarray]:
    """Read a CSV table as a dict of column name -> 1-D array."""
    header, data = load_csv(name)
    return {h: data[:, i] for i, h in enumerate(header)}


@functools.lru_cache(maxsize=None)
def load_npz(name: str) -> dict[str, np.ndarray]:
    """Read the NPZ table ``name`` as a dict of arrays."""
    with np.load(data_path(name), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
