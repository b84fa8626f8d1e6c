"""The compiled libraries built side by side before anything needs them (``make libraries``)."""

import pytest
from toywalk.model import prebuild


def test_every_library_is_built_once_side_by_side(tmp_path, monkeypatch):
    """``build_libraries`` shares the libraries out over its processes: a stand-in compiler that
    records each call and fails (so each process falls back to the virtual machine, and nothing
    waits on gcc) is called once per library, from two processes."""
    log = tmp_path / "calls.log"
    fake = tmp_path / "cc"
    fake.write_text("#!/bin/sh\n"
                    'for a; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done\n'
                    f'echo "$PPID $(basename "$out")" >> {log}\nexit 1\n')
    fake.chmod(0o755)
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", str(fake))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    seconds = prebuild.build_libraries(jobs=2)
    assert list(seconds) == [entry[0] for entry in prebuild.LIBRARIES]
    calls = [line.split() for line in log.read_text().splitlines()]
    # one call per library (outputs are named NAME-HASH.so, the hash that of the code)
    assert len(calls) == len({name for _, name in calls}) == len(prebuild.LIBRARIES)
    assert len({pid for pid, _ in calls}) == 2


def test_build_libraries_refuses_no_jobs():
    with pytest.raises(ValueError, match="jobs must be at least 1"):
        prebuild.build_libraries(jobs=0)
