"""skymodel.render.environment: the equirectangular environment map, its lamp and exposure
numbers and its cache (no Blender)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from skymodel.optics.atmosphere import Atmosphere
from skymodel.render import environment, exposure


@pytest.fixture(scope="module")
def atmosphere():
    return Atmosphere(location="rural", month=6)


def test_camera_is_centred_on_east():
    cam = environment.environment_camera(64)
    dirs, valid = cam.directions()
    centre = dirs[cam.height // 2 - 1:cam.height // 2 + 1, cam.width // 2 - 1:cam.width // 2 + 1].mean(axis=(0, 1))
    assert centre[0] > 0.99  # +X is east
    assert dirs[0, :, 2].min() > 0.99  # the top row looks up


def test_width_by_quality_and_even():
    assert environment.image_width(0, "preview") == environment.IMAGE_WIDTH["preview"]
    assert environment.image_width(33, "final") == 34
    assert environment.image_width(4, "final") == 16


def test_render_then_cache_hit(atmosphere, tmp_path):
    lines = []
    rgb, env = environment.render_environment(atmosphere, 20.0, 135.0, width=32, cache_dir=tmp_path,
                                              progress=lines.append)
    assert rgb.shape == (16, 32, 3) and rgb.dtype == np.float32 and np.all(rgb >= 0)
    assert not env.cache_hit and env.info["cache"] == "miss"
    assert 0 < env.sun_strength < 200 and env.sun_colour[1] > 0
    incident = exposure.exposure_from_illuminance(env.info["horizontal_illuminance_Y"])
    sky = exposure.exposure_from_sky(env.info["sky_log_average_Y"])
    assert env.exposure == pytest.approx(min(incident, sky))
    assert env.info["exposure_incident"] == pytest.approx(incident)
    meta = json.loads((tmp_path / f"sky-{env.info['cache_key']}.json").read_text())
    assert meta["result"] == env.lamp()
    assert any(line.startswith("writing") for line in lines)
    again, hit = environment.render_environment(atmosphere, 20.0, 135.0, width=32, cache_dir=tmp_path)
    assert again is None and hit.cache_hit and hit.image_path == env.image_path
    assert hit.lamp() == env.lamp()
    # another input, another key
    _, other = environment.render_environment(atmosphere, 20.0, 135.0, width=32, include_sun=True, cache_dir=tmp_path)
    assert other.info["cache_key"] != env.info["cache_key"]


def test_other_code_misses_the_cache(atmosphere, tmp_path, monkeypatch):
    """A sky cached by other code (another package tag: another file of skymodel's sources or
    data) is not served: its key differs, so the same inputs render again."""
    from skymodel.render import provenance

    _, first = environment.render_environment(atmosphere, 20.0, 135.0, width=16, cache_dir=tmp_path)
    monkeypatch.setattr(provenance, "package_tag", lambda: "0123456789")
    _, other = environment.render_environment(atmosphere, 20.0, 135.0, width=16, cache_dir=tmp_path)
    assert not other.cache_hit and other.info["cache_key"] != first.info["cache_key"]


def test_another_model_comes_through_model_radiance(atmosphere, tmp_path):
    def flat(camera, wavelengths_nm, include_sun):
        dirs, valid = camera.directions()
        return np.full(valid.shape + (len(wavelengths_nm),), 0.01), np.full(len(wavelengths_nm), 1.0)

    rgb, env = environment.render_environment(atmosphere, 30.0, 180.0, width=32, sky_model="flat",
                                              model_radiance=flat, cache_dir=tmp_path)
    assert np.allclose(rgb, rgb[0, 0]) and env.info["sky_model"] == "flat"
    with pytest.raises(ValueError, match="model_radiance"):
        environment.render_environment(atmosphere, 30.0, 180.0, width=32, sky_model="flat", cache_dir=tmp_path)


def test_imports_no_blender():
    code = "import sys, skymodel.render.environment; assert 'bpy' not in sys.modules and 'blender_addon' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_display_exposure_is_the_incident_rule_in_daylight_and_darker_at_dusk():
    """The sky meter (Krawczyk et al. 2005 key on the sky's log-average) caps the incident
    rule: a bright day sky keeps the incident exposure, a dusk sky is shown darker than the
    white-plate rule would, and a dimmer sky at a lower key."""
    assert exposure.sky_key(4.55) == pytest.approx(0.666, abs=0.002)  # 3100 cd/m2
    assert exposure.sky_key(1.0 / 683.0) == pytest.approx(0.161, abs=0.001)  # 1 cd/m2
    assert exposure.sky_key(0.0) == pytest.approx(0.03)  # L = 0: 1.03 - 2 / 2
    # daylight (rural June, sun 30 degrees): E_h 83.4, sky log-average 4.55 -> incident wins
    assert exposure.exposure_from_sky(4.55) > exposure.exposure_from_illuminance(83.4)
    # sun at the horizon: E_h 1.43, log-average 0.533 -> the sky meter, ~2.8 EV darker
    d = exposure.exposure_from_sky(0.533) - exposure.exposure_from_illuminance(1.43)
    assert -3.2 < d < -2.4
    # a dimmer sky is shown darker (lower key), not at the same level
    assert exposure.sky_key(0.02) < exposure.sky_key(0.5) < exposure.sky_key(5.0)


def test_clear_cache_deletes_and_counts_the_stored_solutions(tmp_path):
    """clear_cache / cache_size cover the multiple-scattering solutions that solution_cache
    stores in <cache folder>/solutions (SolutionCache.path names them; _store's temporaries
    are mkstemp(prefix=name + ".", suffix=".tmp")), and only those: other files stay."""
    import fnmatch
    import os
    import tempfile

    folder = tmp_path / "cache"
    sols = folder / environment.SOLUTIONS_FOLDER
    sols.mkdir(parents=True)
    stored = environment.solution_cache(folder).path("ab" * 32)
    assert stored.parent == sols
    assert any(fnmatch.fnmatch(stored.name, p) for p in environment.SOLUTION_PATTERNS)
    stored.write_bytes(b"x" * 300)
    fd, tmp = tempfile.mkstemp(prefix=stored.name + ".", suffix=".tmp", dir=sols)  # as SolutionCache._store
    os.write(fd, b"y" * 20)
    os.close(fd)
    (folder / "sky-0123.exr").write_bytes(b"e" * 50)
    (folder / "sky-0123.json").write_bytes(b"{}")
    (sols / "README.txt").write_text("not ours")
    (folder / "solution-v1-x.pickle").write_bytes(b"not in solutions/")
    assert environment.cache_size(folder) == (4, 300 + 20 + 50 + 2)
    assert environment.clear_cache(folder, keep=[folder / "sky-0123.exr"]) == (3, 300 + 20 + 2)
    assert sorted(p.name for p in sols.iterdir()) == ["README.txt"]
    assert (folder / "sky-0123.exr").is_file() and (folder / "solution-v1-x.pickle").is_file()
    (sols / "README.txt").unlink()
    assert environment.clear_cache(folder) == (1, 50)
    assert not sols.exists()  # emptied by the cache: removed
    assert environment.cache_size(tmp_path / "missing") == (0, 0)
