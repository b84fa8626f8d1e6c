"""The `toywalk` command line: outputs, and bad input giving one clear line and no output file."""

import json

import pytest

from ..conftest import DATA
from .command import run

SIMPLEST = DATA / "params" / "simplest-walker.toml"
COMPASS = DATA / "params" / "compass-3d.toml"


def test_gait_json_has_the_documented_keys():
    out = run("gait", "--params", SIMPLEST, "--json")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    for key in ("step_time", "stride_length", "fixed_point", "eigenvalues", "max_abs_eigenvalue",
                "can_stand", "status"):
        assert key in report
    assert set(report["fixed_point"]) == {"phi", "phi_dot", "psi", "psi_dot", "theta_st",
                                          "theta_st_dot", "theta_sw", "theta_sw_dot"}
    assert abs(report["step_time"] - 3.8824637528506) < 1e-6  # docs/model.md section 7, g = l = 1
    assert {"re", "im"} <= set(report["eigenvalues"][0])


def test_gait_text_output():
    out = run("gait", "--params", COMPASS)
    assert out.returncode == 0, out.stderr
    assert "max |eigenvalue|" in out.stdout


@pytest.mark.parametrize("content, message", [
    ("leg_length = 1.0\nbogus = 2\n", "unknown parameter 'bogus'"),
    ("leg_length = [\n", "not valid TOML"),
])
def test_bad_parameter_files(tmp_path, content, message):
    bad = tmp_path / "bad.toml"
    bad.write_text(content)
    out = run("gait", "--params", bad)
    assert out.returncode == 2
    assert message in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_missing_parameter_file(tmp_path):
    out = run("simulate", "--params", tmp_path / "nope.toml", "--steps", "3", "--out", tmp_path / "t.csv")
    assert out.returncode == 2
    assert "not found" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_no_gait_is_a_clear_error(tmp_path):
    """A passive walker going uphill has no gait (collisions lose energy, nothing supplies it):
    one line, exit 2, no output."""
    uphill = tmp_path / "uphill.toml"
    uphill.write_text(SIMPLEST.read_text().replace("slope = 0.009", "slope = -0.05"))
    out = run("simulate", "--params", uphill, "--steps", "3", "--out", tmp_path / "t.csv")
    assert out.returncode == 2
    assert "no gait found" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert out.stderr.count("no gait found") == 1, out.stderr  # said once, not by both layers
    assert not (tmp_path / "t.csv").exists()


def test_simulate_writes_trajectory_files(tmp_path):
    out = run("simulate", "--params", COMPASS, "--steps", "4", "--noise", "0.001", "--seed", "7",
              "--out", tmp_path / "walk.csv")
    assert out.returncode == 0, out.stderr
    for name in ("walk.csv", "walk.events.csv", "walk.json"):
        assert (tmp_path / name).exists()
    meta = json.loads((tmp_path / "walk.json").read_text())
    assert meta["noise_sd"] == 0.001 and meta["source"]["seed"] == 7
    assert len((tmp_path / "walk.events.csv").read_text().splitlines()) == 5  # header + 4 strikes
    again = run("simulate", "--params", COMPASS, "--steps", "4", "--noise", "0.001", "--seed", "7",
                "--out", tmp_path / "again.csv")
    assert again.returncode == 0
    # The seed makes the noise reproducible.
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "walk.csv").read_text()


def test_unknown_effect_is_refused(tmp_path):
    out = run("simulate", "--params", COMPASS, "--steps", "2", "--effect", "warp_drive=1",
              "--out", tmp_path / "t.csv")
    assert out.returncode == 2 and "unknown effect" in out.stderr


STABLE_TOY = DATA / "params" / "stable-toy.toml"


def test_effects_json_lists_the_library():
    out = run("effects", "--json")
    assert out.returncode == 0, out.stderr
    rows = {r["name"]: r for r in json.loads(out.stdout)}
    for name in ("hip_damping", "hip_coulomb", "rolling_resistance", "pivot_friction",
                 "impact_trailing_share", "asymmetry", "cross_slope"):
        assert {"unit", "null", "typical", "bounds", "enters", "breaks_symmetry",
                "physics"} <= set(rows[name])
    assert rows["asymmetry"]["breaks_symmetry"] and not rows["hip_damping"]["breaks_symmetry"]
    text = run("effects")
    assert text.returncode == 0 and "cross_slope" in text.stdout


def test_gait_with_effects(tmp_path):
    """--effect on gait: a symmetric effect changes the step-periodic gait; a symmetry-breaking one
    makes it stride-periodic, and the output says so; a value outside the bounds is one line."""
    base = json.loads(run("gait", "--params", STABLE_TOY, "--json").stdout)
    damped = run("gait", "--params", STABLE_TOY, "--effect", "hip_damping=2e-4", "--json")
    assert damped.returncode == 0, damped.stderr
    damped = json.loads(damped.stdout)
    assert damped["map"] == "step" and damped["step_time"] < 0.95 * base["step_time"]
    tilted = run("gait", "--params", STABLE_TOY, "--effect", "effects.cross_slope=0.01")
    assert tilted.returncode == 0, tilted.stderr
    assert "a stride (two steps)" in tilted.stdout and "stride-map eigenvalues" in tilted.stdout
    bad = run("gait", "--params", STABLE_TOY, "--effect", "hip_damping=-1")
    assert bad.returncode == 2 and "physical bounds" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1


def test_continue_in_an_effect(tmp_path):
    out = run("gait", "--params", STABLE_TOY, "--continue", "effects.hip_damping", "0", "1e-4",
              "--points", "40", "--out", tmp_path / "branch.csv")
    assert out.returncode == 0, out.stderr
    lines = (tmp_path / "branch.csv").read_text().splitlines()
    assert lines[0].startswith("effects.hip_damping,step_time")
    values = [float(line.split(",")[0]) for line in lines[1:]]
    assert values[0] == 0.0 and values[-1] == 1e-4 and len(values) >= 3


TOY_SIZED = DATA / "params" / "toy-sized.toml"
CLEARING_TOY = DATA / "params" / "clearing-toy.toml"


def test_simulate_and_gait_say_the_scuffs_in_one_wording(tmp_path):
    """The toy-sized walker's swing foot goes 0.536 mm below the ramp before the legs pass, once a
    step (docs: data/params/toy-sized.toml; `toywalk gait`): simulate's summary line says so in
    the words gait uses, and its JSON counts them; the clearing toy, which clears by 3.48 mm
    (docs/conventions.md), says nothing of scuffs."""
    from toywalk.model import describe_scuffs

    out = run("simulate", "--params", TOY_SIZED, "--steps", "2", "--out", tmp_path / "walk.csv")
    assert out.returncode == 0, out.stderr
    meta = json.loads((tmp_path / "walk.json").read_text())
    assert meta["scuffs"] == 2 and meta["swing_clearance_m"] < 0
    sentence = describe_scuffs(2, 2, meta["swing_clearance_m"])
    assert sentence.startswith("the swing foot scuffs the ramp before the legs pass, twice in 2 steps")
    assert out.stdout.startswith("completed: 2 steps; ") and f"heel strikes; {sentence} -> " in out.stdout
    gait = run("gait", "--params", TOY_SIZED)
    assert gait.returncode == 0, gait.stderr
    assert ("scuffs            the swing foot scuffs the ramp before the legs pass, once a step, down "
            "to 0.536 mm below it (the model lets it through)") in gait.stdout
    assert ("swing clearance   the swing foot goes 0.536 mm below the ramp at its lowest (37 % into the "
            "step, 10.5 mm behind the stance foot); after the legs pass it touches the ramp (0 mm to "
            "round-off); it rises 22.7 mm at its highest") in gait.stdout
    clear = run("simulate", "--params", CLEARING_TOY, "--steps", "2", "--out", tmp_path / "clear.csv")
    assert clear.returncode == 0, clear.stderr
    assert "scuff" not in clear.stdout and json.loads((tmp_path / "clear.json").read_text())["scuffs"] == 0


def test_render_says_the_scuffs_of_its_trajectory(tmp_path):
    """render of a walk with scuffs says them on stderr, in simulate's words (four frames)."""
    said = run("simulate", "--params", TOY_SIZED, "--steps", "2", "--out", tmp_path / "walk.csv").stdout
    sentence = said.split("heel strikes; ", 1)[1].split(" -> ", 1)[0]
    out = run("render", tmp_path / "walk.csv", "--params", TOY_SIZED, "--duration", "0.05", "--size",
              "320x180", "--seed", "1", "--out", tmp_path / "v.mp4")
    assert out.returncode == 0, out.stderr
    assert f"note: {sentence}\n" in out.stderr


def test_help_says_what_each_option_is_and_its_default():
    """simulate's --params, --steps and --seed have help texts; sample's options show their
    defaults."""
    simulate = run("simulate", "--help").stdout
    for text in ("--params P.toml      parameter TOML file", "--steps N            steps to simulate",
                 "--seed S             random seed of the noise"):
        assert text in simulate, simulate
    sample = " ".join(run("sample", "--help").stdout.split())  # argparse wraps the lines
    for text in ("walkers per ensemble (default 32)", "steps per walker (default 1000)",
                 "(default 3)", "local processes (default 1)", "(default 0)"):
        assert text in sample, sample


def test_continuation_plot_prints_plain_numbers(tmp_path, monkeypatch):
    """A family over a narrow range (step times 0.3695125-0.3695132 s) is drawn with plain tick
    labels, not an offset (\"1e-7+3.6951e-1\"), and the x axis names the parameter's unit."""
    import types

    import matplotlib.figure
    import numpy as np
    from toywalk.sysid.commands.gait import _plot_branch

    seen = {}

    def savefig(fig, path, **kwargs):
        fig.canvas.draw()
        seen["offsets"] = [a.get_major_formatter().get_offset() for ax in fig.axes
                           for a in (ax.xaxis, ax.yaxis)]
        seen["xlabel"] = fig.axes[-1].get_xlabel()

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    slope = np.linspace(0.0785, 0.078535, 8)
    # columns slope, step_time, stride_length, max_abs_eigenvalue, stable (Branch.table)
    rows = np.c_[slope, 0.3695125 + 0.02 * (slope - slope[0]), np.full(8, 0.17), np.full(8, 5.75),
                 np.zeros(8)]
    branch = types.SimpleNamespace(name="slope", period=1, events=[], planar=False)
    _plot_branch(branch, rows, tmp_path / "b.png")
    assert seen["offsets"] == ["", "", "", ""] and seen["xlabel"] == "slope (rad)"


ROBUST_TOY = DATA / "params" / "robust-toy.toml"


def test_gait_on_soft_feet_checks_the_strike_integration():
    """With soft_heel on, `gait` re-solves at 4 x the strike's steps per tau and warns when the
    largest eigenvalue moves by more than 0.005 (robust-toy at 4 ms: 0.027 at the default);
    --soft-steps 80 removes the warning; --soft-steps on rigid feet is one line, exit 2."""
    out = run("gait", "--params", ROBUST_TOY, "--effect", "soft_heel=0.004", "--json")
    assert out.returncode == 0, out.stderr
    check = json.loads(out.stdout)["strike_resolution"]
    assert check["checked"] and not check["resolved"] and check["fine_steps_per_tau"] == 80
    text = run("gait", "--params", ROBUST_TOY, "--effect", "soft_heel=0.004")
    assert "WARNING" in text.stdout and "--soft-steps 80" in text.stdout
    fine = run("gait", "--params", ROBUST_TOY, "--effect", "soft_heel=0.004", "--soft-steps", "80")
    assert fine.returncode == 0, fine.stderr
    assert "integrated at 80 RK4 steps per tau; at 320" in fine.stdout and "WARNING" not in fine.stdout
    rigid = run("gait", "--params", ROBUST_TOY, "--soft-steps", "80")
    assert rigid.returncode == 2 and len(rigid.stderr.strip().splitlines()) == 1
    assert "soft_heel" in rigid.stderr
