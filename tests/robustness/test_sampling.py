"""``toywalk sample``: bad fit files, trajectories and chain files; an interrupted run and its resumption.

The chain file is the one output that is meant to be partial: emcee's HDF5 backend stores every
step as it is taken, so a run that is stopped resumes from it. What must hold is that a stored
chain is never damaged or lost by a failed run, that the steps of an interrupted run stay readable
and are continued, and that a failed run that stored no step leaves no file.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time

import emcee
import h5py
import numpy as np
import pytest
from toywalk.sysid.likelihood import LogPosterior
from toywalk.sysid.sample import diagnose_chains

from ..tracking.synthetic import TOYWALK
from .bad_trajectories import BINARY, TRAJECTORIES, bad_trajectory
from .conftest import CAMERA, assert_refused, snapshot, toywalk, write

#: A short run: enough walkers for one free parameter (at least two per parameter), a few steps.
RUN = ("--walkers", "4", "--steps", "6", "--ensembles", "1", "--seed", "2")


def _chain(path):
    return emcee.backends.HDFBackend(str(path), name="ensemble_0", read_only=True).get_chain()


@pytest.fixture(scope="module")
def stored_chain(tmp_path_factory):
    """A chain file as `toywalk sample` writes it (one ensemble of 4 walkers, one parameter, 5
    steps), sampled here from a Gaussian so that it needs no fit."""
    path = tmp_path_factory.mktemp("chain") / "chain.h5"
    backend = emcee.backends.HDFBackend(str(path), name="ensemble_0")
    backend.reset(4, 1)
    rng = np.random.default_rng(0)
    sampler = emcee.EnsembleSampler(4, 1, lambda x: -0.5 * float(x @ x), backend=backend)
    sampler.run_mcmc(rng.normal(size=(4, 1)), 5)
    return path


def _refused_and_untouched(capfd, folder, argv, words):
    before = snapshot(folder)
    outcome = toywalk(capfd, *argv)
    assert_refused(outcome, *words)
    assert snapshot(folder) == before, "the failed run changed the output folder"


# --- fit files ------------------------------------------------------------------------------------

def _fit_cases():
    """name: (a function of the good fit report (dict) giving the file's content; words)."""
    def edit(**changes):
        return lambda report: json.dumps({**report, **changes})

    def drop(key):
        return lambda report: json.dumps({k: v for k, v in report.items() if k != key})

    return {
        "empty": (lambda r: "", ["cannot read fit file"]),
        "cut short": (lambda r: json.dumps(r)[:300], ["cannot read fit file"]),
        "binary": (lambda r: BINARY, ["cannot read fit file"]),
        "a JSON list": (lambda r: "[]", ["must hold a JSON object"]),
        "a camera file (mislabelled)": (lambda r: CAMERA.read_text(), ["not a fit file"]),
        "a failed fit": (edit(success=False, status="Maximum_Iterations_Exceeded"),
                         ["the fit did not succeed", "Maximum_Iterations_Exceeded"]),
        "no covariance": (drop("covariance"), ["not a fit file", "covariance"]),
        "a covariance of the wrong shape": (edit(covariance=[[1e-10]]), ["covariance must be a 7 x 7"]),
        "a covariance with NaN": (lambda r: json.dumps({**r, "covariance": np.full((7, 7), np.nan).tolist()}),
                                  ["covariance of its free parameters is not all finite"]),
        "a NaN estimate": (
            lambda r: json.dumps({**r, "estimates": {**r["estimates"], "foot_radius": np.nan}}),
            ["estimates of the free parameters are not all finite"]),
        "an impossible walker": (lambda r: json.dumps({**r, "params": {**r["params"], "leg_mass": -1}}),
                                 ["leg_mass must be >= 0"]),
        "an unknown free parameter": (edit(free=["bogus"]), ["not a fit file", "bogus"]),
        "nested too deep": (lambda r: "[" * 100_000 + "]" * 100_000, ["cannot read fit file"]),
        "an integer too long to read": (lambda r: '{"success": ' + "9" * 5000 + "}",
                                        ["cannot read fit file"]),
        "a folder": (None, ["cannot read fit file"]),
        "missing": (False, ["fit file not found"]),
    }


FITS = _fit_cases()


@pytest.mark.parametrize("case", FITS)
def test_bad_fit_file(case, fit_file, walk, tmp_path, capfd):
    """A fit file that is not one, or a fit that cannot be sampled: one line, no chain file."""
    make, words = FITS[case]
    bad = tmp_path / "fit.json"
    if make is not False:
        write(bad, None if make is None else make(json.loads(fit_file.read_text())))
    _refused_and_untouched(capfd, tmp_path, ["sample", bad, walk, "--out", tmp_path / "chain.h5", *RUN],
                           words)


@pytest.mark.parametrize("case", TRAJECTORIES)
def test_bad_trajectory(case, fit_file, walk, tmp_path, capfd):
    """The bad trajectories of test_inputs.py, given to ``toywalk sample``."""
    traj, words = bad_trajectory(walk, tmp_path, case)
    _refused_and_untouched(capfd, tmp_path, ["sample", fit_file, traj, "--out", tmp_path / "chain.h5",
                                             *RUN], words)


# --- chain files ----------------------------------------------------------------------------------

def _foreign_hdf5(path, stored):
    with h5py.File(path, "w") as f:
        f["measurements"] = np.arange(10.0)


def _damaged_group(path, stored):
    with h5py.File(path, "w") as f:
        f.create_group("ensemble_0").attrs["iteration"] = 5


#: name: (a function writing the file at a path, given the stored chain's bytes; words).
CHAINS = {
    "zero bytes": (lambda path, stored: path.write_bytes(b""), ["not a readable HDF5 chain file"]),
    "random bytes": (lambda path, stored: path.write_bytes(BINARY), ["not a readable HDF5 chain file"]),
    "a trajectory (mislabelled)": (lambda path, stored: path.write_text("time,lean\n0,0\n"),
                                   ["not a readable HDF5 chain file"]),
    "cut in half": (lambda path, stored: path.write_bytes(stored[:len(stored) // 2]),
                    ["not a readable HDF5 chain file", "truncated"]),
    "an HDF5 file of other data": (_foreign_hdf5, ["not a chain file", "'measurements'"]),
    "an ensemble without its datasets": (_damaged_group, ["ensemble_0 is not an emcee chain"]),
    "a folder": (lambda path, stored: path.mkdir(), ["is not a file"]),
}


@pytest.mark.parametrize("case", CHAINS)
def test_bad_chain_file(case, stored_chain, fit_file, walk, tmp_path, capfd):
    """A file at the chain path that is not a chain (to be resumed): refused in one line, and left
    as it is; no summary written beside it."""
    make, words = CHAINS[case]
    chain = tmp_path / "chain.h5"
    make(chain, stored_chain.read_bytes())
    _refused_and_untouched(capfd, tmp_path, ["sample", fit_file, walk, "--out", chain, *RUN], words)


def test_chain_of_another_shape(stored_chain, fit_file, walk, tmp_path, capfd):
    """A chain stored with 4 walkers, resumed with 6: one line saying so; the chain is kept."""
    chain = tmp_path / "chain.h5"
    chain.write_bytes(stored_chain.read_bytes())
    argv = ["sample", fit_file, walk, "--out", chain, "--walkers", "6", "--steps", "8", "--ensembles", "1"]
    _refused_and_untouched(capfd, tmp_path, argv, ["(walkers, parameters) (4, 1), not (6, 1)"])


def test_report_folder_that_is_a_file(fit_file, walk, tmp_path, capfd):
    """``--report`` naming a file: refused before sampling (it escaped as FileExistsError after
    the chain was written)."""
    (tmp_path / "report").write_bytes(b"stored")
    _refused_and_untouched(capfd, tmp_path, ["sample", fit_file, walk, "--out", tmp_path / "chain.h5",
                                             *RUN, "--report", tmp_path / "report"], ["--report"])


# --- an interrupted run ---------------------------------------------------------------------------

def _interrupt_after(monkeypatch, evaluations):
    """Ctrl-C (SIGINT to this process, as a terminal sends it) during the log-posterior's
    evaluation number ``evaluations + 1``."""
    calls = {"n": 0}
    original = LogPosterior.__call__

    def evaluate(self, x):
        calls["n"] += 1
        if calls["n"] == evaluations + 1:
            signal.raise_signal(signal.SIGINT)
        return original(self, x)

    monkeypatch.setattr(LogPosterior, "__call__", evaluate)


def test_interrupted_run_keeps_its_steps_and_resumes(fit_file, walk, tmp_path, capfd, monkeypatch):
    """Interrupted part-way, the run finishes the step under way and says so in one line (status
    130; emcee's traceback of the walker it was evaluating was printed before); its stored steps
    read back; run again, it continues from them to the requested length, every stored step
    unchanged."""
    chain = tmp_path / "chain.h5"
    argv = ["sample", fit_file, walk, "--out", chain, *RUN]
    # 4 evaluations place the walkers, 4 give their start, then 4 per step: Ctrl-C in the third
    # step, which is finished and stored.
    _interrupt_after(monkeypatch, 4 + 4 + 2 * 4 + 2)
    outcome = toywalk(capfd, *argv)
    assert outcome.code == 130 and outcome.err_lines == ["toywalk sample: interrupted"], outcome.err
    stored = _chain(chain)
    assert len(stored) == 3 and np.all(np.isfinite(stored))
    assert not chain.with_suffix(".json").exists()  # the summary is written only by a whole run
    monkeypatch.undo()
    outcome = toywalk(capfd, *argv)
    assert outcome.code == 0, outcome.err
    resumed = _chain(chain)
    assert resumed.shape == (6, 4, 1)
    np.testing.assert_array_equal(resumed[:len(stored)], stored)
    assert json.loads(chain.with_suffix(".json").read_text())["length"] == 6


def _stored_steps(chain) -> int:
    """Steps stored so far, read while the writer has the file open."""
    try:
        with h5py.File(chain, "r", locking=False) as f:  # a lock would stop the writer's next step
            return int(f["ensemble_0"].attrs["iteration"])
    except (OSError, KeyError):
        return 0


@pytest.mark.slow
def test_killed_run_stops_between_steps_and_resumes(fit_file, walk, tmp_path, capfd):
    """``toywalk sample`` in its own process, killed with SIGTERM (what ``kill PID`` or a job
    scheduler sends) after a few steps: it stores the step under way and exits with one line; the
    chain reads back and a second run continues it, every stored step unchanged."""
    chain = tmp_path / "chain.h5"
    run = ["sample", fit_file, walk, "--out", chain, "--walkers", "4", "--ensembles", "1", "--seed", "2"]
    proc = subprocess.Popen([TOYWALK, *map(str, run), "--steps", "5000"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while _stored_steps(chain) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("... ")]  # progress
    assert proc.returncode == 130 and lines == ["toywalk sample: interrupted"], err
    stored = _chain(chain)
    assert 3 <= len(stored) < 5000 and np.all(np.isfinite(stored))
    outcome = toywalk(capfd, *run, "--steps", str(len(stored) + 2))
    assert outcome.code == 0, outcome.err
    resumed = _chain(chain)
    assert resumed.shape == (len(stored) + 2, 4, 1)
    np.testing.assert_array_equal(resumed[:len(stored)], stored)


def test_run_interrupted_before_its_first_step_leaves_no_file(fit_file, walk, tmp_path, capfd,
                                                            monkeypatch):
    """Interrupted while placing the walkers (no step stored), a new run removes the chain file
    it had begun: nothing to resume, nothing half-made left (an empty chain file was left)."""
    _interrupt_after(monkeypatch, 2)
    outcome = toywalk(capfd, "sample", fit_file, walk, "--out", tmp_path / "chain.h5", *RUN)
    assert outcome.code == 130 and outcome.err_lines == ["toywalk sample: interrupted"], outcome.err
    assert list(tmp_path.iterdir()) == []


def test_chain_whose_walkers_never_moved_reads_back(tmp_path):
    """A chain in which no proposal was accepted (a parameter with zero variance, where emcee's
    autocorrelation estimate divides by zero) is summarised, not a crash: its autocorrelation time
    is infinite and it is not long enough."""
    path = tmp_path / "chain.h5"
    backend = emcee.backends.HDFBackend(str(path), name="ensemble_0")
    backend.reset(4, 1)
    blobs = np.zeros(4, dtype=[("max_abs_eigenvalue", float), ("status", int)])
    blobs["max_abs_eigenvalue"] = 0.97
    backend.grow(6, blobs)
    state = emcee.State(np.full((4, 1), 0.0116), log_prob=np.zeros(4), blobs=blobs,
                        random_state=np.random.RandomState(0).get_state())
    for _ in range(6):
        backend.save_step(state, np.zeros(4, dtype=bool))
    summary = diagnose_chains(path, ["foot_radius"], 1).to_json()
    assert summary["autocorrelation_time"]["foot_radius"] is None  # JSON null: never moved
    json.dumps(summary, allow_nan=False)  # strict JSON: no Infinity, no NaN
    assert summary["long_enough"] is False and summary["length"] == 6
