"""Build the Blender extension zip(s) of skymodel.

    python blender_addon/build_extension.py                 # download wheels, stage, build, validate
    python blender_addon/build_extension.py --no-download   # dependency wheels already in ./wheels/
    python blender_addon/build_extension.py --no-split      # one zip for every platform

Steps
1. ``pip download --only-binary=:all: --python-version 3.11 --platform <tag> --no-deps``
   of every wheel in :data:`WHEELS` into ``<repo>/wheels/`` (files already there are kept).
2. The core: ``pip wheel --no-deps`` of the repository (a clean copy of ``pyproject.toml``,
   ``README.md`` and ``skymodel/``, so no stale build output slips in) into ``wheels/``:
   pure Python, its data tables inside (:func:`core_wheel_name`). Blender installs an
   extension's wheels into its site-packages, so the add-on imports ``skymodel`` there as
   it does from a checkout. Always rebuilt; with ``--no-download`` pip still needs the
   build backend (setuptools) from its index or cache.
3. Stage ``build/extension/``: the add-on package (``blender_addon/*.py`` without this
   script) at the root, ``blender_manifest.toml`` and ``wheels/``.
4. ``blender_ext.py build --split-platforms`` (Blender's own tool, shipped in the ``bpy``
   wheel at ``bpy/<version>/scripts/addons_core/bl_pkg/cli/blender_ext.py``, or give
   ``--blender-ext``) into ``dist/``, then ``blender_ext.py validate`` on every zip.

Install a zip with Edit > Preferences > Get Extensions > Install from Disk, or
``blender --command extension install-file -r user_default <zip>``.
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: requirement -> {Blender platform ("any" for pure wheels): (pip --platform tag, wheel file name)}.
#: numpy is not listed: Blender ships it. imageio/pillow (colour-science's I/O extras) are not
#: needed by anything skymodel calls and are left out.
WHEELS = {
    "colour-science==0.4.6": {"any": ("manylinux_2_28_x86_64", "colour_science-0.4.6-py3-none-any.whl")},
    "typing_extensions==4.16.0": {"any": ("manylinux_2_28_x86_64", "typing_extensions-4.16.0-py3-none-any.whl")},
    # the IANA zones for a named --timezone / the panel's Time Zone where the system has none (Windows)
    "tzdata==2026.6": {"any": ("manylinux_2_28_x86_64", "tzdata-2026.6-py2.py3-none-any.whl")},
    # numpy's BLAS held to one thread in the solver's threaded loops (skymodel.render.threads)
    "threadpoolctl==3.8.0": {"any": ("manylinux_2_28_x86_64", "threadpoolctl-3.8.0-py3-none-any.whl")},
    "scipy==1.17.1": {
        "linux-x64": ("manylinux_2_28_x86_64",
                      "scipy-1.17.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl"),
        "windows-x64": ("win_amd64", "scipy-1.17.1-cp311-cp311-win_amd64.whl"),
        "macos-arm64": ("macosx_12_0_arm64", "scipy-1.17.1-cp311-cp311-macosx_12_0_arm64.whl"),
        "macos-x64": ("macosx_10_14_x86_64", "scipy-1.17.1-cp311-cp311-macosx_10_14_x86_64.whl"),
    },
}

#: What goes into the staged extension besides the manifest and the wheels.
ADDON_EXCLUDE = {"build_extension.py"}
#: What the core's wheel is built from (copied to a clean folder first).
CORE_SOURCES = ("pyproject.toml", "README.md", "skymodel")


def read_pyproject(path: Path = ROOT / "pyproject.toml") -> dict:
    with open(path, "rb") as f:
        return tomllib.load(f)


def core_wheel_name() -> str:
    """File name of the core's wheel (pure Python): ``skymodel-<version>-py3-none-any.whl``."""
    project = read_pyproject()["project"]
    return f"{project['name'].replace('-', '_')}-{project['version']}-py3-none-any.whl"


def manifest_wheel_paths() -> list[str]:
    """The ``wheels`` list the manifest must carry (sorted): the dependencies and the core."""
    names = [name for plats in WHEELS.values() for _tag, name in plats.values()] + [core_wheel_name()]
    return sorted(f"./wheels/{name}" for name in names)


def read_manifest(path: Path = ROOT / "blender_manifest.toml") -> dict:
    with open(path, "rb") as f:
        return tomllib.load(f)


def find_blender_ext() -> Path:
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.origin:
        raise SystemExit("blender_ext.py not found: install the bpy module or pass --blender-ext")
    base = Path(spec.origin).parent
    for cand in sorted(glob.glob(str(base / "*" / "scripts" / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"))
                       + glob.glob(str(base.parent / "*" / "scripts" / "addons_core" / "bl_pkg" / "cli" /
                                       "blender_ext.py"))):
        return Path(cand)
    raise SystemExit(f"blender_ext.py not found under {base}")


def download(wheel_dir: Path) -> None:
    wheel_dir.mkdir(parents=True, exist_ok=True)
    for req, plats in WHEELS.items():
        for plat, (tag, name) in plats.items():
            if (wheel_dir / name).is_file():
                print(f"have {name}")
                continue
            cmd = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", "--no-deps", "--python-version",
                   "3.11", "--implementation", "cp", "--platform", tag, "-d", str(wheel_dir), req]
            print(" ".join(cmd), flush=True)
            subprocess.run(cmd, check=True)
            if not (wheel_dir / name).is_file():
                raise SystemExit(f"pip did not produce {name} for {req} ({plat}); update WHEELS and the manifest")


def build_core_wheel(wheel_dir: Path) -> Path:
    """``pip wheel --no-deps`` of a clean copy of the core into ``wheel_dir`` (replacing any
    previous build of the same name); returns the wheel's path."""
    wheel_dir.mkdir(parents=True, exist_ok=True)
    name = core_wheel_name()
    target = wheel_dir / name
    if target.exists():
        target.unlink()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".*")
    with tempfile.TemporaryDirectory(prefix="skymodel-core-") as tmp:
        src = Path(tmp) / "src"
        src.mkdir()
        for item in CORE_SOURCES:
            path = ROOT / item
            if path.is_dir():
                shutil.copytree(path, src / item, ignore=ignore)
            else:
                shutil.copy2(path, src / item)
        out = Path(tmp) / "out"
        cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)]
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, cwd=tmp)
        built = out / name
        if not built.is_file():
            raise SystemExit(f"pip did not produce {name} (got {sorted(p.name for p in out.glob('*'))})")
        shutil.copy2(built, target)
    print(f"built {target}")
    return target


def stage(stage_dir: Path, wheel_dir: Path) -> None:
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    stage_dir.mkdir(parents=True)
    for f in sorted((ROOT / "blender_addon").glob("*.py")):
        if f.name not in ADDON_EXCLUDE:
            shutil.copy2(f, stage_dir / f.name)
    shutil.copy2(ROOT / "blender_manifest.toml", stage_dir / "blender_manifest.toml")
    (stage_dir / "wheels").mkdir()
    for path in manifest_wheel_paths():
        src = wheel_dir / Path(path).name
        if not src.is_file():
            raise SystemExit(f"missing wheel {src} (run without --no-download)")
        shutil.copy2(src, stage_dir / "wheels" / src.name)


def run_blender_ext(blender_ext: Path, *args: str) -> None:
    cmd = [sys.executable, str(blender_ext), *args]
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--no-download", action="store_true", help="use the wheels already in --wheel-dir")
    ap.add_argument("--no-split", action="store_true", help="one zip with every platform's wheels")
    ap.add_argument("--wheel-dir", type=Path, default=ROOT / "wheels")
    ap.add_argument("--stage-dir", type=Path, default=ROOT / "build" / "extension")
    ap.add_argument("--output-dir", type=Path, default=ROOT / "dist")
    ap.add_argument("--blender-ext", type=Path, default=None, help="path of blender_ext.py")
    args = ap.parse_args(argv)

    listed = sorted(read_manifest().get("wheels", []))
    if listed != manifest_wheel_paths():
        raise SystemExit("blender_manifest.toml wheels do not match WHEELS in build_extension.py:\n"
                         f"  manifest: {listed}\n  script:   {manifest_wheel_paths()}")
    if not args.no_download:
        download(args.wheel_dir)
    build_core_wheel(args.wheel_dir)
    stage(args.stage_dir, args.wheel_dir)
    blender_ext = args.blender_ext or find_blender_ext()
    args.output_dir.mkdir(parents=True, exist_ok=True)
    before = set(args.output_dir.glob("*.zip"))
    build = ["build", "--source-dir", str(args.stage_dir), "--output-dir", str(args.output_dir)]
    if not args.no_split:
        build.append("--split-platforms")
    run_blender_ext(blender_ext, *build)
    zips = sorted(set(args.output_dir.glob("*.zip")) - before) or sorted(args.output_dir.glob("skymodel-*.zip"))
    for z in zips:
        run_blender_ext(blender_ext, "validate", str(z))
        print(f"built {z} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
