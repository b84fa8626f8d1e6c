"""`toywalk gait --all`: every distinct gait of model/gait_search.py, printed and in JSON
(docs/cli.md; the numbers: docs/gaits.md section 6)."""

import json

from ..conftest import DATA
from .command import run

SIMPLEST = DATA / "params" / "simplest-walker.toml"


def test_gait_all_json_lists_the_gaits():
    out = run("gait", "--params", SIMPLEST, "--all", "--json")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    assert report["gaits"] and report["starts"] >= report["converged"] >= len(report["gaits"])
    # Garcia et al. 1998 (docs/model.md section 7): the long-period gait, 3.8825 sqrt(l/g).
    assert round(report["gaits"][0]["step_time"], 4) == 3.8825
    row = report["gaits"][0]
    assert row["stable"] and row["how"] and row["residual"] < report["fixed_point_tol"]
    assert len(row["fixed_point"]) == 8


def test_gait_all_prints_a_row_per_gait():
    out = run("gait", "--params", SIMPLEST, "--all")
    assert out.returncode == 0, out.stderr
    assert "distinct gaits from" in out.stdout
    assert sum(" s " in line and "found from" not in line for line in out.stdout.splitlines()) >= 1
    assert "3.88246 s" in out.stdout
