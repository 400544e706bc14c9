"""Benchmark: what accuracy costs in time (issue 3) — the same run as
``skymodel bench accuracy``: error against a converged reference and wall-clock time of
every renderer knob on its own and of the quality presets, on three scenes.

    nice -n 10 python benchmarks/bench_accuracy.py            # full: docs/accuracy.md, skymodel/data/presets/accuracy/measured.json
    python benchmarks/bench_accuracy.py --quick                # small run into out/accuracy-quick/

References are cached under .cache/accuracy (or $SKYMODEL_CACHE/accuracy); delete it to
re-render them. See skymodel/accuracy.py for the scenes, knobs and error metrics.
"""

from __future__ import annotations

import sys

from skymodel.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "accuracy"] + sys.argv[1:]))
