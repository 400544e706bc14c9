"""Shared helpers for the benchmarks: machine description and medians of repeated timings.

Machines are shared and noisy: every benchmark repeats its measurements, reports the
median (and the spread), and compares alternatives as ratios measured in the same run."""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import sys
import time


def machine() -> str:
    try:
        cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    except OSError:
        cpu = platform.processor() or "?"
    import numpy

    mem = ""
    try:
        kb = next(int(ln.split()[1]) for ln in open("/proc/meminfo") if ln.startswith("MemTotal"))
        mem = f", {kb / 1024**2:.0f} GiB RAM"
    except (OSError, StopIteration):
        pass
    return (f"{cpu}, {os.cpu_count()} cores{mem}; {platform.system()} {platform.release()}; "
            f"Python {platform.python_version()}, numpy {numpy.__version__}")


def git_revision() -> str:
    try:
        return subprocess.check_output(["git", "rev-parse", "--short", "HEAD"], text=True,
                                       stderr=subprocess.DEVNULL).strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def timeit(fn, repeat: int = 7, warmup: int = 1):
    """Run ``fn`` ``warmup`` times untimed, then ``repeat`` times; return (median s, min s, max s, last result)."""
    result = None
    for _ in range(warmup):
        result = fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times), max(times), result


def command_line() -> str:
    return "python " + " ".join([os.path.relpath(sys.argv[0])] + sys.argv[1:])


def update_section(path: str, heading: str, body: str) -> None:
    """Replace (or append) the markdown section that starts with ``heading`` in ``path``."""
    text = open(path, encoding="utf-8").read() if os.path.exists(path) else "# Benchmarks\n"
    lines = text.splitlines(keepends=True)
    start = next((i for i, ln in enumerate(lines) if ln.strip() == heading.strip()), None)
    block = heading.rstrip() + "\n\n" + body.rstrip() + "\n\n"
    if start is None:
        text = text.rstrip() + "\n\n" + block
    else:
        level = len(heading) - len(heading.lstrip("#"))
        end = next((j for j in range(start + 1, len(lines))
                    if lines[j].startswith("#") and len(lines[j]) - len(lines[j].lstrip("#")) <= level), len(lines))
        text = "".join(lines[:start]) + block + "".join(lines[end:])
    with open(path, "w", encoding="utf-8") as f:
        f.write(text.rstrip() + "\n")
