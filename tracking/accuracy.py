"""A tracked trajectory against a known truth (a rendered video's ``V.truth.csv``): the error
statistics of ``benchmarks/TRACKING.md`` and ``toywalk demo``.

Both arguments are :class:`toywalk.model.trajectory.TrajectoryTable` (a tracker's result gives
one through ``TrackResult.table()``); heel strikes are their event dicts (``time``, ``foot``, and
``time_sd`` where measured).
"""

from __future__ import annotations

import numpy as np

from ..model.trajectory import SIGNALS, TrajectoryTable

__all__ = ["match_strikes", "signal_errors"]


def signal_errors(measured: TrajectoryTable, truth: TrajectoryTable, *, atol: float = 1e-4) -> dict:
    """Per signal (lean, steer, pitch_left, pitch_right): ``rms_deg`` and ``max_deg`` of the error
    over the samples measured (None if none), ``gaps`` (samples missing) and ``z_rms``, the RMS of
    error over the measured ``*_sd`` column (None without one).

    Raises ValueError unless both have the same sample times (to ``atol`` s).
    """
    if len(measured.time) != len(truth.time) or not np.allclose(measured.time, truth.time, atol=atol):
        raise ValueError(f"sample times differ: {len(measured.time)} measured, {len(truth.time)} true")
    out = {}
    for k in SIGNALS:
        err = np.degrees(measured.signals[k] - truth.signals[k])
        ok = np.isfinite(err)
        sd = measured.signals.get(f"{k}_sd")
        z = err[ok] / np.degrees(sd[ok]) if sd is not None else None
        out[k] = {"rms_deg": float(np.sqrt(np.mean(err[ok] ** 2))) if ok.any() else None,
                  "max_deg": float(np.max(np.abs(err[ok]))) if ok.any() else None,
                  "gaps": int((~ok).sum()),
                  "z_rms": float(np.sqrt(np.mean(z**2))) if z is not None and ok.any() else None}
    return out


def match_strikes(true_events, measured_events, step: float, dt: float) -> dict:
    """Pair each true heel strike with the nearest measured one within half a ``step`` (s).

    Returns counts (``true``, ``found``, ``missed``, ``invented``, ``wrong_foot``) and the timing
    errors of the pairs in frames of ``dt`` s (``timing_rms_frames``, ``timing_max_frames``) and
    over the measured ``time_sd`` (``timing_z_rms``, and by the measured strike's foot
    ``timing_z_by_foot``: ``{foot: [z, ...]}``); None where there is no pair (or no SD).
    """
    measured = list(measured_events)
    errors, z, wrong_foot, missed, by_foot = [], [], 0, 0, {}
    for ev in true_events:
        if not measured:
            missed += 1
            continue
        j = int(np.argmin([abs(m["time"] - ev["time"]) for m in measured]))
        if abs(measured[j]["time"] - ev["time"]) > 0.5 * step:
            missed += 1
            continue
        m = measured.pop(j)
        errors.append((m["time"] - ev["time"]) / dt)
        if "time_sd" in m:
            z.append((m["time"] - ev["time"]) / m["time_sd"])
            by_foot.setdefault(m["foot"], []).append(float(z[-1]))
        wrong_foot += m["foot"] != ev["foot"]
    return {"true": len(true_events), "found": len(measured_events), "missed": missed,
            "invented": len(measured), "wrong_foot": wrong_foot,
            "timing_rms_frames": float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
            "timing_max_frames": float(np.max(np.abs(errors))) if errors else None,
            "timing_z_rms": float(np.sqrt(np.mean(np.square(z)))) if z else None,
            "timing_z_by_foot": by_foot}
