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


def test_gait_all_out_follows_each_gait_in_slope(tmp_path):
    """`--all --out GAITS.csv`: each gait followed in slope (table, families, plot); the long-period
    gait's family is stable over 0.008-0.010 (Garcia et al. 1998: up to 0.0151)."""
    import csv

    out = tmp_path / "gaits.csv"
    done = run("gait", "--params", SIMPLEST, "--all", "--out", out, "--slopes", "0.008", "0.010",
               "--points", "30")
    assert done.returncode == 0, done.stderr
    assert "gait 1 in slope: down: reached" in done.stdout and str(out) in done.stdout
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    slopes = [float(r["slope"]) for r in rows if r["gait"] == "1"]
    assert min(slopes) == 0.008 and max(slopes) == 0.010 and len(slopes) >= 3
    assert all(r["stable"] == "1.0" for r in rows if r["gait"] == "1")
    families = json.loads(out.with_suffix(".json").read_text())["families"]
    assert families[0]["gait"] == 1 and {s["status"] for s in families[0]["sides"]} == {"reached"}
    assert out.with_suffix(".png").stat().st_size > 10_000


def test_gait_all_out_refuses_a_range_without_the_walker(tmp_path):
    out = tmp_path / "gaits.csv"
    done = run("gait", "--params", SIMPLEST, "--all", "--out", out, "--slopes", "0.01", "0.02")
    assert done.returncode == 2 and "must hold the walker's slope 0.009" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not list(tmp_path.iterdir())
