"""What every command shares: the one-line error (:class:`CommandError`), progress lines
(:func:`say`), the checks of output paths and sizes, reading a walker, and running a command line
(:func:`run`: parse, call the command, turn its error into one line and an exit status)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

__all__ = ["DESCRIPTION", "PROGRESS", "CommandError", "load_walker", "output_path", "parse_size",
           "refuse_overwrite", "run", "say", "scuffs_in", "with_effects"]

#: The command line's one-line description (``toywalk --help``).
DESCRIPTION = "toywalk: film a passive-dynamic walker, fit its model, and find what the model gets wrong."

#: How a progress line on stderr starts (every command's stages; the robustness suite tells them
#: from error lines by it).
PROGRESS = "... "


def say(message: str) -> None:
    """One progress line on stderr, flushed at once, whether stderr is a terminal, a file or a
    pipe: a stage that takes more than a few seconds says what it does before it starts, so that
    a log shows where a long run is (a progress bar, which redraws its line, only in a
    terminal)."""
    print(f"{PROGRESS}{message}", file=sys.stderr, flush=True)


class CommandError(Exception):
    """Bad input or an impossible request: printed as one line, exit status 2."""


def output_path(value: str, suffixes: tuple[str, ...], option: str = "--out") -> Path:
    """The path an option names for writing: one of ``suffixes`` (case-insensitive), in a folder
    that exists; otherwise :class:`CommandError` with one line."""
    out = Path(value)
    if out.suffix.lower() not in suffixes:
        raise CommandError(f"{option} must name a {' or '.join(suffixes)} file, got {out}")
    if not out.parent.is_dir():
        raise CommandError(f"output folder does not exist: {out.parent}")
    return out


def refuse_overwrite(outputs, inputs) -> None:
    """:class:`CommandError` (one line) when an output path is one of the input paths (None: none)."""
    given = {Path(p).resolve() for p in inputs if p is not None}
    clash = [p for p in outputs if p is not None and Path(p).resolve() in given]
    if clash:
        raise CommandError(f"the output would overwrite the input {clash[0]}; choose another --out name")


def parse_size(text: str) -> tuple[int, int]:
    """An image size ``WxH`` in pixels (16 to 8192 each), or a :class:`CommandError`."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError as err:
        raise CommandError(f"--size must be WxH in pixels, e.g. 1280x720, got {text!r}") from err
    if w < 16 or h < 16 or w > 8192 or h > 8192:
        raise CommandError(f"--size must be between 16x16 and 8192x8192, got {text!r}")
    return w, h


def load_walker(path: str):
    """The parameter file ``path`` read, or its error as one :class:`CommandError` line."""
    from toywalk.model.parameters import ParameterError, load_params

    try:
        return load_params(path)
    except ParameterError as err:
        raise CommandError(str(err)) from err


def with_effects(params, items):
    """``params`` with the command line's ``--effect NAME=VALUE`` settings (``items``, the
    option's values; None for none), or a :class:`CommandError` line naming the bad one."""
    from toywalk.model.parameters import ParameterError

    effects = _parse_effects(items)
    if not effects:
        return params
    try:
        return params.replace(**{f"effects.{k}": v for k, v in effects.items()})
    except ParameterError as err:
        raise CommandError(str(err)) from err


def _parse_effects(items) -> dict:
    out = {}
    for item in items or ():
        if "=" not in item:
            raise CommandError(f"--effect expects NAME=VALUE, got {item!r}")
        name, value = item.split("=", 1)
        name = name.strip().removeprefix("effects.")
        try:
            out[name] = float(value)
        except ValueError as err:
            raise CommandError(f"--effect {name}: not a number: {value!r}") from err
    return out


def scuffs_in(table, leg_length: float) -> str:
    """The scuffs of a simulated walk, said as every command says them
    (:func:`toywalk.model.walker.describe_scuffs`), from its metadata (``scuffs``,
    ``swing_clearance_m``; counted over its heel strikes); "" for none, or a walk that does not
    record them (a tracked one)."""
    from toywalk.model.walker import CLEARANCE_RESOLUTION, describe_scuffs

    scuffs = table.metadata.get("scuffs")
    if not isinstance(scuffs, int) or isinstance(scuffs, bool) or scuffs <= 0:
        return ""
    lowest = table.metadata.get("swing_clearance_m")
    return describe_scuffs(scuffs, max(len(table.events), 1),
                           lowest if isinstance(lowest, (int, float)) else None,
                           CLEARANCE_RESOLUTION * leg_length)



def build_parser(commands) -> argparse.ArgumentParser:
    """The ``toywalk`` parser of the command modules ``commands``, in that order: each defines
    ``register(subparsers)``, adding its sub-parser with ``set_defaults(func=...)``, and its
    function raises :class:`CommandError` for bad input."""
    parser = argparse.ArgumentParser(prog="toywalk", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True)
    for module in commands:
        module.register(sub)
    return parser


def run(argv, commands) -> int:
    """Run the command line ``argv`` (None: ``sys.argv[1:]``) of the command modules
    ``commands`` (:func:`build_parser`): the command's exit status; bad input (a
    :class:`CommandError`) one line on stderr and status 2, an interrupt 130, a closed stdout
    141."""
    parser = build_parser(commands)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except CommandError as err:
        print(f"toywalk {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"toywalk {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (`toywalk gait --json | head`): stop quietly, as Unix
        # tools do; point stdout at /dev/null so that Python's own flush at exit cannot raise
        # (https://docs.python.org/3/library/signal.html#note-on-sigpipe)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
