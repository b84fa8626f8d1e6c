"""The model's compliant heel strike against MuJoCo's (docs/soft_feet.md, "Against MuJoCo's heel
strike").

    OPENBLAS_NUM_THREADS=1 MUJOCO_GL=egl .venv/bin/python docs/make_soft_heel_mujoco.py   # about 4 s

The clearing toy (data/params/clearing-toy.toml) at its gait's heel strike (``find_gait``, then
``Walker.step(...).z_minus``): the model's compliant strike (model/compliant.py, critically
damped, the ``soft_heel`` effect's friction 10) and MuJoCo's (model/mujoco_check.py,
``strike_in_mujoco``: the same state, ``solref = (tau, 1)``, flat impedance d = 0.9999, friction
10), sampled at the same times, at tau = 1, 2 and 4 ms; then MuJoCo at tau = 2 ms with other
flat impedances. Prints Markdown tables and writes docs/soft_heel_mujoco.png (tau = 2 ms).
"""

from __future__ import annotations

from pathlib import Path

from toywalk.model import Walker, find_gait, load_params
from toywalk.model.compliant import SoftContact, compliant_strike
from toywalk.model.effects.soft import FRICTION, ZETA
from toywalk.model.mujoco_check import STRIKE_SOLIMP, strike_differences, strike_in_mujoco

HERE = Path(__file__).resolve().parent
PARAMS = HERE.parent / "data" / "params" / "clearing-toy.toml"
TAUS = (1e-3, 2e-3, 4e-3)
FIGURE_TAU = 2e-3
IMPEDANCES = (0.9999, 0.9, 0.5, 0.1, 0.0001)
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")


def strikes(params, z_minus, tau, solimp=STRIKE_SOLIMP):
    """The model's strike and MuJoCo's at ``tau`` and their differences."""
    x_minus = Walker(params).full_state(z_minus)
    model = compliant_strike(params, x_minus, SoftContact(tau, ZETA, FRICTION))
    mujoco = strike_in_mujoco(params, z_minus, tau, solimp=solimp)
    return model, mujoco, strike_differences(model, mujoco)


def _row(tau, d):
    m, j = d["model"], d["mujoco"]
    return (f"| {tau * 1e3:g} | {_vec(d['angles_end'], 1e3)} | {_vec(d['rates_end'], 1)} "
            f"| {_vec(d['rates_max'], 1)} | {m['peak_force']:.2f} / {j['peak_force']:.2f} "
            f"| {m['pulse'] * 1e3:.2f} / {j['pulse'] * 1e3:.2f} "
            f"| {m['max_penetration'] * 1e6:.0f} / {j['max_penetration'] * 1e6:.0f} "
            f"| {m['end_penetration'] * 1e6:.1f} / {j['end_penetration'] * 1e6:.2f} "
            f"| {m['unloaded']} / {j['unloaded']} | {m['lift_off'] * 1e3:.2f} / {j['lift_off'] * 1e3:.2f} "
            f"| {d['force_rms']:.2f} |")


def _vec(values, scale):
    return ", ".join(f"{v * scale:+.3f}" for v in values)


def main() -> None:
    params = load_params(PARAMS)
    z_minus = Walker(params).step(find_gait(params).fixed_point).z_minus
    print("| tau (ms) | angles at 10 tau, MuJoCo - model (mrad) | rates at 10 tau (rad/s) "
          "| largest rate difference in the phase (rad/s) | peak landing N (N) | impact pulse (ms) "
          "| largest landing penetration (um) | landing penetration at 10 tau (um) "
          "| landing unloaded (samples) | trailing lift-off (ms) | landing N, RMS difference (N) |")
    print("| --- " * 11 + "|")
    figure = None
    for tau in TAUS:
        model, mujoco, d = strikes(params, z_minus, tau)
        print(_row(tau, d))
        if tau == FIGURE_TAU:
            figure = (model, mujoco)
    print(f"\nMuJoCo at tau = {FIGURE_TAU * 1e3:g} ms with flat impedance d (solimp = (d, d, 1 mm)):\n")
    print("| d | angles at 10 tau (mrad) | rates at 10 tau (rad/s) | peak landing N (N) "
          "| landing N after the first step, peak (N) | impact pulse (ms) | largest landing penetration (um) "
          "| landing penetration at 10 tau (um) | landing N, RMS difference (N) |")
    print("| --- " * 9 + "|")
    for dimp in IMPEDANCES:
        _, mujoco, d = strikes(params, z_minus, FIGURE_TAU, (dimp, dimp, 0.001))
        j = d["mujoco"]
        print(f"| {dimp:g} | {_vec(d['angles_end'], 1e3)} | {_vec(d['rates_end'], 1)} "
              f"| {j['peak_force']:.2f} | {mujoco.normal_forces[1:, 1].max():.2f} | {j['pulse'] * 1e3:.2f} "
              f"| {j['max_penetration'] * 1e6:.0f} | {j['end_penetration'] * 1e6:.2f} "
              f"| {d['force_rms']:.2f} |")
    _plot(*figure)


def _plot(model, mujoco) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for strike, name, style in ((model, "model", "-"), (mujoco, "MuJoCo", "--")):
        t = strike.times * 1e3
        for foot, colour in ((1, "C0"), (0, "C1")):
            label = f"{name}, {'landing' if foot else 'trailing'} foot"
            top.plot(t, strike.normal_forces[:, foot], style, color=colour, label=label)
            bottom.plot(t, strike.penetrations[:, foot] * 1e6, style, color=colour, label=label)
    top.set_ylabel("normal force (N)")
    top.set_yscale("symlog", linthresh=1.0)
    top.legend(fontsize=8)
    bottom.set_ylabel("penetration (um)")
    bottom.set_ylim(-100, 250)
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_xlabel(f"time from touchdown (ms), tau = {FIGURE_TAU * 1e3:g} ms")
    top.set_title("clearing toy's heel strike: the model's compliant strike and MuJoCo's")
    fig.tight_layout()
    fig.savefig(HERE / "soft_heel_mujoco.png", dpi=110)


if __name__ == "__main__":
    main()
