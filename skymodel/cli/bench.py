"""``skymodel bench accuracy``: what accuracy costs in time, as a command.

The benchmark itself (scenes, knobs, error metrics, the reference cache) is
:mod:`skymodel.validation.accuracy`; this module is its command line.

The command writes only where it is pointed: the measured table (``--json``) and the
markdown with its plots (``--out``; the PNGs go to ``img/`` beside it). Without them it
writes into :data:`DEFAULT_DIR` (``--quick``: :data:`QUICK_DIR`) under the current
directory. The project's own copies, ``docs/accuracy.md`` of a source checkout and the
package's table ``skymodel/data/presets/accuracy/measured.json`` (which the planner
reads), are rewritten only with ``--write-docs``.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

#: Where a run writes when no --out/--json is given (relative to the current directory).
DEFAULT_DIR = "bench-accuracy"
#: The same for --quick runs, so that a quick run never replaces a full one's table.
QUICK_DIR = "bench-accuracy-quick"
MARKDOWN_NAME = "accuracy.md"
TABLE_NAME = "measured.json"


def add_bench_command(sub) -> None:
    """Register ``skymodel bench accuracy`` on the CLI's subparsers."""
    from skymodel.validation.accuracy import KNOBS, SCENES

    p = sub.add_parser("bench", help="benchmarks: what accuracy costs in time")
    bsub = p.add_subparsers(dest="bench", required=True)
    a = bsub.add_parser(
        "accuracy", help="error vs time of every renderer knob and of the quality presets",
        description="Measure the error against a converged reference and the time of every renderer knob and of "
                    f"the quality presets. Writes the measured table and a markdown report into ./{DEFAULT_DIR}/ "
                    f"(./{QUICK_DIR}/ with --quick) unless --json/--out say where; only --write-docs rewrites the "
                    "project's docs/accuracy.md and the package's measured table.")
    a.add_argument("--quick", action="store_true", help="a small run (one scene, 32x16, cheap settings; ~1 min)")
    a.add_argument("--out", default=None, metavar="MD",
                   help=f"markdown to write or update between its markers, plots in img/ beside it (default "
                        f"{DEFAULT_DIR}/{MARKDOWN_NAME}; with --quick: {QUICK_DIR}/{MARKDOWN_NAME})")
    a.add_argument("--json", default=None, metavar="JSON",
                   help=f"measured table to write; a run restricted with --knobs/--scenes merges into it if it exists "
                        f"(default {DEFAULT_DIR}/{TABLE_NAME}; with --quick: {QUICK_DIR}/{TABLE_NAME})")
    a.add_argument("--write-docs", action="store_true",
                   help="write into the project's docs/accuracy.md (and docs/img/) and the package's "
                        "skymodel/data/presets/accuracy/measured.json instead (a source checkout only; not with "
                        "--quick, --out or --json)")
    a.add_argument("--knobs", default=None, help="comma-separated subset of: " + ", ".join(KNOBS))
    a.add_argument("--scenes", default=None, help="comma-separated subset of: " + ", ".join(SCENES))
    a.add_argument("--merge", nargs="+", metavar="PART_JSON", default=None,
                   help="render nothing: merge the measured tables of restricted runs (e.g. one per scene run in "
                        "parallel, then --knobs preset alone) in this order, and write the result like a run")
    a.set_defaults(func=cmd_bench_accuracy)


def checked_in_targets() -> tuple[str, str]:
    """(docs/accuracy.md, the package's measured table) of the source checkout this
    package runs from; ``ValueError`` when it does not run from one (an installed wheel
    has no docs/, and its package data is not the project's)."""
    import skymodel
    from skymodel.data import data_path

    root = Path(skymodel.__file__).resolve().parent.parent
    md = root / "docs" / MARKDOWN_NAME
    table = Path(data_path("presets", "accuracy", TABLE_NAME)).resolve()
    if not md.is_file() or not table.is_relative_to(root):
        raise ValueError(f"--write-docs rewrites docs/{MARKDOWN_NAME} and skymodel/data/presets/accuracy/{TABLE_NAME} "
                         f"of a source checkout (pip install -e); this skymodel runs from {root}, which has no "
                         f"docs/{MARKDOWN_NAME}")
    return str(md), str(table)


def _targets(args) -> tuple[str, str]:
    """(markdown, table) paths this run writes, after checking the flags' combination."""
    if args.write_docs:
        given = [f for f, v in (("--quick", args.quick), ("--out", args.out), ("--json", args.json)) if v]
        if given:
            raise ValueError(f"--write-docs writes the project's own files; it does not go with {', '.join(given)}")
        return checked_in_targets()
    folder = QUICK_DIR if args.quick else DEFAULT_DIR
    return args.out or os.path.join(folder, MARKDOWN_NAME), args.json or os.path.join(folder, TABLE_NAME)


def _load_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def cmd_bench_accuracy(args) -> int:
    from skymodel.validation import accuracy, accuracy_report

    try:
        md, table = _targets(args)
    except ValueError as e:
        print(f"skymodel bench accuracy: error: {e}", file=sys.stderr)
        return 2
    write_docs = " --write-docs" if args.write_docs else ""
    if args.merge:
        try:
            result = accuracy.merge_parts([_load_json(p) for p in args.merge])
        except (OSError, ValueError, KeyError) as e:
            print(f"skymodel bench accuracy --merge: {e}", file=sys.stderr)
            return 2
        result["command"] = "skymodel bench accuracy" + write_docs
        accuracy_report.write_json(result, table)
        accuracy_report.write_markdown(result, md)
        print(f"wrote {table} and {md}", file=sys.stderr)
        return 0
    knobs = [k.strip() for k in args.knobs.split(",")] if args.knobs else None
    scenes = [k.strip() for k in args.scenes.split(",")] if args.scenes else None
    cmd = "skymodel bench accuracy" + (" --quick" if args.quick else "") + "".join(
        f" --{k} {v}" for k, v in (("out", args.out), ("json", args.json), ("knobs", args.knobs),
                                   ("scenes", args.scenes)) if v) + write_docs
    accuracy.bench(args.quick, md, table, knobs, scenes, command=cmd,
                   log=lambda m: print(m, file=sys.stderr, flush=True))
    return 0
