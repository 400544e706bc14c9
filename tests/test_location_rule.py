"""The location rule: aerosol type and surface for any latitude/longitude (skymodel.optics.location_rule)."""

from __future__ import annotations

import numpy as np
import pytest

from skymodel.data import load_npz, load_toml
from skymodel.optics import location_rule
from skymodel.optics.atmosphere import Atmosphere


def test_every_rule_carries_a_source():
    rules = load_toml("presets/location_rules.toml")
    for key in ("sea", "desert", "land"):
        assert rules[key]["source"]
    for key in ("antarctic", "arctic"):
        assert rules["polar"][key]["source"]


@pytest.mark.parametrize("lat, lon, aerosol, surface, rule", [
    (0.0, -150.0, "maritime_clean", "ocean", "sea"),  # mid-Pacific
    (23.0, 5.5, "desert", "desert", "desert"),  # Sahara
    (-90.0, 0.0, "polar_antarctic", "snow", "polar.antarctic"),  # South Pole
    (-85.0, 0.0, "polar_antarctic", "snow", "polar.antarctic"),
    (48.85, 2.35, "continental", "grass", "land"),  # Paris: land, never "urban" by rule
    (78.2, 15.6, "polar_arctic", "snow", "polar.arctic"),  # Svalbard
])
def test_location_rule(lat, lon, aerosol, surface, rule):
    c = location_rule.choose(lat, lon)
    assert (c.aerosol, c.surface, c.rule) == (aerosol, surface, rule)
    assert rule in c.aerosol_rule
    atm = Atmosphere(latitude=lat, longitude=lon)
    assert atm.aerosol == aerosol and atm.surface == surface
    assert any(r.startswith(f"aerosol {aerosol}: rule {rule}") for r in atm.location_rules)


def test_location_rule_yields_to_the_user():
    atm = Atmosphere(latitude=-85.0, longitude=0.0, aerosol="urban", albedo=0.3)
    assert atm.aerosol == "urban" and atm.albedo == 0.3 and atm.location_rules == ()
    assert Atmosphere(latitude=-85.0, longitude=0.0).albedo == pytest.approx(0.8)


def test_land_mask_grid():
    z = load_npz(location_rule.MASK)
    assert tuple(z["shape"]) == (1800, 3600) and float(z["cell_deg"]) == 0.1
    land, *_ = location_rule._mask()
    w = np.cos(np.radians(90.0 - 0.1 * (np.arange(1800) + 0.5)))[:, None]  # cell areas
    assert 0.27 < float((land * w).sum() / (w.sum() * 3600)) < 0.31  # about 29 % of the Earth is land


@pytest.mark.slow
def test_land_mask_regenerates(tmp_path):
    # global-land-mask is in the [test] extra (pyproject.toml): the regeneration runs in CI, no skip
    import importlib.util

    from skymodel.data import DATA_DIR

    spec = importlib.util.spec_from_file_location("make_land_mask", DATA_DIR / "generated" / "make_land_mask.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.make(tmp_path / "mask.npz")
    new, old = np.load(out), load_npz(location_rule.MASK)
    assert np.array_equal(new["land_bits"], old["land_bits"])
