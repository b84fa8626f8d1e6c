"""docs/cli.md, the command reference: a section for every command of `toywalk`, and in it every
option today's parser takes, so that an option added or renamed without the reference following
fails here."""

import re

from toywalk.sysid.cli import build_parser

from .conftest import DATA

ROOT = DATA.parent


def _sections() -> dict[str, str]:
    """The text of each ``## `toywalk CMD` `` section of docs/cli.md, by command."""
    text = (ROOT / "docs" / "cli.md").read_text()
    parts = re.split(r"^## `toywalk (\w+)`\n", text, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def test_every_command_has_a_section_with_every_option():
    commands = build_parser()._subparsers._group_actions[0].choices
    sections = _sections()
    assert set(sections) == set(commands)
    for name, parser in commands.items():
        for action in parser._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}" in sections[name], f"toywalk {name} {option}: not in docs/cli.md"
