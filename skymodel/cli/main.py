"""The ``skymodel`` command line: the parser and the dispatch.

Commands, one module each: ``profile``, ``sun``, ``presets``, ``render``, ``timelapse``,
``radiance``, ``compare`` (:mod:`skymodel.cli.profile` ...) and ``bench`` (:mod:`skymodel.cli.bench`).
Every command takes ``--json`` for machine-readable output where it prints results.

Exit statuses, each with one line on stderr and no traceback:

* 2: bad input (a :class:`~skymodel.errors.SkymodelInputError` naming the parameter and
  what is allowed, or a usage error), found before any work starts;
* 1: the work failed on the system's side (an output that cannot be written at the end:
  disk full, permissions); the writers are atomic, so nothing partial is left behind;
* 130 / 143: interrupted by SIGINT (Ctrl-C) / SIGTERM; temporary files are removed.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from skymodel.cli import bench, compare, presets, profile, radiance, render, sun, timelapse
from skymodel.errors import SkymodelInputError

#: The command registrars, in the order ``skymodel --help`` lists them; each takes the subparsers object.
COMMANDS = (profile.add_command, sun.add_command, presets.add_command, render.add_command,
            timelapse.add_command, radiance.add_command, compare.add_command, bench.add_bench_command)


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors in one line (exit status 2), like every other input error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


class Terminated(BaseException):
    """Raised in the main thread by the SIGTERM handler, so ``finally`` blocks (the atomic
    writers' clean-up) run as they do for Ctrl-C."""


def _raise_terminated(signum, frame):
    raise Terminated(signum)


def build_parser() -> argparse.ArgumentParser:
    """The ``skymodel`` parser with every command registered."""
    parser = _Parser(prog="skymodel", description="Physically based spectral sky and atmosphere.")
    sub = parser.add_subparsers(dest="command", required=True)
    for register in COMMANDS:
        register(sub)
    return parser


def main(argv=None) -> int:
    """Run the command line (``argv`` without the program name); returns the exit status
    (0 done, 1 system failure, 2 bad input, 130 SIGINT, 143 SIGTERM; see the module doc)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    prefix = f"skymodel {args.command}"
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _raise_terminated) if in_main else None
    try:
        return int(args.func(args) or 0)
    except SkymodelInputError as exc:
        print(f"{prefix}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\n{prefix}: interrupted (SIGINT); no partial output left", file=sys.stderr)
        return 128 + signal.SIGINT
    except Terminated:
        print(f"\n{prefix}: terminated (SIGTERM); no partial output left", file=sys.stderr)
        return 128 + signal.SIGTERM
    except OSError as exc:
        where = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"{prefix}: error:{where}: {exc.strerror or exc}; no partial output left", file=sys.stderr)
        return 1
    finally:
        if in_main:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
