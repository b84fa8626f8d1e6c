"""Long walks on soft feet: the model with the compliant heel strike against MuJoCo with the
same contact (docs/soft_feet.md section 7).

    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_soft_heel_walks.py   # about 6 min

For the clearing toy (data/params/clearing-toy.toml) and stable-toy (data/params/stable-toy.toml),
at contact time constants tau = 1, 2 and 4 ms, from the rigid model's gait (``find_gait``) and
from perturbed starts (its four rates plus normal draws of SD 1e-3 and 0.02 rad/s, seeds 0-7):

- the model: ``simulate`` with ``effects.soft_heel = tau`` (and the rigid model, tau = 0, once);
- MuJoCo: ``walk_in_mujoco`` with the same contact as the model's phase: ``solref = (tau, 1)``,
  the flat impedance ``STRIKE_SOLIMP`` (d = 0.9999: the contact follows ``solref``, section 6),
  friction 10 (the ``soft_heel`` effect's), its RK4 at ``tau / 40``.

Per walk: steps walked, fell or not, the step times' mean and RMS fluctuation (SD over the
steps, relative to the mean), the heading (the direction from the start to the last left heel
strike) and the lateral drift per step. For MuJoCo's walks from the gait, also what its contact
does between strikes (the stance foot's slip per step, its penetration, the share of samples it
carries no load, the mechanical energy it loses per flow) and the model run from MuJoCo's states
(``touchdown_predictions``): one step (the model's flow against MuJoCo's), two steps (the model's
strike in place of MuJoCo's once), and a whole walk from MuJoCo's state after its first strike.
Then, on the clearing toy: section 6's isolated heel strike carried one step by the model's
flow, and the model walked with MuJoCo's strike as a constant offset to its own (the difference of
the two strikes' states 10 tau after touchdown, added after every step), at the flat impedances
d = 0.9999, 0.5 and 1e-4; and at 1 ms MuJoCo's walk with one setting changed at a time (time
step, friction, impedance). Prints Markdown tables; writes docs/soft_heel_walks.csv (one row per walk)
and docs/soft_heel_walks.png (step time against step number, clearing toy).
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np
from toywalk.model import Walker, find_gait, load_params
from toywalk.model.effects.soft import FRICTION, ZETA
from toywalk.model.mujoco_check import STRIKE_SOLIMP, strike_in_mujoco, touchdown_predictions, walk_in_mujoco
from toywalk.model.simulate import simulate
from toywalk.model.walker import StepFailure

HERE = Path(__file__).resolve().parent
PARAMS = HERE.parent / "data" / "params"
WALKERS = ("clearing-toy", "stable-toy")
TAUS = (1e-3, 2e-3, 4e-3)
SOFT = "effects.soft_heel"
SPAN = 10  # the model's phase, in time constants (toywalk.model.compliant.SPAN)
GAIT_STEPS = 100  # steps from the gait
KICK_STEPS = 40  # steps from a perturbed start
KICKS = (1e-3, 0.02)  # SD of the rates' kicks (rad/s)
SEEDS = range(8)
# MuJoCo's RK4 step in contact time constants: 40 a tau (25 us at 1 ms). At 10 (0.1 ms, the
# walking build's step) the trailing foot is held at its friction limit for a whole step as the
# other lands, which the variants below measure.
MJ_STEPS_PER_TAU = 40
SAMPLE_RATE = 1000.0  # MuJoCo's samples (Hz)
# Variants of MuJoCo's walk on the clearing toy at VARIANT_TAU, one setting changed each.
VARIANT_TAU = 1e-3
VARIANTS = {"time step tau / 10": {"timestep": VARIANT_TAU / 10},
            "time step tau / 100": {"timestep": VARIANT_TAU / 100},
            "friction 2": {"friction": 2.0},
            "walking impedance": {"solimp": None},
            "impedance d = 0.5": {"solimp": (0.5, 0.5, 0.001)},
            "impedance d = 0.0001": {"solimp": (1e-4, 1e-4, 0.001)}}
# Flat impedances d (solimp = (d, d, 1 mm)) for the isolated strike besides STRIKE_SOLIMP's 0.9999.
IMPEDANCES = (0.5, 1e-4)
FIELDS = ("walker", "engine", "tau_ms", "setting", "start", "kick", "seed", "steps", "fell", "scuffs",
          "step_time_ms", "step_time_rms", "heading_deg", "lateral_mm_per_step", "flow_error_ms",
          "flow_error_rms_ms", "strike_error_ms", "strike_error_rms_ms", "rigid_strike_error_ms",
          "slip_um_per_step", "penetration_um", "unloaded_share", "flow_energy_mJ")


def starts(z_gait):
    """(kick, seed, start): the gait, then its rates kicked by normal draws."""
    out = [(0.0, -1, z_gait)]
    for kick in KICKS:
        for seed in SEEDS:
            z = z_gait.copy()
            z[1::2] += np.random.default_rng(seed).normal(0.0, kick, 4)
            out.append((kick, seed, z))
    return out


def summary(step_times, points, fell, scuffs):
    """The walk's numbers from its step times (s), heel-strike points (m, shape (n, 2), the
    start's first, left foot), whether it fell and its scuffs."""
    left = points[::2]  # the start and every left heel strike
    n = len(step_times)
    return {"steps": n, "fell": fell, "scuffs": scuffs,
            "step_time_ms": 1e3 * np.mean(step_times) if n else math.nan,
            "step_time_rms": np.std(step_times) / np.mean(step_times) if n > 1 else math.nan,
            "heading_deg": math.degrees(math.atan2(left[-1, 1], left[-1, 0])) if len(left) > 1 else math.nan,
            "lateral_mm_per_step": 1e3 * left[-1, 1] / (2 * (len(left) - 1)) if len(left) > 1 else math.nan}


def model_walk(params, z0, steps):
    """The model's walk (``simulate``) and its summary; the step times are between touchdowns."""
    traj = simulate(params, z0, steps)
    times = np.r_[0.0, [e.time for e in traj.events]]
    points = np.vstack([np.zeros((1, 2))] + [[[e.x, e.y]] for e in traj.events])
    return np.diff(times), summary(np.diff(times), points, traj.status != "completed", traj.scuffs)


def mujoco_walk(params, z0, steps, tau, timestep=None, friction=FRICTION, solimp=STRIKE_SOLIMP):
    """MuJoCo's walk with the model's contact and its summary."""
    timestep = tau / MJ_STEPS_PER_TAU if timestep is None else timestep
    walk = walk_in_mujoco(params, z0, steps=steps, timestep=timestep, friction=friction,
                          contact_time=tau, damping_ratio=ZETA, solimp=solimp, sample_rate=SAMPLE_RATE)
    points = np.vstack([np.zeros((1, 2)), walk.strikes[:walk.steps, 1:]])
    return walk, summary(walk.step_times, points, walk.status != "completed", walk.scuffs)


def contact_numbers(walk, params, tau):
    """What MuJoCo's contact does between strikes (from ``SPAN`` tau after each strike to the
    next) and the model run from MuJoCo's states."""
    strikes = np.r_[0.0, walk.strikes[:walk.steps, 0]]
    flows = np.zeros(len(walk.times), dtype=bool)
    energy = []
    for a, b in zip(strikes[:-1], strikes[1:], strict=True):
        inside = np.flatnonzero((walk.times >= a + SPAN * tau) & (walk.times < b))
        flows[inside] = True
        if len(inside) > 1:
            energy.append(walk.energy[inside[-1]] - walk.energy[inside[0]])
    dt = 1.0 / SAMPLE_RATE
    def mean(x):
        return float(np.mean(x[np.isfinite(x)])) if np.any(np.isfinite(x)) else math.nan

    flow = touchdown_predictions(walk, params.replace(**{SOFT: 0.0}), SPAN * tau)
    strike = touchdown_predictions(walk, params.replace(**{SOFT: tau}), SPAN * tau, steps=2)
    rigid = touchdown_predictions(walk, params.replace(**{SOFT: 0.0}), SPAN * tau, steps=2)
    return {"flow_error_ms": 1e3 * mean(flow), "flow_error_rms_ms": 1e3 * math.sqrt(mean(flow ** 2)),
            "strike_error_ms": 1e3 * mean(strike), "strike_error_rms_ms": 1e3 * math.sqrt(mean(strike ** 2)),
            "rigid_strike_error_ms": 1e3 * mean(rigid),
            "slip_um_per_step": 1e6 * dt * walk.slip_speed[flows].sum() / max(walk.steps, 1),
            "penetration_um": 1e6 * np.median(walk.penetration[flows]),
            "unloaded_share": float(np.mean(walk.stance_force[flows] == 0.0)),
            "flow_energy_mJ": 1e3 * np.mean(energy) if energy else math.nan}


def isolated_strike(params, z_gait, tau, substeps, solimp=STRIKE_SOLIMP):
    """Section 6's single heel strike, both engines from the gait's heel strike: MuJoCo's state 10
    tau after touchdown less the model's (the public state, mirrored: the right leg in stance;
    shape (8,)), with MuJoCo's RK4 at ``tau / (20 substeps)`` and impedance ``solimp``, and the
    next step's time from the
    two states by the model's flow, MuJoCo's less the model's (ms)."""
    rigid = Walker(params)
    z_minus = rigid.step(z_gait).z_minus
    model = Walker(params.replace(**{SOFT: tau})).step(z_gait).z_plus  # 10 tau after touchdown
    strike = strike_in_mujoco(params, z_minus, tau, substeps=substeps, solimp=solimp)
    (lean, steer, left, right), rates = strike.angles[-1], strike.rates[-1]
    mujoco = np.array([-steer, -rates[1], -lean, -rates[0], right, rates[3], left, rates[2]])
    later = rigid.step(mujoco, side=-1).step_time - rigid.step(model, side=-1).step_time
    return mujoco - model, 1e3 * later


def offset_walk(params, z0, tau, offset, steps):
    """The model on soft feet with MuJoCo's strike in place of its own, as a constant: after each
    step the state gets ``offset`` (the isolated strike's difference, :func:`isolated_strike`).
    Returns the step times (s, touchdown to touchdown) and whether it fell."""
    walker = Walker(params.replace(**{SOFT: tau}))
    z, side, times, phase = np.asarray(z0, dtype=float), 1, [], 0.0
    for _ in range(steps):
        try:
            step = walker.step(z, side=side)
        except StepFailure:
            return np.array(times), True
        times.append(step.step_time - step.strike_phase + phase)  # touchdown to touchdown
        z, side, phase = step.z_plus + offset, -side, step.strike_phase
    return np.array(times), False


def model_from_mujoco(walk, params, tau, steps):
    """The model's walk from MuJoCo's state ``SPAN`` tau after its first heel strike."""
    i = int(np.searchsorted(walk.times, walk.strikes[0, 0] + SPAN * tau))
    z = walk.public_state(i)  # mirrored: stance right, so the physical state flips steer and lean
    z[:4] *= -1.0
    traj = simulate(params.replace(**{SOFT: tau}), z, steps, first_stance="R")
    first = walk.strikes[0, 0]
    times = np.r_[first, [walk.times[i] + e.time for e in traj.events]]
    return np.diff(times), traj.status != "completed", traj.scuffs


def main() -> None:
    clock = time.perf_counter()
    rows, series = [], {}

    def log(row):
        rows.append(row)
        print(f"[{time.perf_counter() - clock:6.0f} s] {row['walker']} {row['engine']:<22} "
              f"tau {row['tau_ms']:g} ms {row['setting']:<20} {row['start']:<6} kick {row['kick']:g} "
              f"seed {row['seed']}: {row['steps']} steps{' FELL' if row['fell'] else ''}, "
              f"rms {row['step_time_rms']:.4f}", flush=True)

    for name in WALKERS:
        params = load_params(PARAMS / f"{name}.toml")
        gait = find_gait(params)
        print(f"{name}: gait step time {gait.step_time * 1e3:.2f} ms, max |eigenvalue| "
              f"{gait.max_abs_eigenvalue:.4f}", flush=True)
        base = {"walker": name, "setting": "matched"}
        for kick, seed, z0 in starts(gait.fixed_point):
            n = GAIT_STEPS if kick == 0.0 else KICK_STEPS
            start = "gait" if kick == 0.0 else "kicked"
            times, s = model_walk(params, z0, n)
            log({**base, "engine": "rigid model", "tau_ms": 0.0, "start": start, "kick": kick, "seed": seed,
                 **s})
            if kick == 0.0:
                series[name, "rigid model", 0.0] = times
        for tau in TAUS:
            soft = params.replace(**{SOFT: tau})
            for kick, seed, z0 in starts(gait.fixed_point):
                n = GAIT_STEPS if kick == 0.0 else KICK_STEPS
                start = "gait" if kick == 0.0 else "kicked"
                common = {**base, "tau_ms": 1e3 * tau, "start": start, "kick": kick, "seed": seed}
                times, s = model_walk(soft, z0, n)
                log({**common, "engine": "model", **s})
                walk, s = mujoco_walk(params, z0, n, tau)
                extra = contact_numbers(walk, params, tau) if kick == 0.0 and walk.steps else {}
                log({**common, "engine": "MuJoCo", **s, **extra})
                if kick == 0.0:
                    series[name, "model", tau] = times
                    series[name, "MuJoCo", tau] = walk.step_times
                    if walk.steps > 1:
                        times, fell, scuffs = model_from_mujoco(walk, params, tau, n)
                        series[name, "model from MuJoCo", tau] = times
                        points = np.full((1, 2), math.nan)
                        log({**common, "engine": "model from MuJoCo", **summary(times, points, fell, scuffs)})
    params = load_params(PARAMS / "clearing-toy.toml")
    gait = find_gait(params)
    for setting, change in VARIANTS.items():
        options = {"timestep": None, "friction": FRICTION, "solimp": STRIKE_SOLIMP, **change}
        for kick, seed, z0 in starts(gait.fixed_point)[:1 + len(SEEDS)]:  # the gait, the small kicks
            n = GAIT_STEPS if kick == 0.0 else KICK_STEPS
            if setting == "time step tau / 100" and kick:
                continue  # ten minutes; the gait's walk says enough
            walk, s = mujoco_walk(params, z0, n, VARIANT_TAU, **options)
            extra = contact_numbers(walk, params, VARIANT_TAU) if kick == 0.0 and walk.steps else {}
            log({"walker": "clearing-toy", "engine": "MuJoCo", "tau_ms": 1e3 * VARIANT_TAU,
                 "setting": setting, "start": "gait" if kick == 0.0 else "kicked", "kick": kick,
                 "seed": seed, **s, **extra})
    print("\nThe isolated strike (section 6) carried one step: the next step's time, MuJoCo's strike "
          "less the model's (ms), MuJoCo at tau / 400 and at tau / 40; MuJoCo's state less the model's "
          "10 tau after touchdown (tau / 400; public state, rad and rad/s); the model walked with it "
          "added after every step:\n")
    print("| tau (ms) | next step, tau / 400 (ms) | tau / 40 (ms) | state difference "
          "| offset walk: steps | step time (ms) | step-time rms |")
    print("| --- " * 7 + "|")
    for tau in TAUS:
        offset, later = isolated_strike(params, gait.fixed_point, tau, 20)
        times, fell = offset_walk(params, gait.fixed_point, tau, offset, GAIT_STEPS)
        series["clearing-toy", "model with MuJoCo's strike", tau] = times
        print(f"| {tau * 1e3:g} | {later:+.3f} | {isolated_strike(params, gait.fixed_point, tau, 2)[1]:+.3f} "
              f"| {', '.join(f'{v:+.4f}' for v in offset)} | {len(times)}{' (fell)' if fell else ''} "
              f"| {1e3 * times.mean():.2f} | {times.std() / times.mean():.4f} |", flush=True)
        rows.append({"walker": "clearing-toy", "engine": "model with MuJoCo's strike", "tau_ms": 1e3 * tau,
                     "setting": "isolated strike, tau / 400", "start": "gait", "kick": 0.0, "seed": -1,
                     **summary(times, np.full((1, 2), math.nan), fell, 0)})
        for part, keep in (("angles only", slice(0, None, 2)), ("rates only", slice(1, None, 2))):
            masked = np.zeros(8)
            masked[keep] = offset[keep]
            times, fell = offset_walk(params, gait.fixed_point, tau, masked, GAIT_STEPS)
            print(f"|   {part} | | | | {len(times)}{' (fell)' if fell else ''} | {1e3 * times.mean():.2f} "
                  f"| {times.std() / times.mean():.4f} |", flush=True)
    print("\nThe isolated strike at other flat impedances d: the next step (ms) and the model walked "
          "with the offset:\n")
    print("| d | tau (ms) | next step (ms) | offset walk: steps | step-time rms |")
    print("| --- " * 5 + "|")
    for d in IMPEDANCES:
        for tau in TAUS:
            offset, later = isolated_strike(params, gait.fixed_point, tau, 20, (d, d, 0.001))
            times, fell = offset_walk(params, gait.fixed_point, tau, offset, GAIT_STEPS)
            print(f"| {d:g} | {tau * 1e3:g} | {later:+.3f} | {len(times)}{' (fell)' if fell else ''} "
                  f"| {times.std() / times.mean():.4f} |", flush=True)
    _write(rows)
    _tables(rows)
    _plot(series)
    print(f"done in {time.perf_counter() - clock:.0f} s")


def _write(rows) -> None:
    with open(HERE / "soft_heel_walks.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS, restval="")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def _tables(rows) -> None:
    """The walks from the gait, and the falls from the kicked starts."""
    print("\nFrom the gait:\n")
    print("| walker | engine | tau (ms) | setting | steps | scuffs | step time (ms) | step-time rms "
          "| heading (deg) | lateral drift (mm/step) | flow error, mean / rms (ms) "
          "| with the model's strike, soft: mean / rms, rigid: mean (ms) "
          "| slip (um/step) | penetration (um) | unloaded | flow energy (mJ) |")
    print("| --- " * 16 + "|")
    for r in rows:
        if r["start"] != "gait":
            continue
        fell = " (fell)" if r["fell"] else ""
        contact = (f"| {r['flow_error_ms']:+.3f} / {r['flow_error_rms_ms']:.3f} "
                   f"| {r['strike_error_ms']:+.2f} / {r['strike_error_rms_ms']:.2f}, "
                   f"{r['rigid_strike_error_ms']:+.2f} "
                   f"| {r['slip_um_per_step']:.2f} | {r['penetration_um']:.3f} | {r['unloaded_share']:.3f} "
                   f"| {r['flow_energy_mJ']:+.4f} " if "flow_error_ms" in r else "| | | | | | ")
        print(f"| {r['walker']} | {r['engine']} | {r['tau_ms']:g} | {r['setting']} | {r['steps']}{fell} "
              f"| {r['scuffs']} | {r['step_time_ms']:.2f} | {r['step_time_rms']:.4f} "
              f"| {r['heading_deg']:+.2f} "
              f"| {r['lateral_mm_per_step']:+.3f} {contact}|")
    print("\nFrom kicked starts: falls of 8, steps walked by those that fell, rms of those that did not:\n")
    print("| walker | engine | tau (ms) | setting | kick (rad/s) | fell | steps of the falls "
          "| step-time rms (walked) |")
    print("| --- " * 8 + "|")
    keys = []
    for r in rows:
        key = (r["walker"], r["engine"], r["tau_ms"], r["setting"], r["kick"])
        if r["start"] == "kicked" and key not in keys:
            keys.append(key)
    for key in keys:
        group = [r for r in rows if r["start"] == "kicked"
                 and (r["walker"], r["engine"], r["tau_ms"], r["setting"], r["kick"]) == key]
        falls = sorted(r["steps"] for r in group if r["fell"])
        walked = [r["step_time_rms"] for r in group if not r["fell"]]
        rms = f"{np.median(walked):.4f}" if walked else ""
        print(f"| {key[0]} | {key[1]} | {key[2]:g} | {key[3]} | {key[4]:g} | {len(falls)} of {len(group)} "
              f"| {', '.join(map(str, falls))} | {rms} |")


def _plot(series) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(TAUS), 1, figsize=(8, 8), sharex=True, sharey=True, squeeze=False)
    axes = axes[:, 0]
    rigid = series["clearing-toy", "rigid model", 0.0]
    for ax, tau in zip(axes, TAUS, strict=True):
        ax.plot(np.arange(1, len(rigid) + 1), 1e3 * rigid, color="0.6", lw=1, label="rigid model")
        for engine, style in (("model", "C0-"), ("MuJoCo", "C3.-"), ("model from MuJoCo", "C2--"),
                              ("model with MuJoCo's strike", "C1:")):
            times = series.get(("clearing-toy", engine, tau))
            if times is not None and len(times):
                label = {"model from MuJoCo": "model from MuJoCo's state after its first strike",
                         "model with MuJoCo's strike": "model, MuJoCo's strike as a constant offset"}.get(
                    engine, f"{engine}, soft heel")
                ax.plot(np.arange(1, len(times) + 1), 1e3 * times, style, ms=3, lw=1, label=label)
        ax.set_ylabel("step time (ms)")
        ax.set_title(f"tau = {tau * 1e3:g} ms", fontsize=9)
    axes[0].legend(fontsize=7, loc="lower left")
    axes[-1].set_xlabel("step")
    fig.suptitle("clearing toy from the rigid gait: step times, model with soft heel and MuJoCo")
    fig.tight_layout()
    fig.savefig(HERE / "soft_heel_walks.png", dpi=110)


if __name__ == "__main__":
    main()
