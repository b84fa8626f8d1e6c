"""Measured heel strikes against the renderer's true ones, one to one, for the tests of tracked
rendered video (`test_track_rendered.py`, `tests/sysid/test_demo.py`).

A slow, obvious pairing written for the tests, independent of `toywalk.tracking.accuracy`
(which the demo and the benchmark report with): a true and a measured strike are a pair only if
they are by the same foot and within a stated time of each other, each strike is in at most one
pair, and everything left over is a miss or an invention.
"""

import dataclasses

import numpy as np

#: Time (frame intervals) within which a measured strike is the true one, timed. Twice the issue-4
#: timing target (0.25 frame RMS), and under a tenth of the fastest step rendered (6.4 frames,
#: stable-toy), so it cannot reach a neighbouring strike. Measured single-strike errors on the
#: rendered clips at level 1 are at most 0.2 frame; a strike further off fails the timing target
#: of a short clip on its own, and is then reported as a miss plus an invention.
MATCH_FRAMES = 0.5


def _get(event, key):
    """A field of a strike given as a dict (trajectory files) or as a HeelStrike."""
    return event[key] if isinstance(event, dict) else getattr(event, key)


@dataclasses.dataclass
class StrikeMatch:
    """The outcome of :func:`match_strikes`: pairs (true, measured), true strikes missed, measured
    strikes invented; ``errors`` are the pairs' timing errors (measured - true, s)."""

    pairs: list
    missed: list
    invented: list

    @property
    def errors(self) -> list:
        return [_get(m, "time") - _get(t, "time") for t, m in self.pairs]

    def describe(self, dt: float) -> str:
        """The misses and inventions with times in frames of ``dt`` s, for assertion messages."""
        def show(events):
            return [(round(_get(e, "time") / dt, 2), _get(e, "foot")) for e in events]
        return f"missed {show(self.missed)}, invented {show(self.invented)}"


def match_strikes(true, measured, dt: float, *, seek=(-float("inf"), float("inf")),
                  within: float = MATCH_FRAMES) -> StrikeMatch:
    """Pair true and measured heel strikes (dicts or HeelStrikes with ``time``, s, and ``foot``).

    A pair has the same foot and times within ``within`` frames of ``dt`` s; the closest
    candidate pairs are taken first. True strikes outside ``seek`` = (t0, t1) (s), where the
    tracker does not look for strikes (near the clip's ends), may be paired but are not counted
    as missed.
    """
    true, measured = list(true), list(measured)
    candidates = sorted((abs(_get(m, "time") - _get(t, "time")), i, j)
                        for i, t in enumerate(true) for j, m in enumerate(measured)
                        if _get(t, "foot") == _get(m, "foot")
                        and abs(_get(m, "time") - _get(t, "time")) <= within * dt)
    used_t, used_m, pairs = set(), set(), []
    for _, i, j in candidates:
        if i not in used_t and j not in used_m:
            used_t.add(i)
            used_m.add(j)
            pairs.append((true[i], measured[j]))
    pairs.sort(key=lambda p: _get(p[0], "time"))
    missed = [t for i, t in enumerate(true) if i not in used_t and seek[0] < _get(t, "time") < seek[1]]
    invented = [m for j, m in enumerate(measured) if j not in used_m]
    return StrikeMatch(pairs=pairs, missed=missed, invented=invented)


def two_strike_errors(truth, events) -> list:
    """The timing errors (frames) of a short rendered clip's measured heel strikes ``events``
    against its truth's: the clip holds two true strikes away from its ends (three frames, where
    the tracker does not look), and each is found once, by its foot, within :data:`MATCH_FRAMES`
    (asserted here: none missed or invented)."""
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] <= e["time"] <= truth.time[-1]]
    strikes = match_strikes(true, events, dt, seek=(truth.time[0] + 3 * dt, truth.time[-1] - 3 * dt))
    assert len(strikes.pairs) + len(strikes.missed) == 2  # the clip is chosen to hold two
    assert not strikes.missed and not strikes.invented, strikes.describe(dt)
    return [e / dt for e in strikes.errors]
