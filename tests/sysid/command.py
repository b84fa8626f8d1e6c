"""The `toywalk` command line as a user runs it, in a fresh Python process."""

import subprocess
import sys

__all__ = ["run"]


def run(*args):
    """``toywalk ARGS`` (``python -m toywalk.sysid.cli``; each argument through ``str``), its
    output captured as text: the finished :class:`subprocess.CompletedProcess`."""
    return subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600)
