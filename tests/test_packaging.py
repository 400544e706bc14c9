"""The core as a user installs it: a wheel built from the checkout, installed into a fresh
virtual environment outside the checkout, renders a sky from its own package data."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    # build from a clean copy of what the distribution holds, so that leftovers of earlier
    # builds in the checkout (build/lib) cannot slip into the wheel
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    shutil.copytree(ROOT / "skymodel", src / "skymodel", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)],
                   check=True, cwd=out)
    (whl,) = out.glob("skymodel-*.whl")
    return whl


def test_wheel_carries_the_data_and_not_the_addon(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    data = {n for n in names if n.startswith("skymodel/data/")}
    # every table the checkout holds is in the wheel
    expected = {p.relative_to(ROOT).as_posix() for p in (ROOT / "skymodel" / "data").rglob("*")
                if p.is_file() and p.suffix in (".csv", ".toml", ".json", ".npz", ".md", ".py")
                and "__pycache__" not in p.parts}
    assert expected <= data, sorted(expected - data)
    assert not any(n.startswith("blender_addon/") for n in names)
    assert not any(n.startswith(("presets/", "tests/", "benchmarks/")) for n in names)


def test_installed_wheel_renders_a_sky(wheel, tmp_path):
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=False)
    py = env_dir / "bin" / "python"
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             check=True, capture_output=True, text=True).stdout.strip()
    # install the wheel alone (no network); the dependencies (numpy, scipy, colour-science) are
    # borrowed from this interpreter's site-packages through a path file placed after the
    # fresh environment's own, so the editable checkout is not visible
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", purelib, str(wheel)],
                   check=True)
    Path(purelib, "zz_borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    run_dir = tmp_path / "elsewhere"
    run_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "SKYMODEL_PRESETS")}
    script = (
        "import skymodel, sys\n"
        f"assert skymodel.__file__.startswith({purelib!r}), skymodel.__file__\n"
        "from skymodel.cli import main\n"
        "sys.exit(main(['render', '--size', '24', '--quality', 'preview', '--sun-elevation', '20', "
        "'--out', 'sky.exr', '--png', 'sky.png', '--quiet']))\n"
    )
    proc = subprocess.run([str(py), "-c", script], cwd=run_dir, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (run_dir / "sky.exr").stat().st_size > 0 and (run_dir / "sky.png").stat().st_size > 0
