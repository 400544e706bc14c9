"""The ``skymodel`` command line: the parser and the dispatch.

Commands, one module each: ``profile``, ``sun``, ``presets``, ``render``, ``radiance``,
``compare`` (:mod:`skymodel.cli.profile` ...) and ``bench`` (:mod:`skymodel.cli.bench`).
Every command takes ``--json`` for machine-readable output where it prints results;
errors in the input print one line naming the parameter and exit with status 2.
"""

from __future__ import annotations

import argparse
import sys

from skymodel.cli import bench, compare, presets, profile, radiance, render, sun
from skymodel.errors import SkymodelInputError

#: The command registrars, in the order ``skymodel --help`` lists them; each takes the subparsers object.
COMMANDS = (profile.add_command, sun.add_command, presets.add_command, render.add_command, radiance.add_command,
            compare.add_command, bench.add_bench_command)


def build_parser() -> argparse.ArgumentParser:
    """The ``skymodel`` parser with every command registered."""
    parser = argparse.ArgumentParser(prog="skymodel", description="Physically based spectral sky and atmosphere.")
    sub = parser.add_subparsers(dest="command", required=True)
    for register in COMMANDS:
        register(sub)
    return parser


def main(argv=None) -> int:
    """Run the command line (``argv`` without the program name); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except SkymodelInputError as exc:
        print(f"skymodel {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
