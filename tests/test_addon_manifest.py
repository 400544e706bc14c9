"""The extension manifest and its build script (no Blender needed; no download)."""

import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = ROOT / "blender_manifest.toml"


def load_build_script():
    spec = importlib.util.spec_from_file_location("build_extension", ROOT / "blender_addon" / "build_extension.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def manifest():
    with open(MANIFEST, "rb") as f:
        return tomllib.load(f)


def test_required_fields(manifest):
    for key in ("schema_version", "id", "name", "tagline", "version", "type", "maintainer", "license",
                "blender_version_min"):
        assert manifest.get(key), key
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == "skymodel"
    assert manifest["type"] == "add-on"
    assert manifest["blender_version_min"] == "4.5.0"
    assert manifest["license"] == ["SPDX:GPL-3.0-or-later"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", manifest["version"])
    tagline = manifest["tagline"]
    assert len(tagline) <= 64 and tagline[-1].isalnum()
    for reason in manifest.get("permissions", {}).values():
        assert len(reason) <= 64 and reason[-1].isalnum()
    assert set(manifest.get("permissions", {})) <= {"files"}  # only the cache needs anything
    build = manifest.get("build", {})
    assert not ("paths" in build and "paths_exclude_pattern" in build)


def test_version_matches_the_package(manifest):
    text = (ROOT / "pyproject.toml").read_text()
    assert f'version = "{manifest["version"]}"' in text


def test_wheels_match_the_build_script(manifest):
    build = load_build_script()
    assert sorted(manifest["wheels"]) == build.manifest_wheel_paths()
    for path in manifest["wheels"]:
        name = Path(path).name
        assert path.startswith("./wheels/") and name.endswith(".whl")
        py, abi = name[:-4].split("-")[-3:-1]
        # Blender 4.5-5.0: Python 3.11 (a compressed tag set such as py2.py3 includes py3)
        assert set(py.split(".")) & {"py3", "cp311"} and abi in ("none", "cp311"), name
        assert not name.startswith("numpy-")  # Blender ships numpy
    # every declared platform gets every compiled dependency
    for req, plats in build.WHEELS.items():
        if "any" not in plats:
            assert set(plats) == set(manifest["platforms"]), req
    # the core travels as its own pure wheel, of the package's version
    assert f"./wheels/skymodel-{manifest['version']}-py3-none-any.whl" in manifest["wheels"]


def test_build_script_rejects_a_mismatch(manifest, tmp_path, monkeypatch):
    build = load_build_script()
    bad = dict(manifest, wheels=manifest["wheels"][:-1])
    monkeypatch.setattr(build, "read_manifest", lambda path=None: bad)
    with pytest.raises(SystemExit, match="do not match"):
        build.main(["--no-download", "--stage-dir", str(tmp_path / "s"), "--output-dir", str(tmp_path / "d")])


def _blender_ext():
    spec = importlib.util.find_spec("bpy")  # locate, do not import
    if spec is None or not spec.origin:
        return None
    hits = sorted(Path(spec.origin).parent.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    return hits[0] if hits else None


def test_blender_validator_accepts_the_manifest(tmp_path):
    tool = _blender_ext()
    if tool is None:
        pytest.skip("blender_ext.py (shipped in the bpy wheel) not found")
    shutil.copy2(MANIFEST, tmp_path / "blender_manifest.toml")
    shutil.copy2(ROOT / "blender_addon" / "__init__.py", tmp_path / "__init__.py")
    res = subprocess.run([sys.executable, str(tool), "validate", str(tmp_path)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "Success" in res.stdout


def test_addon_package_is_extension_style():
    text = (ROOT / "blender_addon" / "__init__.py").read_text()
    assert not re.search(r"^bl_info\s*=", text, re.M)
    for f in (ROOT / "blender_addon").glob("*.py"):
        src = f.read_text()
        assert not re.search(r"^\s*(from|import) blender_addon", src, re.M), f.name  # relative imports only
        # the core through ordinary imports (it is installed from its own wheel), never looked up by name
        assert "importlib" not in src or f.name == "build_extension.py", f.name
    assert not (ROOT / "blender_addon" / "core.py").exists()
