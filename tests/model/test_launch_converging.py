"""Hand launches that walk into the gait (docs/gaits.md section 7): docs/launch_converging.toml
(docs/make_launch_margin.py, "Toward a smaller fore-aft margin"), the first walker of the project
whose hand launch converges into its stable gait, in the model and in MuJoCo, from tips near its
lean amplitude and not from 1.5 x; and docs/launch_search_best.toml (docs/make_launch_search.py,
"From 1.5 and 2.5 x lean"), whose launch from 1.5 x lean converges, and from 2.5 x does not."""

import numpy as np
import pytest
from toywalk.model import can_stand, find_gait, load_params
from toywalk.model.basin import hand_launch, launch_state

from ..conftest import ROOT

PARAMS = ROOT / "docs" / "launch_converging.toml"


@pytest.fixture(scope="module")
def gait():
    return find_gait(load_params(PARAMS))


def test_stable_and_cannot_stand(gait):
    assert gait.stable and gait.max_abs_eigenvalue == pytest.approx(0.979, abs=5e-4)
    assert not can_stand(gait.params).can_stand


def test_hand_launch_converges_at_its_lean_and_not_at_one_and_a_half(gait):
    """Released at rest tipped by 1.0 x its lean amplitude (0.45 degree) it walks into its gait:
    measured, within 1e-4 state units (``recovers``' rule) after 97 steps; at 1.5 x it falls after
    12, as documented. The 400-step budget is the one docs/make_launch_margin.py confirmed it with.
    About 0.1 s."""
    launch = hand_launch(gait.params, [1.0 * gait.lean_amplitude, 1.5 * gait.lean_amplitude], gait=gait,
                         steps=400)
    converged, failed = launch.results[0]
    assert converged.recovered and converged.reason == "recovered" and 90 <= converged.steps <= 110
    assert not failed.recovered and failed.reason == "fell" and failed.steps == 12


@pytest.mark.slow
def test_hand_launch_walks_on_in_mujoco(gait):
    """The same launch at 1.0 x lean in MuJoCo at 2 ms contacts and friction 1, a setting the design
    never met, walks 100 alternating heel strikes; its last ten steps settle within 2 ms of the
    model's 118.4 ms step (measured: 119.8 ms; docs/gaits.md section 7 walks it to 200 heel strikes).
    About 4 s."""
    mujoco_check = pytest.importorskip("toywalk.model.mujoco_check")
    walk = mujoco_check.walk_in_mujoco(gait.params, launch_state(gait.lean_amplitude), steps=100,
                                       friction=1.0, contact_time=2e-3)
    assert walk.status == "completed" and walk.steps == 100, walk.message
    assert abs(np.mean(walk.step_times[-10:]) - gait.step_time) < 2e-3


@pytest.fixture(scope="module")
def searched():
    """docs/launch_search_best.toml (docs/make_launch_search.py): the best walker of the local search
    around docs/launch_converging.toml that cannot stand."""
    return find_gait(load_params(ROOT / "docs" / "launch_search_best.toml"))


def test_searched_walker_launches_from_one_and_a_half_not_two_and_a_half(searched):
    """docs/gaits.md section 7, "From 1.5 and 2.5 x lean": it cannot stand, its gait is stable, its
    hand launch at 1.5 x lean converges (measured: 168 steps) and at 2.5 x falls (10 steps): the
    issue's 2.5 x is what the search did not reach. About 1 s."""
    assert searched.stable and not can_stand(searched.params).can_stand
    launch = hand_launch(searched.params, [1.5 * searched.lean_amplitude, 2.5 * searched.lean_amplitude],
                         gait=searched, steps=400)
    converged, failed = launch.results[0]
    assert converged.recovered and 150 <= converged.steps <= 190
    assert not failed.recovered and failed.reason == "fell" and failed.steps <= 12


@pytest.mark.slow
def test_searched_walker_launch_walks_on_in_mujoco(searched):
    """Its launch at 1.5 x lean walks 100 alternating heel strikes in MuJoCo at 2 ms contacts and
    friction 1 (measured: 100, at (1 ms, 2) too; at 4 ms, 0.6 it falls after 24). About 3 s."""
    mujoco_check = pytest.importorskip("toywalk.model.mujoco_check")
    walk = mujoco_check.walk_in_mujoco(searched.params, launch_state(1.5 * searched.lean_amplitude),
                                       steps=100, friction=1.0, contact_time=2e-3)
    assert walk.status == "completed" and walk.steps == 100, walk.message
