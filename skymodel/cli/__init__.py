"""The ``skymodel`` command line.

One module per command, the argument groups that several commands share in
:mod:`skymodel.cli.options`, and the parser in :mod:`skymodel.cli.main`. Every command
checks its input before any work and reports bad input in one line naming the parameter
and its allowed range (exit status 2). May import every other wing; no command imports
another command.
"""

from skymodel.cli.main import main

__all__ = ["main"]
