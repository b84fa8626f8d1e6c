"""The suite's own scheduling hint (conftest.LONGEST_FIRST) names files that exist."""

from pathlib import Path

from .conftest import LONGEST_FIRST


def test_the_longest_files_exist():
    here = Path(__file__).resolve().parent
    missing = [name for name in LONGEST_FIRST if not (here / name).is_file()]
    assert not missing, f"conftest.LONGEST_FIRST names files that are gone: {missing}"
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
