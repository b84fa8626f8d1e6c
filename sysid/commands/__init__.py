"""The ``toywalk`` commands, one module each (:mod:`toywalk.sysid.cli` runs them): each parses
its options (``register(subparsers)``), checks them, calls the library and reports. What they
share (the one-line error, progress lines, output checks, running a command line) is
:mod:`~toywalk.sysid.commands.common`'s. Every option: docs/cli.md.
"""
