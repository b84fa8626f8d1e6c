"""`toywalk fit` and `toywalk diagnose` with their defaults on a 30-stride walk that starts off
its cycle, and the Jacobian check's re-solve of a transient walk against the way before.

Run ``.venv/bin/python benchmarks/fit_speed.py`` (about 9 minutes).
It writes ``benchmarks/results/fit_speed.json`` and prints a table. The walk
(``tests/sysid/offcycle.py``): 60 steps of data/params/stable-toy.toml with the foot radius 1.08
and the balance masses' sideways offset 0.95 times the file's, released with its lean rate 0.002
rad/s off its gait's, 120 frames/s, 0.004 rad of noise; fitted from the file with those two free.

- Each command runs as a user runs it, in its own process, stderr a pipe: its wall time, and each
  progress line's time since the start (``stages``: each stage's seconds, to the next line or
  the end). ``fit`` by default (the periodicity test, then the chosen model's fit with its
  Jacobian checked), ``fit --model periodic`` (one fit; the periodic model misses this walk), and
  ``diagnose`` by default (its periodicity test, the base fit, the screening, any candidates'
  fits; two worker processes on two cores). The aims: fit within 5 minutes, diagnose within 10.
- The way before: the check re-solved the walk at each perturbed parameter by IPOPT first, then
  Newton from IPOPT's solution or, where IPOPT failed, from the fit's (``previous_resolve``);
  now Newton from the fit's, IPOPT only where Newton fails (``problem.FitProblem._resolve``). One
  re-solve each way on walks of 10 to 20 steps, and ``fit`` by default both ways on 20 steps.
  The way before is not run on 60 steps: one re-solve took 324 s there (2026-11-28), and the
  default fit ran past 15 minutes.

Measured (2026-11-28, 2 cores, load 1.1 to 3.0): fit 56.3 s (the periodicity test's fits 19.2 s,
the chosen transient fit 36.7 s), both parameters within 0.1 SE; fit --model periodic 3.9 s;
diagnose 90.2 s (its periodicity test 51.6 s, base fit 33.8 s, screening 4.4 s). On 20 steps the
default fit 16.5 s now, 120.7 s before, the same estimates; one re-solve now 0.14-0.28 s at 10 to
20 steps, before 0.18 s (IPOPT converged), 0.73, 7.6 and 25.4 s (IPOPT's restoration failed).

The machine may be shared: compare the two ways within one run.
"""

from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
from tests.sysid.offcycle import FREE, PARAMS, truth, write_offcycle_walk  # noqa: E402

STEPS = 60
#: Walk lengths of the re-solve's comparison: IPOPT still converges at 10 steps, from 14 on it
#: stops in its restoration phase, slower the longer the walk.
RESOLVE_STEPS = (10, 14, 18, 20)
#: The walk of the whole default fit run both ways: the shortest on which the way before cost
#: minutes.
BOTH_WAYS_STEPS = 20
#: The aims (s): fit by default within 5 minutes, diagnose within 10, on 2 cores.
AIMS = {"fit": 300.0, "diagnose": 600.0}


def previous_resolve(problem, x: np.ndarray, theta: np.ndarray):
    """The check's re-solve the way before: IPOPT on the BVP (a transient's start held), then
    Newton from its solution or, where it failed, from ``x``."""
    w0, p = x[:problem.n_w], problem.p_full(theta)
    lbx, ubx = np.full(problem.n_w, -np.inf), np.full(problem.n_w, np.inf)
    lbx[problem.start_free] = ubx[problem.start_free] = w0[problem.start_free]
    sol = problem.prob.solver(x0=w0, p=p, lbg=problem.prob.lbg, ubg=problem.prob.ubg, lbx=lbx, ubx=ubx)
    solved = bool(problem.prob.solver.stats()["success"])
    w = np.array(sol["x"]).ravel() if solved else w0.copy()
    return problem._newton(w, p, w.copy() if solved else None)


def command(argv: list[str], previous: bool = False) -> dict:
    """``toywalk ARGV`` in its own process, stderr a pipe: wall time, exit status, the progress
    lines with their times, and each stage's seconds."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    head = [sys.executable, str(Path(__file__).resolve()), "--previous"] if previous else \
        [sys.executable, "-m", "toywalk.sysid.cli"]
    clock = time.perf_counter()
    run = subprocess.Popen(head + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    lines = []
    for line in run.stderr:
        lines.append((time.perf_counter() - clock, line.rstrip("\n")))
    stdout = run.stdout.read()
    run.wait()
    wall = time.perf_counter() - clock
    stages = [{"line": text, "at_s": at, "seconds": (lines[k + 1][0] if k + 1 < len(lines) else wall) - at}
              for k, (at, text) in enumerate(lines)]
    return {"argv": argv, "way": "before" if previous else "now", "exit": run.returncode,
            "wall_s": wall, "stages": stages, "stdout_tail": stdout.strip().splitlines()[-3:]}


def recovered(fit_file: Path) -> dict:
    """The fit's model, and each free parameter's estimate against the walk's truth in SEs."""
    report = json.loads(fit_file.read_text())
    walker = truth()
    return {"model": report["model"], "status": report["status"],
            "jacobian_check": report["jacobian_check"],
            "estimates": {n: report["estimates"][n] for n in FREE},
            "error_se": {n: (report["estimates"][n] - walker.get(n)) / report["std"][n] for n in FREE}}


def resolves(folder: Path) -> list[dict]:
    """One re-solve of the check each way on walks of :data:`RESOLVE_STEPS` steps, at the
    transient fit's solution (aligned on the measured strikes, as the periodicity test fits)
    with the foot radius a central difference's step up."""
    from toywalk.model.parameters import load_params
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid import fit as fitting
    from toywalk.sysid.problem import continued, setup

    rows = []
    for steps in RESOLVE_STEPS:
        table = read_trajectory(write_offcycle_walk(folder / f"walk{steps}.csv", steps))
        fitted = fitting.fit(table, load_params(PARAMS), FREE, model="transient", strikes="measured",
                             check_jacobian=False)
        problem, w0 = setup(table, fitted.params, FREE, z_guess=None, check_jacobian=True,
                            priors=fitted.priors, **fitted.options)
        x = continued(problem, w0, fitted)
        problem.jacobian(x, fitted.sigma)  # sets the free start the re-solve holds
        theta = problem.theta(x)
        theta[0] += 1e-5 * problem.scale[0]  # fd_check's step
        row = {"steps": steps, "unknowns": problem.n_w}
        for way in ("now", "before"):
            clock = time.perf_counter()
            w = problem._resolve(x, theta) if way == "now" else previous_resolve(problem, x, theta)
            row[f"{way}_s"] = time.perf_counter() - clock
            if way == "before":
                row["ipopt_status"] = problem.prob.solver.stats()["return_status"]
            row[f"{way}_solved"] = w is not None
        row["ratio"] = row["before_s"] / row["now_s"]
        print(f"re-solve, {steps:2d} steps: now {row['now_s']:6.2f} s, before {row['before_s']:7.2f} s "
              f"(IPOPT {row['ipopt_status']})", flush=True)
        rows.append(row)
    return rows


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        walk = write_offcycle_walk(folder / "walk.csv", STEPS)
        free = ["--free", ",".join(FREE)]
        runs = {}
        for name, argv in {
                "fit": ["fit", str(walk), "--params", str(PARAMS), *free, "--out", str(folder / "f.json")],
                "fit_periodic": ["fit", str(walk), "--params", str(PARAMS), *free, "--model", "periodic",
                                 "--out", str(folder / "p.json")],
                "diagnose": ["diagnose", str(walk), "--params", str(PARAMS), *free,
                             "--out", str(folder / "diagnosis")]}.items():
            runs[name] = command(argv)
            print(f"{name:<14s} {runs[name]['wall_s']:7.1f} s (exit {runs[name]['exit']})", flush=True)
            for stage in runs[name]["stages"]:
                print(f"    {stage['seconds']:7.1f} s  {stage['line']}", flush=True)
        runs["fit"]["result"] = recovered(folder / "f.json")
        runs["fit_periodic"]["result"] = recovered(folder / "p.json")
        short = write_offcycle_walk(folder / f"walk{BOTH_WAYS_STEPS}.csv", BOTH_WAYS_STEPS)
        both = {}
        for previous in (False, True):
            out = folder / f"f{BOTH_WAYS_STEPS}_{int(previous)}.json"
            run = command(["fit", str(short), "--params", str(PARAMS), *free, "--out", str(out)], previous)
            run["result"] = recovered(out)
            both[run["way"]] = run
            print(f"fit, {BOTH_WAYS_STEPS} steps, {run['way']:<6s} {run['wall_s']:7.1f} s", flush=True)
        same = both["now"]["result"]["estimates"] == both["before"]["result"]["estimates"]
        rows = resolves(folder)
    data = {
        "benchmark": "fit_speed", "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "steps": STEPS, "cpus": os.cpu_count(), "python": sys.version.split()[0],
        "load_average": os.getloadavg(), "aims_s": AIMS, **runs,
        "aims_met": {name: runs[name]["wall_s"] < aim and runs[name]["exit"] == 0
                     for name, aim in AIMS.items()},
        f"fit_{BOTH_WAYS_STEPS}_steps": {**both, "ratio": both["before"]["wall_s"] / both["now"]["wall_s"],
                                         "same_estimates": same},
        "resolve": rows,
    }
    out = HERE / "results" / "fit_speed.json"
    atomic_write_json(out, data)
    print(f"fit {runs['fit']['wall_s']:.1f} s, diagnose {runs['diagnose']['wall_s']:.1f} s; "
          f"{BOTH_WAYS_STEPS} steps {data[f'fit_{BOTH_WAYS_STEPS}_steps']['ratio']:.1f}x faster than before "
          f"(same estimates: {same}) -> {out}")


def _previous_cli(argv: list[str]) -> int:
    """``toywalk ARGV`` with the check's re-solve the way before (:func:`previous_resolve`)."""
    from toywalk.sysid.cli import main as cli
    from toywalk.sysid.problem import FitProblem

    FitProblem._resolve = lambda self, x, theta: previous_resolve(self, x, theta)
    return cli(argv)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--previous"]:
        sys.exit(_previous_cli(sys.argv[2:]))
    main()
