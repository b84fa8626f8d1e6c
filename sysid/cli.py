"""toywalk: film a passive-dynamic walker, fit its model, and find what the model gets wrong.

The command line (every option: docs/cli.md): :func:`main`, the ``toywalk`` console script, runs
one of the commands of :mod:`toywalk.sysid.commands`, one module each. Every command exits
non-zero with one clear line on stderr for bad input, and never leaves a half-written output file
behind.
"""

from __future__ import annotations

import argparse
import sys

from .commands import (
    accuracy,
    calibrate,
    demo,
    diagnose,
    effects,
    fit,
    gait,
    render,
    sample,
    simulate,
    track,
)
from .commands.common import PROGRESS, run, say
from .commands.common import build_parser as _parser

__all__ = ["COMMANDS", "PROGRESS", "build_parser", "main", "say"]

#: The commands' modules, in the order ``toywalk --help`` lists them.
COMMANDS = (calibrate, render, track, accuracy, fit, sample, diagnose, demo, gait, effects, simulate)


def build_parser() -> argparse.ArgumentParser:
    """The ``toywalk`` parser of every command (:data:`COMMANDS`)."""
    return _parser(COMMANDS)


def main(argv=None) -> int:
    """``toywalk ARGV``: the command's exit status (:func:`toywalk.sysid.commands.common.run`)."""
    return run(argv, COMMANDS)


if __name__ == "__main__":
    sys.exit(main())
