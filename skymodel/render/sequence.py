"""Sequences of skies: one multiple-scattering solve shared by every frame of one atmosphere.

The multiple-scattering field depends on the optical profile and the march settings but not
on the sun: its table spans every sun elevation and the sun's azimuth only rotates the sky
about the zenith (:class:`~skymodel.render.marcher.SkySolution`). A sequence therefore
solves once per distinct profile (:func:`~skymodel.render.marcher.optics_key`) and then
marches each frame's pixels at its own sun: :func:`render_frame` is
:func:`skymodel.render.sky.render_sky` with the solve taken from a :class:`SolutionCache`
(``render_sky(..., solution=)``), so a frame equals an independent render of the same
instant bit for bit (the same arithmetic on the same arrays; ``tests/test_sequence.py``);
:func:`render_frame_reduced` is the same for ``render_sky_reduced``.

:class:`SolutionCache` keeps the solutions in memory and, given a folder, on disk (one
pickle per key, written to a temporary file and renamed into place, so a crash never
leaves half a file; a file that cannot be read is solved again and rewritten). The cache
holds only files this program wrote; do not point it at a folder others can write to,
since a pickle can run code when loaded.
"""

from __future__ import annotations

import os
import pickle
import tempfile
import threading
import time
from collections import OrderedDict
from pathlib import Path

from skymodel.render import provenance
from skymodel.render.cameras import Camera
from skymodel.render.marcher import SkySolution, optics_key, solve_sky
from skymodel.render.quality import quality_settings
from skymodel.render.sky import SkyImage, check_render_arguments, render_sky, render_sky_reduced

__all__ = ["SolutionCache", "render_frame", "render_frame_reduced", "SOLUTION_FORMAT"]

#: Version of the pickled :class:`SkySolution` layout; part of every cache file's name, with the
#: package's version and :func:`skymodel.render.provenance.package_tag` (any change to the code or
#: data that makes a solve gives a new name, so no cache serves a solution the code would no
#: longer make; the key, :func:`optics_key`, covers only the profile and the settings).
SOLUTION_FORMAT = 8  # 4: the medium carries its delta-M cone (FactoredMedium.cutoff_deg); 5: the
#                      peak aureole's FFTLog table (60acfad), the altitude nodes' ground split;
#                      6: ``to_full`` a SolverSpectrumMap (was a matrix); 7: ``peak_spread``;
#                      8: ``peak_spread`` holds only the turned light (the marcher subtracts the rest)


class SolutionCache:
    """Multiple-scattering solutions by :func:`optics_key`, in memory (the ``keep`` most
    recent) and, with ``folder``, on disk. ``stats``: solves, memory hits, disk hits,
    unreadable files replaced."""

    def __init__(self, folder=None, keep: int = 4):
        self.folder = None if folder is None else Path(folder)
        self.keep = max(1, int(keep))
        self._memory: OrderedDict[str, SkySolution] = OrderedDict()
        # the add-on's builds run in threads (a cancelled one may finish while the next reads):
        # the memory dictionary is read and changed under this lock; solving and disk I/O are not
        self._lock = threading.Lock()
        self.stats = {"solves": 0, "memory_hits": 0, "disk_hits": 0, "corrupt": 0, "solve_s": 0.0}

    def path(self, key: str) -> Path | None:
        """The cache file of ``key`` (None without a folder)."""
        if self.folder is None:
            return None
        import skymodel

        version = getattr(skymodel, "__version__", "0")
        return self.folder / f"solution-v{SOLUTION_FORMAT}-{version}-{provenance.package_tag()}-{key[:32]}.pickle"

    def _load(self, key: str):
        path = self.path(key)
        if path is None or not path.is_file():
            return None
        try:
            with open(path, "rb") as f:
                sol = pickle.load(f)
            if not isinstance(sol, SkySolution) or sol.key != key:
                raise ValueError("not the solution of this key")
            return sol
        except Exception:  # unreadable, truncated, another version: solve again and overwrite
            self.stats["corrupt"] += 1
            return None

    def _store(self, sol: SkySolution) -> None:
        path = self.path(sol.key)
        if path is None:
            return
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump(sol, f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, path)  # atomic on one file system
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def get(self, profile, settings, progress=None) -> SkySolution:
        """The solution for ``profile`` and ``settings`` (MarchSettings or a quality name):
        from memory, from disk, or solved now (and stored)."""
        s = quality_settings(settings)
        key = optics_key(profile, s)
        with self._lock:
            sol = self._memory.get(key)
            if sol is not None:
                self._memory.move_to_end(key)
                self.stats["memory_hits"] += 1
                return sol
        sol = self._load(key)
        if sol is not None:
            self.stats["disk_hits"] += 1
        else:
            t0 = time.perf_counter()
            sol = solve_sky(profile, s, progress=progress)
            self.stats["solves"] += 1
            self.stats["solve_s"] += time.perf_counter() - t0
            self._store(sol)
        with self._lock:
            self._memory[key] = sol
            self._memory.move_to_end(key)
            while len(self._memory) > self.keep:
                self._memory.popitem(last=False)
        return sol


def _solution(profile, quality, solution, cache, progress):
    """``(solution, reused)``: the given solution, or the cache's (solved there when missing)."""
    if solution is not None:
        return solution, True
    cache = cache if cache is not None else SolutionCache()
    solves = cache.stats["solves"]
    solution = cache.get(profile, quality_settings(quality), progress=progress)
    return solution, cache.stats["solves"] == solves


def render_frame(profile, camera: Camera, sun_elevation_deg: float, sun_azimuth_deg: float = 180.0,
                 observer_altitude_m: float = 0.0, quality=None, include_sun: bool = True,
                 solution: SkySolution | None = None, cache: SolutionCache | None = None,
                 progress=None) -> SkyImage:
    """One frame: :func:`skymodel.render.sky.render_sky` with the multiple-scattering
    solve taken from ``solution`` or ``cache`` (solved there when missing).

    ``profile`` may carry the date's solar spectrum (scaled for the Earth-sun distance);
    the solution does not depend on it. Same arguments, checks and result as
    ``render_sky``; ``info["solve_reused"]`` says whether this frame used a solve made before."""
    check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, quality)
    t0 = time.perf_counter()
    solution, reused = _solution(profile, quality, solution, cache, progress)
    image = render_sky(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, quality,
                       include_sun, solution=solution)
    image.info["total_s"] = time.perf_counter() - t0
    image.info["solve_reused"] = bool(reused)
    return image


def render_frame_reduced(profile, camera: Camera, sun_elevation_deg: float, reduce, n_channels: int,
                         sun_azimuth_deg: float = 180.0, observer_altitude_m: float = 0.0, quality=None,
                         band_pixels: int = 65536, solution: SkySolution | None = None,
                         cache: SolutionCache | None = None, progress=None):
    """:func:`skymodel.render.sky.render_sky_reduced` with the solve from ``solution`` or
    ``cache``: ``(image (H, W, n_channels), sun_irradiance (n_wl,), info)``."""
    check_render_arguments(profile, camera, sun_elevation_deg, sun_azimuth_deg, observer_altitude_m, quality)
    t0 = time.perf_counter()
    solution, reused = _solution(profile, quality, solution, cache, progress)
    out, sun_irr, info = render_sky_reduced(profile, camera, sun_elevation_deg, reduce, n_channels,
                                            sun_azimuth_deg, observer_altitude_m, quality, band_pixels,
                                            solution=solution)
    info["total_s"] = time.perf_counter() - t0
    info["solve_reused"] = bool(reused)
    return out, sun_irr, info
