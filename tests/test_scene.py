"""The parameter registry (skymodel/scene.py): every user parameter once, read by the CLI,
the Python API and the Blender add-on; and the one function that places the sun."""

from __future__ import annotations

import dataclasses
import io
import math
import tokenize
from pathlib import Path

import pytest

from skymodel import scene
from skymodel.errors import SkymodelInputError

ROOT = Path(__file__).resolve().parents[1]


def patch_parameter(monkeypatch, name, **changes):
    monkeypatch.setitem(scene.PARAMETERS, name, dataclasses.replace(scene.PARAMETERS[name], **changes))


# ------------------------------------------------------------------ the registry


def test_every_entry_is_consistent():
    for key, p in scene.PARAMETERS.items():
        assert p.name == key and p.help and not p.help.endswith(".")
        if p.default is not None:
            assert scene.check(key, p.default) == p.default, key  # the default is allowed
        if p.suggested is not None:
            scene.check(key, p.suggested)
        if p.minimum is not None and p.maximum is not None:
            assert p.minimum < p.maximum
        for alias, canonical in p.aliases:
            assert canonical in p.choices and scene.check(key, alias) == canonical


def test_check_names_the_parameter_and_the_range():
    with pytest.raises(SkymodelInputError) as e:
        scene.check("sun_elevation", -20)
    assert e.value.parameter == "sun_elevation" and "-18..90 deg" in str(e.value)
    with pytest.raises(SkymodelInputError, match="layers.*1..64"):
        scene.check("layers", 0)
    with pytest.raises(SkymodelInputError, match="layers"):
        scene.check("layers", 100_000)
    with pytest.raises(SkymodelInputError, match="month.*integer"):
        scene.check("month", 6.5)
    with pytest.raises(SkymodelInputError, match=r"ozone_du.*\(0, 1000\]"):
        scene.check("ozone_du", 0.0)
    with pytest.raises(SkymodelInputError, match="quality.*preview, final, reference"):
        scene.check("quality", "ultra")
    assert scene.check("aerosol", "Desert_Dust") == "desert" and scene.check("quality", "FINAL") == "final"
    assert scene.check("layers", None) is None  # a derived default passes as None


def test_the_quality_default_is_one_and_everywhere_the_same():
    from skymodel.models import SkyScene
    from skymodel.render import quality, sky

    name = scene.default("quality")
    assert name == "preview"
    assert sky.quality_settings(None) == quality.QUALITIES[name].settings
    assert sky._quality_name(None) == name
    assert SkyScene.__dataclass_fields__["quality"].default == name
    import inspect

    from skymodel.models.comparison import compare

    assert inspect.signature(sky.render_sky).parameters["quality"].default is None  # None = the registry's
    assert inspect.signature(compare).parameters["quality"].default is None


def test_quality_registry_names_the_choices_and_keeps_the_settings():
    from skymodel.render import quality

    with pytest.raises(SkymodelInputError) as e:
        quality.quality_settings("ultra")
    assert e.value.parameter == "quality" and "preview, final, reference" in str(e.value)
    assert tuple(quality.QUALITIES) == scene.parameter("quality").choices
    assert quality.QUALITY["final"].table_mus == 32 and quality.QUALITY["preview"].view_steps == 64
    m = quality.QUALITIES["final"].measured()
    assert 0 < m["radiance_rel_mean"] <= quality.QUALITIES["final"].target["radiance_rel_mean"]
    assert "measured.json" in m["source"]
    from skymodel.validation.accuracy_report import TARGETS

    assert TARGETS == quality.targets()


# ------------------------------------------------------------------ one place for the sun


def test_place_sun_from_angles_and_from_a_date():
    s = scene.place_sun()
    assert (s.elevation_deg, s.azimuth_deg, s.earth_sun_distance_au) == (25.0, 180.0, 1.0)
    assert scene.place_sun(elevation_deg=5, azimuth_deg=-90).azimuth_deg == 270.0
    a = scene.place_sun(41.65, -0.88, "2026-06-21T12:00:00Z")
    b = scene.place_sun(41.65, -0.88, (2026, 6, 21, 12, 0))
    assert a == b and a.month == 6 and 60 < a.elevation_deg < 80 and a.earth_sun_distance_au > 1.01
    with pytest.raises(SkymodelInputError, match="time_utc.*not both"):
        scene.place_sun(41.65, -0.88, "2026-06-21T12:00:00Z", elevation_deg=10)
    with pytest.raises(SkymodelInputError, match="time_utc.*night"):
        scene.place_sun(41.65, -0.88, (2026, 6, 21, 0, 0))
    # allow_night: the true elevation below the bound (the renderers skip the sunlit sky there)
    n = scene.place_sun(41.65, -0.88, (2026, 6, 21, 0, 0), allow_night=True)
    assert n.elevation_deg < scene.parameter("sun_elevation").minimum and n.time_utc == "2026-06-21T00:00:00Z"
    assert scene.place_sun(41.65, -0.88, (2026, 6, 21, 12, 0), allow_night=True) == a
    with pytest.raises(SkymodelInputError) as e:
        scene.place_sun(41.65, -0.88, (2026, 2, 30, 12, 0))
    assert e.value.parameter == "day"


def test_cli_and_addon_place_the_sun_through_scene(monkeypatch):
    from skymodel.cli import options

    calls = []
    real = scene.place_sun
    monkeypatch.setattr(scene, "place_sun", lambda *a, **k: calls.append((a, k)) or real(*a, **k))
    from skymodel.cli.main import build_parser
    from skymodel.optics.atmosphere import Atmosphere

    args = build_parser().parse_args(["render", "--sun-elevation", "10"])
    assert options.sun_from_args(args, Atmosphere()).elevation_deg == 10.0
    physics = pytest.importorskip("blender_addon.physics")
    assert physics.resolve(physics.SkyParams(sun_elevation_deg=11.0)).sun_elevation_deg == 11.0
    assert len(calls) == 2


# ------------------------------------------------------------------ one change reaches every interface


def test_a_patched_bound_reaches_the_cli_the_api_and_blender(monkeypatch, capsys):
    from skymodel.cli import main, options
    from skymodel.cli.main import build_parser
    from skymodel.optics.atmosphere import Atmosphere

    with pytest.raises(SkymodelInputError):
        scene.place_sun(elevation_deg=-19.0)
    with pytest.raises(SkymodelInputError):
        Atmosphere(turbidity=80.0)
    patch_parameter(monkeypatch, "sun_elevation", minimum=-20.0)
    patch_parameter(monkeypatch, "turbidity", maximum=100.0)
    # the CLI: help and parse
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    assert "-20..90 deg" in " ".join(capsys.readouterr().out.split())
    args = build_parser().parse_args(["render", "--sun-elevation", "-19", "--turbidity", "80"])
    atm = options.atmosphere_from_args(args)
    assert options.sun_from_args(args, atm).elevation_deg == -19.0 and atm.turbidity == 80.0
    # the Python API
    assert scene.place_sun(elevation_deg=-19.0).elevation_deg == -19.0
    assert Atmosphere(turbidity=80.0).turbidity == 80.0
    # the Blender add-on: its property definition and its validation
    pytest.importorskip("bpy")
    from blender_addon import physics, props

    kw = props.registry_property("sun_elevation").keywords
    assert kw["min"] == pytest.approx(math.radians(-20.0))
    assert props.registry_property("turbidity").keywords["max"] == 100.0
    assert physics.resolve(physics.SkyParams(sun_elevation_deg=-19.0)).sun_elevation_deg == -19.0


def test_a_patched_default_reaches_the_cli_the_api_and_blender(monkeypatch, capsys):
    from skymodel.cli.main import build_parser
    from skymodel.render.quality import QUALITIES, quality_settings

    patch_parameter(monkeypatch, "quality", default="final")
    patch_parameter(monkeypatch, "sun_azimuth", default=135.0)
    patch_parameter(monkeypatch, "layers", maximum=8)
    for command in ("render", "radiance", "compare"):
        assert build_parser().parse_args([command]).quality == "final", command
    args = build_parser().parse_args(["render"])
    from skymodel.cli import options
    from skymodel.optics.atmosphere import Atmosphere

    assert options.sun_from_args(args, Atmosphere()).azimuth_deg == 135.0
    assert quality_settings(None) == QUALITIES["final"].settings  # render_sky(quality=None)
    assert scene.place_sun().azimuth_deg == 135.0
    from skymodel.cli import main

    assert main(["profile", "--layers", "9", "--wavelengths", "550"]) == 2
    assert "layers" in capsys.readouterr().err
    pytest.importorskip("bpy")
    from blender_addon import props

    assert props.registry_property("quality").keywords["default"] == "final"
    assert props.registry_property("sun_azimuth").keywords["default"] == pytest.approx(math.radians(135.0))


def test_signature_defaults_are_the_registrys():
    from skymodel.optics.atmosphere import Atmosphere

    atm = Atmosphere()
    assert atm.month == scene.default("month") == 6
    assert atm.location == scene.default("location") and atm.n_altitudes == scene.default("n_altitudes")
    assert Atmosphere(aerosol="desert_dust").aerosol == "desert"
    physics = pytest.importorskip("blender_addon.physics")
    p = physics.SkyParams()
    assert (p.month, p.sun_elevation_deg, p.sun_azimuth_deg, p.quality, p.n_layers) == (
        scene.default("month"), scene.default("sun_elevation"), scene.default("sun_azimuth"),
        scene.default("quality"), scene.default("volume_layers"))
    assert physics.MIN_SUN_ELEVATION_DEG == scene.parameter("sun_elevation").minimum


# ------------------------------------------------------------------ nobody else types the numbers


def _code_lines(path: Path):
    """(line number, [(token type, text)]) of the code tokens (no strings, no comments)."""
    lines: dict[int, list] = {}
    with open(path, "rb") as f:
        for tok in tokenize.tokenize(f.readline):
            if tok.type in (tokenize.STRING, tokenize.COMMENT, tokenize.ENCODING, tokenize.NL, tokenize.NEWLINE):
                continue
            lines.setdefault(tok.start[0], []).append((tok.type, tok.string))
    return lines


def _hard_coded(path: Path) -> list[str]:
    """Lines that type the lowest sun elevation (the registry's, -18) or the default month (6) as numbers."""
    lowest = -float(scene.parameter("sun_elevation").minimum)
    found = []
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path.name
    for n, toks in _code_lines(path).items():
        for (t0, s0), (t1, s1) in zip(toks, toks[1:]):
            if s0 == "-" and t1 == tokenize.NUMBER and float(s1) == lowest:
                found.append(f"{rel}:{n}: -{s1}")
        names = [s for t, s in toks if t == tokenize.NAME]
        if any("month" in s for s in names) and any(t == tokenize.NUMBER and s in ("6", "6.0") for t, s in toks):
            found.append(f"{rel}:{n}: month 6")
    return found


#: Modules that still type the numbers, each with why (strict xfail: remove the entry when fixed).
_PENDING: dict[str, str] = {}


def _sources():
    files = sorted(p for d in ("skymodel", "blender_addon") for p in (ROOT / d).rglob("*.py")
                   if p != ROOT / "skymodel" / "scene.py")
    out = []
    for p in files:
        rel = str(p.relative_to(ROOT))
        marks = [pytest.mark.xfail(strict=True, reason=_PENDING[rel])] if rel in _PENDING else []
        out.append(pytest.param(p, id=rel, marks=marks))
    return out


@pytest.mark.parametrize("path", _sources())
def test_no_module_but_scene_types_the_lowest_sun_or_the_default_month(path):
    assert _hard_coded(path) == []


def test_the_scan_finds_what_it_looks_for(tmp_path):
    f = tmp_path / "probe.py"
    f.write_text('x = check_range("sun_elevation", e, -18.0, 90.0)\nmonth = args.month or 6\ny = 1e-18\n'
                 '"""-18 in a string"""  # -18 in a comment\n')
    assert [s.split(": ", 1)[1] for s in _hard_coded(f)] == ["-18.0", "month 6"]
