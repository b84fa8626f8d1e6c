"""``toywalk demo``: the toolkit's whole job on the bundled sample video (data/sample/).

A walker that cannot stand walks stably down a ramp. The demo calibrates the camera from views of
a ChArUco board, tracks the video with that lens, fits the base model (the seed's physics, with
the two quantities a builder measures least well free: the foot's radius and the balance masses'
sideways offset) to the tracked walk, diagnoses what the fitted model gets wrong and names its
cause from the effect library and the parameters it held, and samples the posterior of the named
model (a short run). The video was made with an effect the analysis is not told about
(data/make_sample.py says which and how); only after the analysis does the demo read that, and
the lens and the angles the video was rendered with, and compare.

Everything lands in one folder (default ``out/demo``): ``camera.json``, ``tracked.csv`` (with its
events file), ``fit.json``, ``diagnosis/`` (``report.md``, ``report.json``, figures),
``posterior/`` (chain, summary, figures), and ``report.md`` and ``report.json`` that tie them
together. Each file is written whole (under a temporary name, then renamed); a stage that fails
stops the demo with one line and leaves the earlier stages' files in place. Exit status 0 when the
hidden effect is named, 1 when it is not, 2 for bad input.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

from toywalk.model.files import software_version

from . import calibrate, track
from .common import CommandError, run

__all__ = ["cmd_demo", "register", "SAMPLE_FREE"]

#: The commands the demo's first two stages run, each as ``toywalk`` would (its line on error).
_STAGES = (calibrate, track)

#: The base fit's free parameters: what a builder measures least well on a toy (the foot's
#: fore-aft radius of curvature and the balance mass's sideways offset).
SAMPLE_FREE = ("foot_radius", "com_offset[1]")


def register(subparsers) -> None:
    p = subparsers.add_parser("demo", help="the whole job on the bundled sample video: track, fit, "
                                           "diagnose, sample, report")
    p.add_argument("--out", default="out/demo", help="folder for everything the demo writes")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes for the candidates' fits and the sampler (default: one "
                        "per core, at most four)")
    p.add_argument("--sample-steps", type=int, default=120,
                   help="steps per walker of the posterior's short run (default 120)")
    p.set_defaults(func=cmd_demo)


def _say(message: str) -> None:
    print(f"... {message}", file=sys.stderr, flush=True)


def cmd_demo(args) -> int:
    from toywalk.model.files import DATA_DIR as _DATA

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CommandError(f"--out must name a folder, got the file {out}")
    workers = min(4, os.cpu_count() or 1) if args.workers is None else args.workers
    if workers < 1:
        raise CommandError(f"--workers must be >= 1, got {workers}")
    if args.sample_steps < 10:
        raise CommandError(f"--sample-steps must be >= 10, got {args.sample_steps}")
    sample = _DATA / "sample"
    video, params_path = sample / "walk.mp4", sample / "walker.toml"
    views = sorted((sample / "calibration").glob("view-*.jpg"))
    for path in (video, params_path, sample / "walk.markers.json", sample / "truth.toml"):
        if not path.exists():
            raise CommandError(f"bundled sample file not found: {path} (data/README.md lists them)")
    if not views:
        raise CommandError(f"bundled calibration views not found in {sample / 'calibration'}")
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter()
    seconds: dict[str, float] = {}

    here = _DATA.parent
    print(f"1. Calibrating the camera from {len(views)} views of a ChArUco board "
          f"({views[0].parent.relative_to(here)}/)")
    lap = time.perf_counter()
    status = run(["calibrate", *map(str, views), "--out", str(out / "camera.json")], _STAGES)
    if status != 0:
        return status
    print(f"\n2. Tracking the sample video ({video.relative_to(here)}) with that lens")
    status = run(["track", str(video), "--camera", str(out / "camera.json"), "--markers",
                  str(sample / "walk.markers.json"), "--out", str(out / "tracked.csv")], _STAGES)
    if status != 0:
        return status
    seconds["calibrate and track"] = time.perf_counter() - lap
    return _analyse(out, params_path, sample, workers, args.sample_steps, seconds, clock)


def _analyse(out: Path, params_path: Path, sample: Path, workers: int, sample_steps: int,
             seconds: dict, clock: float) -> int:
    """Stages 3-5 on the tracked walk ``out/tracked.csv``."""
    import numpy as np
    from toywalk.model.files import atomic_write_json, atomic_write_text
    from toywalk.model.parameters import load_params
    from toywalk.model.trajectory import read_trajectory
    from toywalk.sysid.diagnosis_report import write_diagnosis
    from toywalk.sysid.discrepancy import diagnose
    from toywalk.sysid.fit import CONTACT_KEYS, FitError
    from toywalk.sysid.measurement import MeasurementError, observations
    from toywalk.sysid.naming import DiagnoseError
    from toywalk.sysid.sample import SampleError
    from toywalk.sysid.sample import sample as run_sampler

    table = read_trajectory(out / "tracked.csv")
    params = load_params(params_path)
    obs = observations(table)
    sds = {k: float(np.nanmedian(table.signals[f"{k}_sd"])) for k in ("lean", "steer", "pitch_left",
                                                                       "pitch_right")
           if f"{k}_sd" in table.signals}
    print(f"   {len(table.time)} frames, {len(table.events)} heel strikes, {obs.n_steps} whole steps; "
          "median SD " + ", ".join(f"{k} {math.degrees(v):.2f} deg" for k, v in sds.items()))
    free = list(SAMPLE_FREE)
    print(f"\n3. Fitting the base model (the seed's physics; {params_path.name}; free: "
          f"{', '.join(free)}) and diagnosing what it gets wrong")
    try:
        result = diagnose(table, params, model="periodic", free=free, progress=_say, workers=workers)
    except (DiagnoseError, FitError, MeasurementError) as err:
        raise CommandError(str(err)) from err
    seconds["diagnose"] = result.seconds["total"]
    base = result.base
    atomic_write_json(out / "fit.json", dict(base.to_json(), input={
        "trajectory": str(out / "tracked.csv"), "params": str(params_path), "software": software_version()}))
    for name in base.free:
        print(f"   {name:<16s} {base.estimates[name]: .5g} +/- {base.std[name]:.2g} "
              f"(file {params.get(name):.5g})")
    rms = ", ".join(f"{k} {math.degrees(v):.3g} deg" for k, v in base.residual_rms.items()
                    if k not in ("step_duration", "strike_time", *CONTACT_KEYS))
    print(f"   base fit: reduced chi-square {base.to_json()['reduced_chi2']:.2f}; residual RMS {rms}; "
          f"max |eigenvalue| {base.gait.get('max_abs_eigenvalue', math.nan):.3f}")
    write_diagnosis(result, out / "diagnosis", {"trajectory": str(out / "tracked.csv"),
                                                "params": str(params_path), "free": free,
                                                "model": base.model, "software": software_version()})
    print(f"   verdict: {result.verdict}; cause: {result.cause}")
    print(f"   evidence: {result.evidence}")
    gain = result.gain
    if gain:
        name = result.causes[0]
        row = next(r for r in result.ranking if r["effect"] == name)
        lo, hi = row["interval"][name]
        print(f"   {name} = {row['estimate'][name]:.4g}, 95 % [{lo:.4g}, {hi:.4g}]; held-out "
              f"chi-square {gain['base']:.1f} -> {gain['extended']:.1f}; max |eigenvalue| "
              f"{gain['max_abs_eigenvalue']['base']:.3f} -> {gain['max_abs_eigenvalue']['extended']:.3f}")
    print(f"   report -> {out / 'diagnosis' / 'report.md'}")

    chosen = result.extended["+".join(result.causes)] if result.causes else base
    posterior = None
    if chosen.model == "periodic" and chosen.success:
        print(f"\n4. Sampling the posterior of the {'named' if result.causes else 'base'} model "
              f"({', '.join(chosen.free)}; a short run: 2 ensembles x 16 walkers x {sample_steps} "
              "steps)")
        lap = time.perf_counter()
        chain = out / "posterior" / "chain.h5"
        chain.parent.mkdir(exist_ok=True)
        chain.unlink(missing_ok=True)  # a fresh run: the demo's chain is not resumed
        report = chosen.to_json()
        try:
            summary = run_sampler(report, table, chain, walkers=16, steps=sample_steps, ensembles=2,
                                  workers=workers, seed=0, progress=sys.stderr.isatty())
        except (SampleError, FitError, MeasurementError) as err:
            raise CommandError(f"sampling: {err}") from err
        posterior = summary.to_json()
        atomic_write_json(chain.with_suffix(".json"), posterior)
        from toywalk.sysid.sample import posterior_from_fit
        from toywalk.sysid.sample_report import write_report

        write_report(chain, posterior, out / "posterior", posterior_from_fit(report, table)[0], table)
        seconds["sample"] = time.perf_counter() - lap
        for name in summary.names:
            q5, q50, q95 = posterior["quantiles_5_50_95"][name]
            print(f"   {name:<32s} median {q50:.5g}  90 % [{q5:.5g}, {q95:.5g}]")
        if posterior["probability_stable"] is not None:
            print(f"   P(stable gait) {posterior['probability_stable']:.3f}")
        if not posterior["long_enough"]:
            print("   (a short run: longer than the demo's for intervals to rely on; "
                  "`toywalk sample` resumes its chain file)")
        print(f"   report -> {out / 'posterior' / 'report.md'}")

    truth = load_params(sample / "truth.toml")
    hidden = _hidden(truth)
    print("\n5. What the sample video hides (data/sample/truth.toml, read only now)")
    for name, value in hidden.items():
        got = ("named" if name in result.causes else "not named")
        print(f"   {name} = {value:g}: {got}")
    print(f"   the {'named' if result.causes else 'base'} model's fit against the truth:")
    parameters = _against_truth(chosen, truth)
    lens = _lens_errors(out / "camera.json", sample / "walk.camera.json")
    tracking = _tracking_errors(out / "tracked.csv", sample / "walk.truth.csv")
    seconds["total"] = time.perf_counter() - clock
    data = {"verdict": result.verdict, "cause": result.cause, "causes": result.causes,
            "hidden": hidden, "found": sorted(set(hidden) & set(result.causes)),
            "fit": "fit.json", "diagnosis": "diagnosis/report.json",
            "posterior": "posterior/chain.json" if posterior else None,
            "parameters_against_truth": parameters, "lens_errors": lens,
            "tracking_errors": tracking, "seconds": seconds, "software": software_version()}
    atomic_write_json(out / "report.json", data)
    atomic_write_text(out / "report.md", _markdown(data, result, base, posterior))
    print(f"\nreport -> {out / 'report.md'} ({seconds['total']:.0f} s)")
    return 0 if hidden and set(hidden) <= set(result.causes) else 1


def _lens_errors(calibrated_path: Path, truth_path: Path) -> dict:
    """The calibrated lens against the one the video was rendered with (data/sample/
    walk.camera.json, read only after the analysis): each intrinsic's error with the calibration's
    own standard error; printed and returned."""
    from toywalk.model.files import read_json_object
    from toywalk.tracking.camera import Camera, CameraError, load_camera

    calibration = read_json_object(calibrated_path, "camera file", CameraError)
    got, true = Camera.from_dict(calibration), load_camera(truth_path)
    std = calibration["calibration"]["std"]
    values = {"fx": (got.matrix[0, 0], true.matrix[0, 0]), "fy": (got.matrix[1, 1], true.matrix[1, 1]),
              "cx": (got.matrix[0, 2], true.matrix[0, 2]), "cy": (got.matrix[1, 2], true.matrix[1, 2]),
              "k1": (got.distortion[0], true.distortion[0]), "k2": (got.distortion[1], true.distortion[1])}
    errors = {k: {"calibrated": float(a), "true": float(b), "error": float(a - b), "se": std[k]}
              for k, (a, b) in values.items()}
    print("   the calibrated lens against the video's (walk.camera.json): "
          + ", ".join(f"{k} {e['error']:+.3g} (SE {e['se']:.2g})" for k, e in errors.items()))
    return errors


def _tracking_errors(tracked_path: Path, truth_path: Path) -> dict:
    """The tracked walk against the renderer's truth (data/sample/walk.truth.csv, read only after
    the analysis): RMS error per angle and the heel strikes found; printed and returned."""
    import numpy as np
    from toywalk.model.trajectory import read_trajectory
    from toywalk.tracking.accuracy import match_strikes, signal_errors

    tracked, truth = read_trajectory(tracked_path), read_trajectory(truth_path)
    errors = signal_errors(tracked, truth)
    print("   the tracker against the video's truth (walk.truth.csv):")
    for name, e in errors.items():
        rms = math.nan if e["rms_deg"] is None else e["rms_deg"]
        print(f"   {name:<12s} RMS error {rms:.2f} deg over {len(truth.time) - e['gaps']} of "
              f"{len(truth.time)} frames")
    dt = float(np.median(np.diff(truth.time)))
    true = [e for e in truth.events if truth.time[0] + 3 * dt < e["time"] < truth.time[-1] - 3 * dt]
    step = float(np.median(np.diff([e["time"] for e in truth.events])))
    strikes = match_strikes(true, tracked.events, step, dt)
    timing = (f", timing RMS {strikes['timing_rms_frames']:.2f} frame"
              if strikes["timing_rms_frames"] is not None else "")
    print(f"   heel strikes {strikes['found']} found, {strikes['true']} true (more than 3 frames "
          f"from the ends){timing}")
    return {"signals": errors, "heel_strikes": strikes}


def _hidden(truth) -> dict:
    """The effects the sample video was made with (``truth``, data/sample/truth.toml), by their
    parameter names (``effects.NAME``, as the diagnosis names causes)."""
    return {f"effects.{k}": float(v) for k, v in truth.effects.items() if float(v) != 0.0}


def _against_truth(fit, truth) -> dict:
    """Each free parameter of ``fit`` (the named model's, or the base's) against the value the
    video was made with: estimate, SE and their distance in SEs; printed and returned."""
    rows = {}
    for name in fit.free:
        value, est, se = truth.get(name), fit.estimates[name], fit.std[name]
        rows[name] = {"truth": value, "estimate": est, "se": se, "z": (est - value) / se}
        print(f"   {name:<20s} truth {value:.5g}, fitted {est:.5g} +/- {se:.2g} "
              f"({rows[name]['z']:+.1f} SE)")
    return rows


def _markdown(data: dict, result, base, posterior) -> str:
    lines = ["# toywalk demo", "",
             "The bundled sample video (data/sample/walk.mp4) tracked with a lens calibrated from "
             "the bundled board views, the seed's model fitted to it, "
             "what the model gets wrong diagnosed and its cause named, and the named model's "
             "posterior sampled.", "",
             f"- Verdict: **{result.verdict}**; cause: **{result.cause}**.",
             f"- Evidence: {result.evidence}.",
             f"- Hidden in the video: {', '.join(f'{k} = {v:g}' for k, v in data['hidden'].items())}"
             f" ({'found' if data['found'] else 'not found'}).", "",
             "## Base fit (fit.json)", "",
             "| parameter | estimate | SE |", "| --- | --- | --- |"]
    lines += [f"| {n} | {base.estimates[n]:.5g} | {base.std[n]:.2g} |" for n in base.free]
    lines += ["", "## Diagnosis (diagnosis/report.md)", "",
              "![residuals by phase](diagnosis/residuals_by_phase.png)", "",
              "![candidates](diagnosis/candidates.png)", ""]
    if result.gain:
        g = result.gain
        lines += [f"Held-out chi-square {g['base']:.1f} -> {g['extended']:.1f}; max |eigenvalue| "
                  f"{g['max_abs_eigenvalue']['base']:.3f} -> {g['max_abs_eigenvalue']['extended']:.3f}.",
                  ""]
    if posterior:
        lines += ["## Posterior (posterior/report.md; a short run)", "",
                  "| parameter | median | 90 % interval |", "| --- | --- | --- |"]
        for name, (q5, q50, q95) in posterior["quantiles_5_50_95"].items():
            lines.append(f"| {name} | {q50:.5g} | [{q5:.5g}, {q95:.5g}] |")
        lines += ["", "![corner](posterior/corner.png)", ""]
    lines += ["## Against the truth (read only after the analysis)", "",
              "| parameter | truth | fitted | SE | off by |", "| --- | --- | --- | --- | --- |"]
    lines += [f"| {n} | {r['truth']:.5g} | {r['estimate']:.5g} | {r['se']:.2g} | {r['z']:+.1f} SE |"
              for n, r in data["parameters_against_truth"].items()]
    lines += ["", "Calibrated lens: " + ", ".join(f"{k} {e['error']:+.3g} (SE {e['se']:.2g})"
                                              for k, e in data["lens_errors"].items()) + ".", "",
              "Tracker, RMS error against the renderer's truth: "
              + ", ".join(f"{k} {e['rms_deg']:.3f} deg" for k, e in data["tracking_errors"]["signals"].items()
                          if e["rms_deg"] is not None) + ".", ""]
    lines += ["## Time", "", ", ".join(f"{k} {v:.0f} s" for k, v in data["seconds"].items()), ""]
    return "\n".join(lines)
