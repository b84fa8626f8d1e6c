"""Issue 44's kicks in MuJoCo, for the tests of the walkers designed against them
(tests/model/test_robust_toy_mujoco.py, tests/model/test_launch_toy.py): the fixed point with its
four rates kicked by +-0.02 rad/s, the signs drawn as docs/make_basin.py draws them (seeds 0-7)."""

import numpy as np

__all__ = ["KICK", "SEEDS", "STEPS", "kick_signs", "kicked_walks"]

STEPS = 60  # issue 44: a kicked walker walks at least 60 heel strikes
KICK = 0.02  # rad/s on each of the four rates (issue 44's kick)
SEEDS = range(8)  # the signs of docs/make_basin.py and docs/make_basin_mujoco.py


def kick_signs(seed: int) -> np.ndarray:
    """The four rates' signs of a kick, drawn as docs/make_basin.py draws them."""
    return np.random.default_rng(seed).choice([-1.0, 1.0], 4)


def kicked_walks(gait, contact_time: float, friction: float, steps: int = STEPS) -> tuple[dict, list]:
    """Each distinct kick walked once in MuJoCo (its walk is deterministic; seeds 2 and 3 draw the
    same signs, and so do 4 and 7): the outcomes ``(status, steps, message)`` by signs, and by seed
    of :data:`SEEDS`."""
    from toywalk.model.mujoco_check import walk_in_mujoco

    walked = {}
    for seed in SEEDS:
        signs = tuple(kick_signs(seed))
        if signs not in walked:
            z0 = gait.fixed_point.copy()
            z0[[1, 3, 5, 7]] += KICK * np.array(signs)
            walk = walk_in_mujoco(gait.params, z0, steps=steps, friction=friction, contact_time=contact_time,
                                  max_time=2.0 * steps * gait.step_time)
            walked[signs] = (walk.status, walk.steps, walk.message)
    return walked, [walked[tuple(kick_signs(seed))] for seed in SEEDS]
