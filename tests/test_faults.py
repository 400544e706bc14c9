"""Failure injection (issue 22): each fault has a named outcome — the exit status, one line
on stderr naming what failed, no temporary files left behind, and the last complete file
still valid.

* a read-only folder: refused before any work (exit 2, naming the option);
* a full disk: ENOSPC from a patched file write, and a real kernel refusal (a child whose
  file-size limit, RLIMIT_FSIZE, is smaller than the image: EFBIG): exit 1, the earlier
  file intact, no ``.tmp`` litter;
* SIGINT and SIGTERM during the render and during the write: exit 130 / 143, one line,
  no litter, the earlier file intact;
* two writers to one path: the file is always one writer's complete image.

Run alone with ``pytest -m faults``. The renders are 16x8 px at preview quality; the
write-time cases replace the render by a synthetic image so they take no render time."""

from __future__ import annotations

import errno
import glob
import io
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from skymodel.cli import main

pytestmark = pytest.mark.faults

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def litter(folder):
    """Temporary or probe files the writers left in ``folder``."""
    return sorted(glob.glob(os.path.join(folder, ".*.tmp")) + glob.glob(os.path.join(folder, ".*.probe")))


def child(script, *args, preexec_fn=None, env=None):
    """Start ``python -c script args`` in the repository (stderr piped)."""
    e = dict(os.environ, PYTHONPATH=ROOT, **(env or {}))

    def start():
        # a shell's background job starts with SIGINT ignored, and Python then installs no
        # Ctrl-C handler: give the child SIGINT's usual meaning however the tests were started
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if preexec_fn is not None:
            preexec_fn()

    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(script), *args], cwd=ROOT, env=e,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=start)


#: A child that runs the CLI with the render replaced by a synthetic image (instant) and a
#: hook in the writer: FAULT=sigint|sigterm sends the signal to itself in the middle of a
#: file write.
FAKE_RENDER = """
import os, signal, sys
import numpy as np
from skymodel.render import image_io, sky
from skymodel.cli.main import main

def fake_render(profile, camera, *a, **k):
    dirs, valid = camera.directions()
    rad = np.full(camera.shape + (profile.wavelengths_nm.size,), 0.01) * valid[..., None]
    return sky.SkyImage(rad, valid, dirs, profile.wavelengths_nm, camera, np.array([0, 0, 1.0]),
                        np.ones(profile.wavelengths_nm.size), {"total_s": 0.0, "orders": 1})

def fake_reduced(profile, camera, el, reduce, n_channels, *a, **k):
    dirs, valid = camera.directions()
    img = np.full(camera.shape + (n_channels,), 0.01) * valid[..., None]
    return img, np.ones(profile.wavelengths_nm.size), {"total_s": 0.0, "orders": 1}

sky.render_sky = fake_render
sky.render_sky_reduced = fake_reduced  # a render reduced to colour band by band, where the CLI uses one
fault = os.environ.get("FAULT")
if fault:
    real = image_io._write_temp
    def hooked(path, write_fn):
        def write(f):
            f.write(b"partial")
            os.kill(os.getpid(), signal.SIGINT if fault == "sigint" else signal.SIGTERM)
            write_fn(f)
        return real(path, write)
    image_io._write_temp = hooked
sys.exit(main(sys.argv[1:]))
"""


def _one_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err, err
    return lines[0]


# ---------------------------------------------------------------------------- read-only folder


#: Root ignores a folder's mode; as root the child runs in its own mount namespace with
#: the folder bind-mounted read-only (a real EROFS).
RO_MOUNT = 'mount --bind "$0" "$0" && mount -o remount,bind,ro "$0" "$0" && exec "$@"'


def _read_only_prefix(folder) -> list:
    if os.geteuid() != 0:
        os.chmod(folder, 0o555)
        return []
    if shutil.which("unshare") is None or subprocess.run(
            ["unshare", "-m", "sh", "-c", RO_MOUNT, str(folder), "true"], capture_output=True).returncode != 0:
        pytest.skip("running as root without unshare/mount: no way to make a folder read-only")
    return ["unshare", "-m", "sh", "-c", RO_MOUNT, str(folder)]


def test_read_only_folder_is_refused_before_the_render(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    prefix = _read_only_prefix(ro)
    cmd = prefix + [sys.executable, "-c", "import sys; from skymodel.cli.main import main; sys.exit(main(sys.argv[1:]))",
                    "render", "--size", "16", "--out", str(ro / "sky.exr"), "--quiet"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, env=dict(os.environ, PYTHONPATH=ROOT), capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2, p.stderr
    line = _one_line(p.stderr)
    assert "out=" in line and "writable" in line
    assert time.perf_counter() - t0 < 60  # refused at the path check, not after a render
    assert os.listdir(ro) == []


def test_compare_out_in_a_read_only_folder(tmp_path, capsys, monkeypatch):
    """The same refusal through the probe, with the folder made read-only by a patched
    os.open (EROFS, as a read-only mount gives), in-process."""
    real_open = os.open

    def ro_open(path, flags, *a, **k):
        if str(path).startswith(str(tmp_path)) and flags & os.O_CREAT:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), path)
        return real_open(path, flags, *a, **k)

    monkeypatch.setattr(os, "open", ro_open)
    t0 = time.perf_counter()
    code = main(["compare", "--size", "16", "--out", str(tmp_path / "c.png")])
    err = capsys.readouterr().err
    assert code == 2 and time.perf_counter() - t0 < 1.0
    assert "out=" in _one_line(err) and "Read-only file system" in err


# ---------------------------------------------------------------------------- full disk


class _FullDisk(io.RawIOBase):
    """A file object that takes ``room`` bytes, then fails with ENOSPC."""

    def __init__(self, f, room):
        self.f, self.room = f, room

    def write(self, b):
        if len(b) > self.room:
            self.f.write(bytes(b[:self.room]))
            self.room = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(b)
        return self.f.write(b)

    def flush(self):
        if not self.f.closed:
            self.f.flush()

    def fileno(self):
        return self.f.fileno()

    def close(self):
        super().close()
        self.f.close()


def _save(folder, value):
    """save_outputs of a tiny synthetic image: EXR + PNG in ``folder``."""
    from skymodel.render import image_io
    from skymodel.render.cameras import make_camera
    from skymodel.wavelengths import default_wavelengths

    wl = default_wavelengths(50.0)
    cam = make_camera("equirectangular", 16, 8, n_wavelengths=wl.size)
    rad = np.full((8, 16, wl.size), value)
    return image_io.save_outputs(out=str(folder / "sky.exr"), png=str(folder / "sky.png"), radiance=rad,
                                 wavelengths=wl, camera=cam)


def test_enospc_during_the_write_keeps_the_last_complete_files(tmp_path, monkeypatch):
    _save(tmp_path, 0.01)
    before = {n: (tmp_path / n).read_bytes() for n in ("sky.exr", "sky.png")}
    real_fdopen = os.fdopen
    monkeypatch.setattr(os, "fdopen", lambda fd, *a, **k: _FullDisk(real_fdopen(fd, *a, **k), 100))
    with pytest.raises(OSError) as e:
        _save(tmp_path, 0.02)
    assert e.value.errno == errno.ENOSPC
    assert litter(tmp_path) == []
    assert {n: (tmp_path / n).read_bytes() for n in ("sky.exr", "sky.png")} == before


def test_enospc_through_the_cli_is_one_line_and_exit_1(tmp_path, capsys, monkeypatch):
    from skymodel.render import sky

    monkeypatch.setattr(sky, "render_sky", _fake_render)
    monkeypatch.setattr(sky, "render_sky_reduced", _fake_reduced)
    real_fdopen = os.fdopen
    monkeypatch.setattr(os, "fdopen", lambda fd, *a, **k: _FullDisk(real_fdopen(fd, *a, **k), 10))
    code = main(["render", "--size", "16", "--wavelength-step", "50", "--quiet", "--out", str(tmp_path / "s.exr")])
    err = capsys.readouterr().err
    assert code == 1
    assert "No space left on device" in _one_line(err)
    assert os.listdir(tmp_path) == []


def _fake_render(profile, camera, *a, **k):
    from skymodel.render import sky

    dirs, valid = camera.directions()
    rad = np.full(camera.shape + (profile.wavelengths_nm.size,), 0.01) * valid[..., None]
    return sky.SkyImage(rad, valid, dirs, profile.wavelengths_nm, camera, np.array([0, 0, 1.0]),
                        np.ones(profile.wavelengths_nm.size), {"total_s": 0.0, "orders": 1})


def _fake_reduced(profile, camera, el, reduce, n_channels, *a, **k):
    dirs, valid = camera.directions()
    return (np.full(camera.shape + (n_channels,), 0.01) * valid[..., None], np.ones(profile.wavelengths_nm.size),
            {"total_s": 0.0, "orders": 1})


def _small_files():  # pragma: no cover - runs in the child
    import resource

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (256, 256))  # smaller than any EXR header


def test_a_real_file_size_limit_fails_cleanly(tmp_path):
    """The kernel refuses the write (RLIMIT_FSIZE: EFBIG, as a full disk refuses with
    ENOSPC): exit 1, one line, nothing left behind."""
    p = child(FAKE_RENDER, "render", "--size", "64", "--wavelength-step", "50", "--quiet", "--out",
              str(tmp_path / "sky.exr"), preexec_fn=_small_files)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 1, err
    assert "File too large" in _one_line(err)
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------------------- signals


@pytest.mark.parametrize("fault, status, word", [("sigint", 130, "SIGINT"), ("sigterm", 143, "SIGTERM")])
def test_signal_during_the_write(tmp_path, fault, status, word):
    args = ["render", "--size", "16", "--wavelength-step", "50", "--quiet", "--out", str(tmp_path / "sky.exr")]
    p = child(FAKE_RENDER, *args)
    assert p.communicate(timeout=120)[0] is not None and p.returncode == 0
    before = (tmp_path / "sky.exr").read_bytes()
    p = child(FAKE_RENDER, *args, env={"FAULT": fault})
    out, err = p.communicate(timeout=120)
    assert p.returncode == status, err
    assert word in _one_line(err)
    assert litter(tmp_path) == []
    assert (tmp_path / "sky.exr").read_bytes() == before


@pytest.mark.parametrize("sig, status, word", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")])
def test_signal_during_the_render(tmp_path, sig, status, word):
    p = child("import sys; from skymodel.cli.main import main; sys.exit(main(sys.argv[1:]))", "render", "--size",
              "16", "--quality", "preview", "--out", str(tmp_path / "sky.exr"))
    # wait for the render to start (its first progress line), then interrupt it
    seen = []
    while not any("atmosphere:" in ln for ln in seen):
        seen.append(p.stderr.readline())
        assert seen[-1], seen  # the child ended before its render started
    time.sleep(0.3)
    p.send_signal(sig)
    out, err = p.communicate(timeout=120)
    assert p.returncode == status, err
    assert "Traceback" not in err
    assert word in err.strip().splitlines()[-1]
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------------------- two writers

TWO_WRITERS = """
import sys
import numpy as np
from skymodel.render import image_io
path, value, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
img = np.full((64, 64, 3), value, dtype=np.uint8)
for _ in range(n):
    image_io.write_png(path, img)
"""


def test_two_writers_to_one_path_leave_one_complete_file(tmp_path):
    from skymodel.render import image_io

    expected = set()
    for value in (10, 200):
        ref = tmp_path / f"ref{value}.png"
        image_io.write_png(str(ref), np.full((64, 64, 3), value, dtype=np.uint8))
        expected.add(ref.read_bytes())
    target = tmp_path / "shared" / "sky.png"
    target.parent.mkdir()
    procs = [child(TWO_WRITERS, str(target), str(v), "60") for v in (10, 200)]
    seen = set()
    while any(p.poll() is None for p in procs):
        if target.exists():
            try:
                seen.add(target.read_bytes())
            except FileNotFoundError:  # pragma: no cover - never with os.replace
                pytest.fail("the file vanished between two writes")
        time.sleep(0.005)
    for p in procs:
        assert p.wait() == 0, p.stderr.read()
    seen.add(target.read_bytes())
    assert seen <= expected  # every state a reader saw was one writer's complete image
    assert litter(target.parent) == []
