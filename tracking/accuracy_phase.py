"""The tracker's errors by phase of the step: measured on renders of the walker as the camera
films it, and carried into the trajectory it tracks.

The ``*_sd`` columns of a tracked trajectory describe each frame's own error, independent from
frame to frame. A tracker also errs the same way at the same moment of every step: where the legs
pass, the far leg's flags are partly hidden behind the near leg's, and its pitch comes out biased
(measured on the toy-sized walker filmed at 120 frames/s, noise level 1: -0.28 to -0.34 degrees
at 0.60-0.70 of a left step, five reported SDs of its neighbours). ``fit`` and ``diagnose`` take
an error repeated every step for physics: the analysis found the hidden hip damping and then
called the walk ``unexplained`` because of "a pattern repeated every step" that was the tracker's.

So the errors are measured where the truth is known: walks of the same walker (its model, from the
parameter file), rendered as the video was filmed (frame rate, noise level, camera, marker layout)
and tracked back (:func:`measure_by_rendering`). The walks differ as a real walk differs from its
model's: the first on the ramp given, the others on ramps 5 and 10 % shallower and steeper (their
gaits a few percent apart in step time and swing), each with its own noise seed. Per signal, per
stance foot (the camera sees the two legs differently) and per phase bin of the step,
:class:`PhaseErrors` holds

- ``bias``: the mean error over the walks (rad);
- ``bias_sd``: how much one walk's mean error in the bin departs from that, the SD of the walks'
  bin means (with one walk, the samples' scatter over the square root of their number), rad;
- ``excess_sd``: the error's spread about the bias beyond what the tracker's own SDs say
  (``sqrt(max(0, var - mean(sd^2)))``, rad);

and ``timing_scale``, per foot, the spread of its heel strikes' time errors over their ``time_sd``
(normal-consistent median |z|: one misplaced strike set the RMS, :func:`_timing_spread`; never
below 1: a stated SD too large only costs power, one too small names causes wrongly). The feet
differ: through video on compass-3d (150 strikes of ten walks) the left strikes' errors were 0.52
of their SDs and the right ones' 1.33 (the far leg, seen past the near one).

:meth:`PhaseErrors.apply` carries them into a tracked trajectory, each sample between two heel
strikes by its bin: its SD widened to ``sqrt(sd^2 + excess_sd^2 + bias^2 + bias_sd^2)``, and a
column ``NAME_phase_sd`` of ``sqrt(bias^2 + bias_sd^2)``, the size of an error the sample shares
with the same phase of every step, which the test of a pattern repeated every step
(sysid/residuals.py) allows for; each strike's ``time_sd`` is multiplied by its foot's ``timing_scale``. The
bias is not subtracted: it depends on the gait. Subtracted (from three renders of one walk, their
spread 0.003 degrees in lean), it left patterns in lean, steer and the swing pitch of a walk with
hip damping hidden (p 1e-4 to 5e-5) that the track as it came did not have (0.02 to 0.4). The
phase and the stance foot are the tracked trajectory's own (its heel strikes), as they are in the
calibration walks. Samples before the first or after the last strike (outside the steps that fit
uses) are left as they are.

The errors hold for the walker, layout, camera placement and filming settings they were measured
with; a real walker whose gait differs much from its model's sees its legs pass at another phase.
``toywalk accuracy`` makes the file and ``toywalk track --accuracy`` uses it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ..model.trajectory import SIGNALS, TrajectoryTable, read_trajectory
from .accuracy import match_strikes

__all__ = ["FEET", "MAX_BINS", "SLOPE_FACTORS", "AccuracyError", "PhaseErrors", "bins_for",
           "load_phase_errors", "measure", "measure_by_rendering", "step_phase", "walk_variant"]

#: Stance feet, the key's second part: the camera sees the two legs differently.
FEET = ("L", "R")
#: Phase bins at most: 20 resolve the legs' passing (a tenth of a step wide on the toy-sized
#: walker, where the bias lasts 0.1 of a step).
MAX_BINS = 20
#: An interval between strikes this many times the median is taken to hold a missed strike (a
#: walk's steps vary far less; as sysid.measurement.MISSED_STEP_RATIO, which is 2 for the fit's
#: steps: here a missed strike would put a step's errors into the wrong phase, so 1.5).
MISSED_STEP = 1.5
#: Samples of one walk's step in one bin, at least (:func:`bins_for`): fewer leave bins empty in
#: some steps and the bins' means noisy.
SAMPLES_PER_BIN = 2


class AccuracyError(ValueError):
    """A phase-error file or calibration that cannot be used; the message says why."""


def step_phase(table: TrajectoryTable) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's phase in its step (in [0, 1), NaN outside the steps) and the step's stance
    foot ('L'/'R', '' outside), from the table's own heel strikes: a step runs from one strike
    to the next, and the foot that struck first stands. An interval that holds a missed strike
    (the same foot twice, or longer than :data:`MISSED_STEP` median intervals) is no step."""
    phase = np.full(len(table.time), np.nan)
    foot = np.full(len(table.time), "", dtype="<U1")
    strikes = sorted((float(e["time"]), str(e["foot"])) for e in table.events
                     if e.get("foot") in FEET and math.isfinite(float(e["time"])))
    typical = float(np.median(np.diff([t for t, _ in strikes]))) if len(strikes) > 1 else math.inf
    for (a, f), (b, g) in zip(strikes[:-1], strikes[1:], strict=True):
        if f == g or b - a > MISSED_STEP * typical:
            continue
        sel = (table.time >= a) & (table.time < b)
        phase[sel] = (table.time[sel] - a) / (b - a)
        foot[sel] = f
    return phase, foot


def bins_for(samples_per_step: float) -> int:
    """Phase bins for steps of this many samples: :data:`SAMPLES_PER_BIN` each, 4 to
    :data:`MAX_BINS`."""
    return int(np.clip(math.floor(samples_per_step / SAMPLES_PER_BIN), 4, MAX_BINS))


def _bin(phase: np.ndarray, bins: int) -> np.ndarray:
    return np.minimum((np.nan_to_num(phase, nan=0.0) * bins).astype(int), bins - 1)


@dataclasses.dataclass
class PhaseErrors:
    """The tracker's errors by signal, stance foot and phase bin (module docstring).

    Attributes
    ----------
    bins : int
    bias, bias_sd, excess_sd : dict of str to ndarray, shape (bins,)
        Keyed ``SIGNAL@FOOT`` (e.g. ``pitch_left@L``), rad.
    count : dict of str to ndarray of int
        Samples behind each bin.
    timing_scale : dict of str to float
        Per foot (the striking one, ``L`` and ``R``), the spread of its heel strikes' time errors
        over their ``time_sd`` (1.4826 median |z|), at least 1.
    strikes : int
        Heel strikes paired with the truth.
    walks : int
    source : dict
        How the calibration was made (walker, filming, seeds).
    timing_z : dict
        Per foot, the calibration's strike time errors over their ``time_sd``: ``strikes``,
        ``robust`` (the scale before its floor of 1), ``rms``, ``largest`` (:func:`_timing_spread`).
    """

    bins: int
    bias: dict
    bias_sd: dict
    excess_sd: dict
    count: dict
    timing_scale: dict
    strikes: int
    walks: int
    source: dict = dataclasses.field(default_factory=dict)
    timing_z: dict = dataclasses.field(default_factory=dict)

    def largest(self) -> dict:
        """Per signal, the largest |bias| over both feet and all bins, with its SD (rad)."""
        out = {}
        for name in SIGNALS:
            keys = [f"{name}@{f}" for f in FEET]
            k, i = max(((k, int(np.argmax(np.abs(self.bias[k])))) for k in keys),
                       key=lambda ki: abs(self.bias[ki[0]][ki[1]]))
            out[name] = {"bias": float(self.bias[k][i]), "sd": float(self.bias_sd[k][i]),
                         "foot": k[-1], "phase": (i + 0.5) / self.bins}
        return out

    def apply(self, table: TrajectoryTable, note: str = "") -> TrajectoryTable:
        """A copy of a tracked trajectory with these errors carried (module docstring); its
        metadata says so under ``tracker_errors``."""
        phase, foot = step_phase(table)
        b = _bin(phase, self.bins)
        signals = {k: v.copy() for k, v in table.signals.items()}
        for name in SIGNALS:
            if name not in signals:
                continue
            sd = signals.get(f"{name}_sd")
            shared = np.full(len(table.time), np.nan)
            for f in FEET:
                sel = foot == f
                key = f"{name}@{f}"
                shared[sel] = np.hypot(self.bias[key][b[sel]], self.bias_sd[key][b[sel]])
                if sd is not None:
                    sd[sel] = np.sqrt(sd[sel] ** 2 + self.excess_sd[key][b[sel]] ** 2 + shared[sel] ** 2)
            signals[f"{name}_phase_sd"] = np.where(shared > 0, shared, np.nan)
        events = [dict(e) for e in table.events]
        for e in events:
            if "time_sd" in e and math.isfinite(float(e["time_sd"])):
                worst = max(self.timing_scale.values())  # a strike of no known foot: the larger
                e["time_sd"] = float(e["time_sd"]) * self.timing_scale.get(e.get("foot"), worst)
        metadata = dict(table.metadata)
        metadata["tracker_errors"] = {
            "file": note, "method": "by signal, stance foot and phase bin: sd widened to sqrt(sd^2 + "
                                    "excess_sd^2 + bias^2 + bias_sd^2), *_phase_sd = sqrt(bias^2 + "
                                    "bias_sd^2); time_sd times timing_scale (tracking/accuracy_phase.py)",
            "bins": self.bins, "walks": self.walks, "timing_scale": self.timing_scale,
            "largest_bias_rad": self.largest(), "calibration": self.source}
        return TrajectoryTable(table.time, signals, table.stance, events, metadata)

    def to_json(self) -> dict:
        def arrays(d):
            return {k: [float(x) for x in v] for k, v in d.items()}

        return {"kind": "toywalk tracker errors by phase of the step", "units": "rad",
                "bins": self.bins, "walks": self.walks, "strikes": self.strikes,
                "timing_scale": self.timing_scale, "timing_z": self.timing_z, "bias": arrays(self.bias),
                "bias_sd": arrays(self.bias_sd), "excess_sd": arrays(self.excess_sd),
                "count": {k: [int(x) for x in v] for k, v in self.count.items()},
                "largest_bias_rad": self.largest(), "source": self.source}

    @classmethod
    def from_json(cls, data: dict) -> PhaseErrors:
        bins = int(data["bins"])
        keys = [f"{s}@{f}" for s in SIGNALS for f in FEET]
        tables = {}
        for part in ("bias", "bias_sd", "excess_sd", "count"):
            tables[part] = {k: np.asarray(data[part][k], dtype=float) for k in keys}
            if any(v.shape != (bins,) or not np.all(np.isfinite(v)) for v in tables[part].values()):
                raise AccuracyError(f"{part} must hold {bins} finite numbers for each of {', '.join(keys)}")
        given = data["timing_scale"]
        # a number: one scale for both feet (the files before the feet were told apart)
        scale = ({f: given for f in FEET} if isinstance(given, int | float) else
                 {f: given.get(f) for f in FEET} if isinstance(given, dict) else None)
        if scale is None or not all(isinstance(v, int | float) and not isinstance(v, bool)
                                    and math.isfinite(v) and v >= 1.0 for v in scale.values()):
            raise AccuracyError(f"timing_scale must be a number >= 1 for each foot ({', '.join(FEET)}), "
                                f"got {given!r}")
        scale = {f: float(v) for f, v in scale.items()}
        return cls(bins, tables["bias"], tables["bias_sd"], tables["excess_sd"],
                   {k: v.astype(int) for k, v in tables["count"].items()}, scale,
                   int(data["strikes"]), int(data["walks"]), dict(data.get("source") or {}),
                   dict(data.get("timing_z") or {}))


def load_phase_errors(path: str | Path) -> PhaseErrors:
    """Read a file of :meth:`PhaseErrors.to_json`; AccuracyError (one line) if it is not one."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        return PhaseErrors.from_json(data)
    except FileNotFoundError as err:
        raise AccuracyError(f"tracker-error file not found: {path}") from err
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
        if isinstance(err, AccuracyError):
            raise AccuracyError(f"{path}: {err}") from err
        why = str(err).splitlines()[0] if str(err) else "unreadable"
        raise AccuracyError(f"{path} is not a tracker-error file from toywalk accuracy "
                            f"({type(err).__name__}: {why})") from err


def measure(pairs, bins: int | None = None, source: dict | None = None) -> PhaseErrors:
    """The tracker's errors from ``pairs`` of (tracked, truth) :class:`TrajectoryTable` with the
    same sample times (module docstring). ``bins`` defaults to :func:`bins_for` the walks' median
    samples a step. AccuracyError if no pair has two heel strikes."""
    pairs = list(pairs)
    phased = [(m, t, *step_phase(m)) for m, t in pairs]
    phased = [p for p in phased if np.isfinite(p[2]).any()]
    if not phased:
        raise AccuracyError("no calibration walk had two heel strikes found: nothing to measure")
    if bins is None:
        per_step = [np.median(np.diff([e["time"] for e in m.events])) / np.median(np.diff(m.time))
                    for m, *_ in phased if len(m.events) >= 2]
        bins = bins_for(float(np.median(per_step)))
    keys = [f"{s}@{f}" for s in SIGNALS for f in FEET]
    tables = {part: {k: np.zeros(bins) for k in keys} for part in ("bias", "bias_sd", "excess_sd", "count")}
    for name in SIGNALS:
        for f in FEET:
            key = f"{name}@{f}"
            for i in range(bins):
                errs, sds, means = [], [], []
                for m, t, phase, foot in phased:
                    sel = (foot == f) & (_bin(phase, bins) == i) & np.isfinite(phase)
                    err = (m.signals[name] - t.signals[name])[sel]
                    sd = m.signals.get(f"{name}_sd", np.zeros_like(m.time))[sel]
                    ok = np.isfinite(err) & np.isfinite(sd)
                    if ok.any():
                        errs.append(err[ok])
                        sds.append(sd[ok])
                        means.append(float(np.mean(err[ok])))
                _cell(tables, key, i, errs, sds, means)
    z = {f: [] for f in FEET}
    strikes = 0
    for m, t, *_ in phased:
        step = float(np.median(np.diff([e["time"] for e in t.events]))) if len(t.events) >= 2 else math.inf
        found = match_strikes(t.events, m.events, step, float(np.median(np.diff(m.time))))
        strikes += found["true"] - found["missed"]
        for f, values in found["timing_z_by_foot"].items():
            z.setdefault(f, []).extend(values)
    spread = {f: _timing_spread(np.asarray(z[f], float)) for f in FEET}
    scale = {f: max(1.0, spread[f]["robust"]) if z[f] else 1.0 for f in FEET}
    return PhaseErrors(bins, tables["bias"], tables["bias_sd"], tables["excess_sd"],
                       {k: v.astype(int) for k, v in tables["count"].items()}, scale, strikes,
                       len(phased), dict(source or {}), spread)


def _timing_spread(z: np.ndarray) -> dict:
    """One foot's heel-strike time errors over their ``time_sd``: how many, their normal-consistent
    median absolute value (1.4826 median |z|, the scale), their RMS and the largest |z|.

    The scale is the robust one because a strike the tracker misplaces (the far leg hidden at the
    strike) lands many SDs off, and one such strike set the RMS: on compass-3d, the right strikes
    of three calibration walks gave an RMS of 1.84 (one strike 5.3 SDs off; 1.57 without it) and
    of five others 7.72, against 1.33 over the 75 right strikes of ten walks analysed. A rare
    misplaced strike is the tracker's failure, not its typical error."""
    if not len(z):
        return {"strikes": 0, "robust": math.nan, "rms": math.nan, "largest": math.nan}
    return {"strikes": int(len(z)), "robust": float(1.4826 * np.median(np.abs(z))),
            "rms": float(np.sqrt(np.mean(z**2))), "largest": float(np.max(np.abs(z)))}


def _cell(tables: dict, key: str, i: int, errs: list, sds: list, means: list) -> None:
    """One bin's bias, its SD from walk to walk, the excess spread and the count (module
    docstring); zeros where no sample fell in it (a bin the tracker never saw carries nothing)."""
    if not errs:
        return
    err, sd = np.concatenate(errs), np.concatenate(sds)
    n = len(err)
    var = float(np.var(err, ddof=1)) if n > 1 else 0.0
    tables["bias"][key][i] = float(np.mean(err))
    tables["bias_sd"][key][i] = math.sqrt(float(np.var(means, ddof=1)) if len(means) > 1 else var / n)
    tables["excess_sd"][key][i] = math.sqrt(max(0.0, var - float(np.mean(sd**2))))
    tables["count"][key][i] = n

#: The calibration walks' ramps, as factors of the walker's slope, in order (module docstring):
#: the toy-sized walker's step time moves by about 1 % and its swing by 2 % a 5 % step.
SLOPE_FACTORS = (1.0, 0.95, 1.05, 0.9, 1.1)


def walk_variant(params, k: int):
    """The walker of calibration walk ``k``: its slope times :data:`SLOPE_FACTORS` in turn (a ramp
    on which the walker has no gait near its own is replaced by its own ramp, and the file says
    so: ``slopes_without_gait``)."""
    return params.replace(slope=float(params.slope) * SLOPE_FACTORS[k % len(SLOPE_FACTORS)])


def measure_by_rendering(params, folder: str | Path, *, walks: int = 5, steps: int = 16, fps: float = 120.0,
                         noise: int = 1, size: tuple[int, int] = (1280, 720), camera=None, layout=None,
                         seed: int = 0, hip_width: float | None = None, engine: str = "scene",
                         progress=None) -> PhaseErrors:
    """Measure the tracker's errors on ``walks`` renders of the walker's gait (``steps`` steps from
    its fixed point, as ``toywalk simulate``; walk ``k`` on the ramp of :func:`walk_variant`)
    filmed as ``toywalk render`` films them (frame rate, ``noise`` level, image ``size``;
    ``camera`` with a ramp pose, else placed for each walk as render places it; ``layout``, else
    the walker's default), each with its own noise seed (``seed``, ``seed + 1``, ...), tracked
    back as ``toywalk track`` tracks them (the lens's intrinsics only, the ramp pose measured).
    Videos go to ``folder`` (kept: they are the calibration's evidence). ``engine`` is the
    renderer, the project's own (``scene``) or MuJoCo's (``mujoco``), as ``toywalk render
    --engine``. ``progress(k, walks)`` is called after each walk.

    Raises AccuracyError where the walker has no gait or a walk cannot be rendered or tracked.
    """
    from ..model.gait import GaitNotFound, find_gait
    from ..model.simulate import gait_walk
    from .markers import default_layout
    from .render import RenderError, RenderOptions, default_filming, params_record, render
    from .track import TrackError, track_video

    if walks < 1 or steps < 3:
        raise AccuracyError(f"need at least one walk of three steps, got {walks} walk(s) of {steps}")
    given = camera is not None
    draw, failures = render, (RenderError, TrackError)
    if engine == "mujoco":
        from .render_mujoco import MujocoUnavailable, render_mujoco

        draw, failures = render_mujoco, (RenderError, TrackError, MujocoUnavailable)
    elif engine != "scene":
        raise AccuracyError(f"engine must be 'scene' or 'mujoco', got {engine!r}")
    try:
        options = RenderOptions.preset(noise, fps=float(fps))
    except RenderError as err:
        raise AccuracyError(str(err).splitlines()[0]) from err
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        start = find_gait(params).fixed_point
    except GaitNotFound as err:
        raise AccuracyError(f"the walker has no gait to film: {str(err).splitlines()[0]}") from err
    pairs, slopes, skipped = [], [], []
    for k in range(walks):
        walker = walk_variant(params, k)
        video = folder / f"walk{k}.mp4"
        try:
            walk = gait_walk(walker, steps, source="toywalk accuracy", z_guess=start)
        except GaitNotFound:  # a ramp too far from the walker's: its own ramp again instead
            skipped.append(float(walker.slope))
            walker = params
            walk = gait_walk(walker, steps, source="toywalk accuracy", z_guess=start)
        try:
            shot, path, placed = ((camera, None, None) if given
                                  else default_filming(walk, walker, *size, options))
            shown = layout if layout is not None else (placed or default_layout(walker))
            result = draw(walk, walker, shot, shown, options, video, rng=seed + k, path=path,
                          source="toywalk accuracy: the walker's gait")
            tracked, _ = track_video(video, dataclasses.replace(shot, ramp_pose=None), shown,
                                     hip_width=hip_width)
        except failures as err:
            raise AccuracyError(f"calibration walk {k + 1}: {str(err).splitlines()[0]}") from err
        pairs.append((tracked.table(), read_trajectory(result.paths["truth"])))
        slopes.append(float(walker.slope))
        if progress is not None:
            progress(k + 1, walks)
    source = {"walker": params_record(params), "effects": dict(params.effects), "steps": steps,
              "slopes": slopes, "slopes_without_gait": skipped, "seeds": [seed + k for k in range(walks)],
              "fps": float(fps),
              "noise_level": noise, "size": list(shot.size), "engine": engine,
              "camera": "given" if given else "placed for each walk as render places it",
              "layout": shown.description, "folder": str(folder)}
    return measure(pairs, source=source)
