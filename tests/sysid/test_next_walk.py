"""A tie between candidate causes, and the further walk that breaks it: the single walk's analysis
weighs further walks by first order (toywalk.sysid.design.next_walk), and the walk it suggests,
simulated and analysed with the first one, names the hidden cause by the margin first order gave
(the nonlinear joint fits of toywalk.sysid.walks)."""

import json
import math

import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.diagnosis_report import write_diagnosis, write_walks_diagnosis
from toywalk.sysid.discrepancy import diagnose
from toywalk.sysid.naming import SEPARATION, tied
from toywalk.sysid.walks import diagnose_walks

from ..conftest import DATA
from .builders import simulated_walk

FREE = ["foot_radius", "com_offset[1]"]
#: The tied pair: the hinge's viscous and dry friction, which a walk on its cycle moves along
#: nearly one direction (docs/diagnosis.md, "Which second walk breaks the ties").
EFFECTS = ["hip_damping", "hip_coulomb"]
#: Hip damping on compass-3d (N m s/rad): at 0.002 rad of noise, 10 steps, the base misses the
#: walk by hundreds in chi-square and the dry friction fits it within the rule's margin.
DAMPING = 0.002
NOISE = 0.002


def _measured(params, seed: int) -> TrajectoryTable:
    """A simulated walk with its noise SD stated, as `toywalk simulate --noise` writes it."""
    table, _ = simulated_walk(params.replace(**{"effects.hip_damping": DAMPING}), 10, NOISE, seed)
    sds = {f"{n}_sd": np.full(len(table.time), NOISE) for n in list(table.signals)}
    return TrajectoryTable(table.time, {**table.signals, **sds}, table.stance, table.events, {})


def test_tied_takes_the_significant_candidates_within_the_margin():
    """Only fitted, significant candidates within SEPARATION of the best are tied, and a best
    that stands alone leaves no tie."""
    rows = [{"effect": "a", "fitted": True, "lr": 100.0, "lr_p": 1e-20},
            {"effect": "b", "fitted": True, "lr": 100.0 - 0.9 * SEPARATION, "lr_p": 1e-19},
            {"effect": "c", "fitted": True, "lr": 100.0 - 1.1 * SEPARATION, "lr_p": 1e-18},
            {"effect": "d", "fitted": True, "lr": 99.0, "lr_p": 0.5},
            {"effect": "e", "score_z": 12.0}]
    assert [r["effect"] for r in tied(rows, 1e-3)] == ["a", "b"]
    assert tied([rows[0], rows[2], rows[3]], 1e-3) == []
    assert tied([rows[3], rows[4]], 1e-3) == []


@pytest.mark.slow
def test_a_tie_suggests_the_further_walk_that_names_the_cause(tmp_path):
    """compass-3d with hip damping hidden: one walk leaves the damper and the hinge's dry friction
    tied; first order says a ramp 0.8 or 1.2 times as steep separates them (a viscous torque
    scales with the legs' rates, a dry one does not), moving the masses or the same walk again
    does not. The suggested walk, simulated with the truth and analysed with the first, names
    the damper, ahead of the dry friction by a margin of first order's size."""
    walker = load_params(DATA / "params" / "compass-3d.toml")
    first = _measured(walker, 41)
    # the search for the missing force is not this test's (tests/sysid/test_missing_force.py)
    d = diagnose(first, walker, model="periodic", free=FREE, effects=EFFECTS, parameters=[], workers=2,
                 missing_force=False)
    assert d.cause == "unexplained", d.evidence
    further = d.next_walk
    assert further is not None and sorted(further["tied"]) == ["effects.hip_coulomb",
                                                               "effects.hip_damping"], further
    rows = {r["label"]: r for r in further["conditions"]}
    assert all("reason" not in r for r in rows.values()), rows
    by_parameter = {r["parameter"]: [] for r in rows.values()}
    for r in rows.values():
        by_parameter[r["parameter"]].append(r["gap"])
    # Measured (the least gap over the tied pair): a ramp at 0.8 and 1.2 times the slope 355 and
    # 260, the masses 10 % out or in 3.6 and 3.7, the same walk again 1.8; the rule's margin (9.2)
    # lies well between.
    assert min(by_parameter["slope"]) > 5 * SEPARATION, rows
    assert max(by_parameter["com_offset[1]"]) < SEPARATION, rows
    assert further["same_again"]["gap"] < SEPARATION, further["same_again"]
    assert rows[further["suggestion"]]["parameter"] == "slope", further["suggestion"]
    assert "would tell them apart" in d.evidence
    write_diagnosis(d, tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["next_walk"]["suggestion"] == further["suggestion"]
    assert f"Suggested: a further walk with {further['suggestion']}" in (tmp_path / "report.md").read_text()

    # The same walk given twice and analysed as two walks stays tied (measured 0.4 apart), and
    # the analysis of walks weighs a third the same way: a third like the first leaves 2.8, the
    # ramps 531 and 355, the masses 5.1 and 5.2 (what separates is the new condition, not more of
    # the old).
    twice = diagnose_walks([first, first], [walker, walker], model="periodic", free=FREE, effects=EFFECTS,
                           parameters=[], workers=2)
    assert twice.cause == "unexplained" and twice.next_walk is not None, twice.evidence
    rows_twice = {r["label"]: r for r in twice.next_walk["conditions"]}
    assert twice.next_walk["same_again"]["gap"] < SEPARATION, twice.next_walk["same_again"]
    assert min(r["gap"] for r in rows_twice.values() if r["parameter"] == "slope") > 5 * SEPARATION
    assert rows_twice[twice.next_walk["suggestion"]]["parameter"] == "slope"
    write_walks_diagnosis(twice, tmp_path / "twice")
    assert "Which further walk would tell them apart" in (tmp_path / "twice" / "report.md").read_text()

    row = rows[further["suggestion"]]
    second_walker = walker.replace(slope=row["to"])
    second = _measured(second_walker, 42)
    both = diagnose_walks([first, second], [walker, second_walker], model="periodic", free=FREE,
                          effects=EFFECTS, parameters=[], workers=2)
    assert both.cause == "effects.hip_damping", both.evidence
    lr = {r["effect"]: r["lr"] for r in both.ranking}
    gap = lr["effects.hip_damping"] - lr["effects.hip_coulomb"]
    expected = next(r for r in row["results"] if r["hidden"] == "effects.hip_damping")["gap"]
    # First order about the base fit: the stable toy's fitted gaps were 0.95-1.38 times first
    # order's (docs/diagnosis.md), here 325.8 against 354.7; a factor of 2 either way still
    # leaves the gap far beyond the margin.
    assert expected / 2 < gap < 2 * expected, (gap, expected)
    # A score statistic cannot exceed the whitened residuals' norm (it is their projection on a
    # unit vector): the joint base fit that once ended 400 times the walks' own chi-square, at
    # a lateral offset ten times the truth, gave scores of 1500.
    bound = math.sqrt(both.base.chi2)
    assert all(abs(r["score_z"]) <= bound for r in both.ranking if "score_z" in r), both.ranking
