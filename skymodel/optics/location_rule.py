"""Which aerosol type and ground surface a place gets when the user names only its coordinates.

The rule (``skymodel/data/presets/location_rules.toml``, first match wins):

1. polar bands: south of 60 S -> ``polar_antarctic`` over snow; north of the Arctic Circle
   (66.56 N) -> ``polar_arctic`` over snow;
2. sea (a sea cell of the 0.1 degree land mask ``generated/land_mask_0p1deg.npz``, made from the
   GLOBE 1 km mask by ``generated/make_land_mask.py``) -> ``maritime_clean`` over ocean;
3. land inside a desert box -> ``desert`` over desert sand;
4. other land -> ``continental`` over grass.

"urban" is never chosen: a city is the user's choice. :func:`choose` returns the choice with the
sentence of the rule that made it, which the CLI prints.

>>> choose(-85.0, 0.0).aerosol
'polar_antarctic'
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from skymodel.data import load_npz, load_toml
from skymodel.errors import SkymodelInputError

MASK = "generated/land_mask_0p1deg.npz"


@dataclass(frozen=True)
class LocationChoice:
    """The aerosol type and surface chosen for a place, and the rule (a sentence) behind each."""

    aerosol: str
    surface: str
    aerosol_rule: str
    surface_rule: str
    rule: str  #: the rule's key: polar.antarctic, polar.arctic, sea, desert, land


@functools.lru_cache(maxsize=1)
def _rules() -> dict:
    return load_toml("presets/location_rules.toml")


@functools.lru_cache(maxsize=1)
def _mask() -> tuple[np.ndarray, float, float, float]:
    z = load_npz(MASK)
    shape = tuple(int(v) for v in z["shape"])
    land = np.unpackbits(z["land_bits"], axis=1)[:, : shape[1]].astype(bool)
    land.setflags(write=False)
    return land, float(z["cell_deg"]), float(z["north_deg"]), float(z["west_deg"])


def is_land(latitude_deg: float, longitude_deg: float) -> bool:
    """Whether the 0.1 degree cell holding the point is land (at least half of its GLOBE 1 km
    pixels are land)."""
    land, cell, north, west = _mask()
    i = min(int((north - latitude_deg) / cell), land.shape[0] - 1)
    lon = (longitude_deg - west) % 360.0
    j = min(int(lon / cell), land.shape[1] - 1)
    return bool(land[max(i, 0), j])


def desert_region(latitude_deg: float, longitude_deg: float) -> str | None:
    """The name of the desert box holding the point, or None."""
    for name, (s, n, w, e) in _rules()["desert"]["boxes"].items():
        if s <= latitude_deg <= n and w <= longitude_deg <= e:
            return name
    return None


def choose(latitude_deg: float, longitude_deg: float) -> LocationChoice:
    """The aerosol type and surface of the place (degrees north, degrees east)."""
    lat, lon = float(latitude_deg), float(longitude_deg)
    if not (np.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise SkymodelInputError("latitude", latitude_deg, "a latitude in -90..90 deg")
    if not (np.isfinite(lon) and -360.0 <= lon <= 360.0):
        raise SkymodelInputError("longitude", longitude_deg, "a longitude in -180..180 deg")
    lon = (lon + 180.0) % 360.0 - 180.0
    r = _rules()
    where = f"({lat:g}, {lon:g})"
    if lat <= r["polar"]["antarctic"]["max_latitude"]:
        key, e, why = "polar.antarctic", r["polar"]["antarctic"], f"{where} is south of 60 S"
    elif lat >= r["polar"]["arctic"]["min_latitude"]:
        key, e, why = "polar.arctic", r["polar"]["arctic"], f"{where} is north of the Arctic Circle"
    elif not is_land(lat, lon):
        key, e, why = "sea", r["sea"], f"{where} is sea in the land mask"
    else:
        box = desert_region(lat, lon)
        if box is not None:
            key, e, why = "desert", r["desert"], f"{where} is land in the {box} desert box"
        else:
            key, e, why = "land", r["land"], f"{where} is land outside the polar bands and desert boxes"
    text = f"rule {key}: {why}"
    return LocationChoice(aerosol=e["aerosol"], surface=e["surface"], aerosol_rule=text, surface_rule=text, rule=key)
