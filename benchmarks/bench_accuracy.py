"""Benchmark: what accuracy costs in time (issue 3) — ``skymodel bench accuracy`` writing
into the project: error against a converged reference and wall-clock time of every
renderer knob on its own and of the quality presets, on three scenes, written into
docs/accuracy.md (between its markers, plots in docs/img/) and the package's table
skymodel/data/presets/accuracy/measured.json (``--write-docs``).

    nice -n 10 python benchmarks/bench_accuracy.py                  # full run into the docs (about 2 h)
    nice -n 10 python benchmarks/bench_accuracy.py --knobs geometry # re-measure one knob, merged into them
    python benchmarks/bench_accuracy.py --quick                     # small run into ./bench-accuracy-quick/

With ``--quick``, ``--out`` or ``--json`` the arguments go to the command as they are (the
docs are left alone). References are cached under .cache/accuracy (or
$SKYMODEL_CACHE/accuracy); delete it to re-render them. See
skymodel/validation/accuracy.py for the scenes, knobs and error metrics.
"""

from __future__ import annotations

import sys

from skymodel.cli import main

if __name__ == "__main__":
    args = sys.argv[1:]
    own = {"--quick", "--out", "--json", "--write-docs"}
    if not any(a.split("=", 1)[0] in own for a in args):
        args.append("--write-docs")
    sys.exit(main(["bench", "accuracy"] + args))
