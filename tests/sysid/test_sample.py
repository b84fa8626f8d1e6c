"""Posterior sampling: agreement with the fit, resumption after SIGKILL, and the same chain from
one process, local workers and a Dask cluster."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from toywalk.model.trajectory import read_trajectory
from toywalk.sysid.sample import sample

from ..conftest import DATA


def _cli(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "toywalk.sysid.cli", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def _run(*args):
    proc = _cli(*args)
    out, err = proc.communicate(timeout=900)
    return proc.returncode, out, err


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A 10-step noisy walk of the stable toy and its fit of foot radius and lateral offset."""
    folder = tmp_path_factory.mktemp("posterior")
    params = DATA / "params" / "stable-toy.toml"
    walk, fit = folder / "walk.csv", folder / "fit.json"
    assert _run("simulate", "--params", params, "--steps", "10", "--noise", "0.002", "--seed", "3",
                "--out", walk)[0] == 0
    assert _run("fit", walk, "--params", params, "--free", "foot_radius,com_offset[1]",
                "--model", "periodic", "--out", fit)[0] == 0
    return folder, walk, fit


def _chain(path, ensemble=0):
    import emcee

    return emcee.backends.HDFBackend(str(path), name=f"ensemble_{ensemble}", read_only=True).get_chain()


@pytest.mark.slow
def test_posterior_agrees_with_the_fit(fitted, tmp_path):
    """The posterior's mean and SD agree with the fit's estimate and Gauss-Newton SE (the
    posterior is nearly Gaussian here, so the Laplace approximation holds): two independent
    routes to the uncertainty (collocation + implicit-function theorem vs shooting + MCMC)."""
    _, walk, fit_path = fitted
    report = json.loads(fit_path.read_text())
    summary = sample(report, read_trajectory(walk), tmp_path / "chain.h5", walkers=8, steps=150,
                     ensembles=2, seed=4).to_json()
    for name in ("foot_radius", "com_offset[1]"):
        se = report["std"][name]
        # Monte Carlo error of the mean: SD / sqrt(ESS ~ 2400 / tau ~ 5) ~ 0.05 SE.
        assert abs(summary["mean"][name] - report["estimates"][name]) < 0.3 * se, name
        assert 0.75 < summary["std"][name] / se < 1.33, name
        assert summary["rhat"][name] < 1.1
    assert summary["fraction_no_gait"] == 0.0 and summary["probability_stable"] == 1.0


def test_killed_run_resumes_with_every_stored_step(fitted, tmp_path):
    """SIGKILL mid-run; the resumed run keeps every stored step and ends at the requested length."""
    _, walk, fit = fitted
    chain = tmp_path / "chain.h5"
    args = ("sample", fit, walk, "--out", chain, "--walkers", "6", "--steps", "60",
            "--ensembles", "1", "--seed", "2")
    proc = _cli(*args)
    stored = 0
    deadline = time.time() + 300
    while stored < 10 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.5)
        try:
            import h5py

            # Without a lock: a reader holding one would make the writer's next step fail.
            with h5py.File(chain, "r", locking=False) as f:
                stored = int(f["ensemble_0"].attrs["iteration"])
        except (OSError, KeyError):
            continue
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate()  # reap it and close its pipes
    before = _chain(chain)
    assert 10 <= len(before) < 60
    code, out, err = _run(*args, "--report", tmp_path / "report")
    assert code == 0, err
    after = _chain(chain)
    assert after.shape == (60, 6, 2)
    np.testing.assert_array_equal(after[:len(before)], before)
    summary = json.loads(chain.with_suffix(".json").read_text())
    assert summary["length"] == 60 and summary["names"] == ["foot_radius", "com_offset[1]"]
    for name in ("trace.png", "corner.png", "eigenvalues.png", "predictive.png", "checks.png", "report.md"):
        assert (tmp_path / "report" / name).stat().st_size > 0, name
    # the posterior predictive checks (tests/sysid/test_predictive.py): every statistic checked
    checks = json.loads((tmp_path / "report" / "report.json").read_text())["predictive_checks"]
    assert checks["draws"] == 40 and set(checks["p"]) == {"chi2", "lean_range", "steer_range", "steer_mean",
                                                          "stance_pitch_range", "swing_pitch_range"}
    assert "Posterior predictive checks" in (tmp_path / "report" / "report.md").read_text()


def test_workers_and_dask_give_the_serial_chain(fitted, tmp_path):
    """The same seed gives the same chain whether the log-posterior runs in this process, in two
    local processes or on a Dask cluster (a real one, on the loopback address)."""
    from distributed import LocalCluster

    _, walk, fit = fitted
    report = json.loads(fit.read_text())
    table = read_trajectory(walk)
    kwargs = dict(walkers=6, steps=8, ensembles=1, seed=7)
    sample(report, table, tmp_path / "serial.h5", **kwargs)
    sample(report, table, tmp_path / "local.h5", workers=2, **kwargs)
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                      processes=True) as cluster:
        sample(report, table, tmp_path / "dask.h5", scheduler=cluster.scheduler_address, **kwargs)
    serial = _chain(tmp_path / "serial.h5")
    # Warm starts differ between processes; Newton is polished to round-off, so the chains agree
    # to far below any accept/reject margin.
    np.testing.assert_allclose(_chain(tmp_path / "local.h5"), serial, rtol=1e-9)
    np.testing.assert_allclose(_chain(tmp_path / "dask.h5"), serial, rtol=1e-9)


def test_progress_lines_for_a_log(fitted, tmp_path):
    """Where stderr is not a terminal (a batch job's log), `sample` prints a progress line at every
    tenth of each ensemble instead of a progress bar, or nothing for tens of minutes (the defaults
    take 96,000 log-posterior evaluations); a resumed run counts on from the stored steps."""
    _, walk, fit = fitted
    report, table = json.loads(fit.read_text()), read_trajectory(walk)
    lines = []
    sample(report, table, tmp_path / "chain.h5", walkers=6, steps=20, ensembles=2, seed=1, log=lines.append)
    assert len(lines) == 20  # every second step of two ensembles of 20
    assert lines[0].startswith("ensemble 1 of 2: step 2 of 20, ") and "left" in lines[0]
    assert lines[-1].startswith("ensemble 2 of 2: step 20 of 20, ") and lines[-1].endswith("about 0 s left")
    lines.clear()
    sample(report, table, tmp_path / "chain.h5", walkers=6, steps=30, ensembles=2, seed=1, log=lines.append)
    assert [line.split(",")[0] for line in lines] == [f"ensemble {e} of 2: step {k} of 30" for e in (1, 2)
                                                       for k in (21, 24, 27, 30)]
    code, _, err = _run("sample", fit, walk, "--walkers", "6", "--steps", "5", "--ensembles", "1",
                        "--out", tmp_path / "cli.h5")
    assert code == 0, err
    assert "... ensemble 1 of 1: step 5 of 5, " in err


def test_sample_refuses_bad_input(fitted, tmp_path):
    _, walk, fit = fitted
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    code, _, err = _run("sample", bad, walk, "--out", tmp_path / "c.h5")
    assert code == 2 and "cannot read fit file" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c.h5").exists()
    code, _, err = _run("sample", fit, walk, "--out", tmp_path / "c.h5", "--walkers", "2")
    assert code == 2 and "at least twice" in err
