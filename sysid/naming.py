"""The naming rule, written once: which candidate cause a discrepancy analysis names, and when.

Every analysis of what the model lacks (one walk, :func:`toywalk.sysid.discrepancy.diagnose`;
several walks of one walker, :func:`toywalk.sysid.walks.diagnose_walks`; a few summary numbers,
:func:`toywalk.sysid.summary.diagnose_summary`) fits candidate causes that nest the base model,
one more parameter each, and then asks the same questions in the same order (:func:`decide`):

1. **Significant.** A candidate's likelihood ratio against the base has p below ``alpha / K``
   (K candidates; Bonferroni). None: ``unexplained``.
2. **Decisive.** The best beats every other significant candidate by :data:`SEPARATION` in
   chi-square (a likelihood ratio of 100 between two one-parameter extensions). Otherwise the
   candidates are tied: ``unexplained``, and which further walk would tell them apart is
   weighed where the analysis can.
3. **Predicts.** Where the data can be split (strides of a walk), the best predicts held-out
   strides better than the base. Otherwise ``unexplained``.
4. **Together.** The runner-up is named beside it when, added to it, it is significant at
   ``alpha / (K - 1)``.
5. **Explains.** The model with the named causes must *explain the data*, not only fit them
   better (:func:`judge`): per signal the held-out RMS within :data:`RMS_FACTOR` of the noise
   (widened by the noise estimate's own uncertainty), no pattern repeated every step, no
   autocorrelated structure where the noise is known to be white, and no gait feature missed at
   ``alpha`` over the features (:func:`feature_p`, Bonferroni). When it does, the cause is named
   (verdict ``discrepancy``). When it does not, the verdict is ``partly explained``: the best
   candidate is reported as an *effective description* (:class:`Explanation`: the share of the
   base model's excess misfit it removes, and what remains per signal in noise units), never as
   the physical cause: physics the library lacks can be mimicked in part by a term that is in it
   (a soft heel strike by rolling resistance, a hinge spring by the slope).

Each analysis supplies its own answers to the questions (callables), and reads back a
:class:`Decision`. The constants, the candidate records and the rule's text live here too.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from scipy import special
from toywalk.model.effects import EFFECTS, LIBRARY
from toywalk.model.parameters import Params

from .problem import ALONE, fit_bounds
from .residuals import scatter_noise

__all__ = ["ALPHA", "MAX_EXTENDED", "NOISE_GROUPS", "NOISE_WHITENESS", "PARAMETERS", "RMS_FACTOR",
           "SEPARATION", "Candidate", "Decision", "DiagnoseError", "Explanation", "Verdict", "candidates",
           "compatible", "complete_rows", "decide", "feature_p", "judge", "lr_p_value", "noise_reference",
           "parameter_note", "percent", "rule_text", "tied", "white_components"]

#: Family-wise false-alarm rate of the verdict.
ALPHA = 0.01
#: Base parameters that are candidate causes when the analysis holds them fixed: the foot's shape,
#: where the balance masses sit, the hip width and the slope.
PARAMETERS = ("foot_radius", "foot_lateral_radius", "com_offset[0]", "com_offset[1]",
              "com_offset[2]", "hip_width", "slope")
#: Candidates fitted in full after screening.
MAX_EXTENDED = 4
#: Chi-square margin by which a named cause must beat every other significant candidate.
SEPARATION = 2.0 * math.log(100.0)
#: A named model's held-out RMS may exceed the noise SD by this factor, beyond the noise
#: estimate's own uncertainty: what remains is then at most sqrt(1.1**2 - 1) = 0.46 noise SD of
#: misfit. The right model predicts held-out strides at 1.00 +- 1/sqrt(2 n) of the noise (its
#: parameters fitted on the other fold add about p/n, p a few, n hundreds of samples); a soft heel
#: strike in MuJoCo that rolling resistance stands in for left 1.10 to 2.07 (docs/diagnosis.md).
RMS_FACTOR = 1.1
#: Noise whose scatter over alternate samples exceeds that over every sample by more than this is
#: correlated from sample to sample and has less scatter than its SD (on 12-step walks at 140
#: samples/s: 4 % of white signals exceed it, 83 % of signals whose noise is a three-sample
#: running mean).
NOISE_WHITENESS = 1.3
#: The kinds of signal whose noise is judged together: lean, steer, and the legs' pitches.
NOISE_GROUPS = (("lean",), ("steer",), ("pitch_left", "pitch_right"))
#: Standard errors of the noise estimate (and of the held-out RMS itself) by which the RMS limit is
#: widened: the RMS test is one-sided at about 1e-3 per signal when the misfit is nil.
NOISE_Z = 3.0


class DiagnoseError(ValueError):
    """The analysis cannot be made (no base fit, no candidates); the message says why."""


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One candidate cause: a parameter-file name freed from its base value.

    Attributes
    ----------
    name : str
        ``effects.<name>`` or a parameter name.
    kind : str
        'effect' or 'parameter'.
    base : float
        Its value in the base model.
    bounds : tuple of float
        Physical bounds (the fit's).
    side : int
        +1 when the base value is on the lower bound (only increases are possible), -1 on the
        upper one, 0 otherwise.
    prior_sd : float
        Scale of the Savage-Dickey prior: an effect's ``typical`` magnitude; a tenth of the leg
        length for lengths; 0.02 rad for the slope.
    breaks_symmetry : bool
    """

    name: str
    kind: str
    base: float
    bounds: tuple
    side: int
    prior_sd: float
    breaks_symmetry: bool


def compatible(a: str, b: str) -> bool:
    """Two candidates that one fit can free together: not the compliant heel strike beside
    another effect (:data:`toywalk.sysid.problem.ALONE`)."""
    return not (ALONE in (a, b) and a.startswith("effects.") and b.startswith("effects."))


def candidates(params: Params, free=(), effects=None, parameters=None) -> list[Candidate]:
    """The candidate causes: the library's effects (or those named in ``effects``) and the
    parameters of :data:`PARAMETERS` (or ``parameters``), less the free ones and those that
    cannot move (both bounds at the base value). The port-only terms of the registry
    (:data:`toywalk.model.effects.PORTS`) are candidates only where ``effects`` names them, and
    the compliant heel strike (``soft_heel``) only where no other effect is on or free.
    ``library`` in ``effects`` stands for the library's effects (``library,soft_heel``)."""
    names = []
    chosen = list(LIBRARY) if effects is None else [
        e for name in effects for e in (LIBRARY if name == "library" else (name,))]
    for name in chosen:
        if name.removeprefix("effects.") not in EFFECTS:
            raise DiagnoseError(f"unknown effect {name!r}; the library has {', '.join(EFFECTS)}")
        names.append("effects." + name.removeprefix("effects."))
    names += list(PARAMETERS if parameters is None else parameters)
    if not names:  # none asked for: the analysis goes straight to the missing force's search
        return []
    # The compliant heel strike is fitted on the seed's walker only (problem.ALONE).
    effects_on = any(n.startswith("effects.") for n in free) or any(
        f"effects.{n}" != ALONE for n in params.active_effects)
    out = []
    for name in names:
        if name in free or (name == ALONE and effects_on):
            continue
        low, high = fit_bounds(params, list(free) + [name], name)
        value = params.get(name)
        tiny = 1e-12 * max(abs(value), 1.0)
        if high - low <= tiny:
            continue
        side = 1 if value - low <= tiny else (-1 if high - value <= tiny else 0)
        if name.startswith("effects."):
            effect = EFFECTS[name.split(".", 1)[1]]
            kind, prior, breaks = "effect", abs(effect.typical), effect.breaks_symmetry
        else:
            kind = "parameter"
            prior = 0.02 if name == "slope" else 0.1 * params.leg_length
            breaks = False
        out.append(Candidate(name, kind, float(value), (float(low), float(high)), side, prior, breaks))
    if not out:
        raise DiagnoseError("no candidate causes left to test (all free or fixed by their bounds)")
    return out


@dataclasses.dataclass
class Verdict:
    """What every discrepancy analysis answers: the fields of ``report.json`` (docs/formats.md).

    Attributes
    ----------
    verdict : str
        'adequate', 'discrepancy' (a cause named, or ``unexplained``) or 'partly explained' (the
        best candidate improves the model but does not explain the data: ``effective``).
    cause : str or None
        The named cause, ``"unexplained"``, or None (adequate). Never the effective description
        of a ``partly explained`` verdict, which is ``effective``'s.
    causes : list of str
        Every named cause (two when two are decisive).
    ranking : list of dict
        Every candidate, best first.
    gain : dict
        The fit before and after the named cause, and the change in predicted stability.
    evidence : str
        What in the data pointed to the cause.
    effective : dict or None
        :meth:`Explanation.to_json` of the named model's explanation (``explains`` true) or of
        the effective description (``partly explained``); None where no candidate got that far.
    """

    verdict: str
    cause: str | None
    causes: list
    ranking: list
    gain: dict
    evidence: str
    effective: dict | None = dataclasses.field(default=None, kw_only=True)


def lr_p_value(lr: float, bounded: bool) -> float:
    """Likelihood-ratio p-value on one degree of freedom; a 50:50 mixture with zero for a null on
    a physical bound (Self & Liang 1987, JASA 82:605)."""
    p = float(special.chdtrc(1, max(lr, 0.0)))
    return 0.5 * p if bounded else p


def tied(ranking: list[dict], level: float) -> list[dict]:
    """The candidates a walk leaves tied: the fitted ones significant at ``level`` whose
    likelihood ratios come within :data:`SEPARATION` of the best one's, best first (empty when
    the best stands alone or none is significant)."""
    passing = sorted((r for r in ranking if r.get("fitted") and r.get("lr_p", 1.0) < level),
                     key=lambda r: -r["lr"])
    if len(passing) < 2:
        return []
    close = [r for r in passing if passing[0]["lr"] - r["lr"] < SEPARATION]
    return close if len(close) > 1 else []


def complete_rows(ranking: list) -> list:
    """The keys every ranking row of a report has (docs/formats.md: ``effect``, ``score``,
    ``estimate``, ``interval``), in place, where a candidate was not fitted: its score the
    likelihood ratio where there is one, else the score statistic ``z^2`` (None without either),
    and empty estimate and interval. Returns ``ranking``."""
    for row in ranking:
        if "score" not in row:
            row["score"] = row["lr"] if "lr" in row else (row["score_z"] ** 2 if "score_z" in row else None)
        row.setdefault("estimate", {})
        row.setdefault("interval", {})
    return ranking


def feature_p(misfit: dict) -> float:
    """Two-sided p-value of a gait feature's misfit (:func:`toywalk.sysid.residuals.feature_misfit`):
    its standard error is the steps' own scatter, so the misfit over it is Student's t on ``dof``
    degrees of freedom (normal without ``dof``). With 10 steps, 3.7 SE has p = 0.005, where the
    normal law would say 2e-4."""
    z, dof = abs(misfit["z"]), misfit.get("dof")
    if dof is not None and dof >= 1:
        return float(2.0 * special.stdtr(dof, -z))
    return float(2.0 * special.ndtr(-z))


@dataclasses.dataclass
class Explanation:
    """Whether a model explains the data (:func:`judge`).

    Attributes
    ----------
    candidates : list of str
        The candidate(s) the model adds to the base.
    explains : bool
    shortfalls : list of str
        What it leaves, in words (empty when it explains the data).
    remaining : dict of str to float
        Per signal, the held-out RMS in units of the noise SD (1 is the noise alone).
    limit : dict of str to float
        Per signal, the RMS ratio allowed (:data:`RMS_FACTOR` widened by :data:`NOISE_Z` standard
        errors of the noise estimate and of the held-out RMS).
    not_judged : dict of str to str
        Signals whose RMS could not be judged, and why (their noise is not known).
    share : float
        Share of the base model's excess misfit removed, on held-out strides in units of the noise
        reference: ``(chi2_base - chi2_model) / (chi2_base - n)`` over the n held-out samples of
        the judged signals (NaN where not measured, or where the base has no excess).
    """

    candidates: list
    explains: bool
    shortfalls: list
    remaining: dict
    limit: dict
    not_judged: dict
    share: float

    def to_json(self) -> dict:
        return {"candidates": self.candidates, "explains": self.explains, "shortfalls": self.shortfalls,
                "remaining_in_noise_sd": self.remaining, "limit": self.limit,
                "not_judged": self.not_judged, "share_of_excess_misfit": self.share}

    def sentence(self) -> str:
        """One plain sentence on an effective description (``partly explained``)."""
        who = " and ".join(self.candidates)
        one = len(self.candidates) == 1
        share = (f"remove{'s' if one else ''} {percent(self.share)} of the base model's excess misfit"
                 if math.isfinite(self.share) else f"improve{'s' if one else ''} the fit")
        left = "; ".join(self.shortfalls)
        return (f"{who} {share} but {'does' if one else 'do'} not explain the data ({left}): "
                f"{'it' if one else 'they'} may stand in for physics the library lacks, an effective "
                "description, not a named cause")


def percent(share: float) -> str:
    """A share in per cent, a small one with a decimal (0.1 %, not 0 %)."""
    return f"{100 * share:.1f} %" if abs(share) < 0.1 else f"{100 * share:.0f} %"


def judge(names: list, *, held: list | None, patterns: list, features: list,
          whiteness: dict | None = None, alpha: float = ALPHA) -> Explanation:
    """Does the model that adds ``names`` to the base explain the data?

    Parameters
    ----------
    names : list of str
    held : list of (str, dict, dict), or None
        Per walk, labelled (``""`` for one walk, ``" (walk 2)"``): its held-out prediction
        (``rms`` of the model and ``rms_base`` of the base per signal, rad; ``n`` samples per
        signal) and its noise reference (:func:`noise_reference`: per signal ``sd``, rad, None
        when not known, with ``rel_se`` or ``why``). None where the data cannot be split.
    patterns : list of (str, ResidualReport)
        The model's residual reports, labelled: any ``systematic`` component fails.
    features : list of (str, dict)
        The model's gait-feature misfits, labelled (:func:`toywalk.sysid.residuals.feature_misfit`).
    whiteness : dict of str to float, optional
        Per residual component known to have white noise, its Ljung-Box p-value at the model's
        fit: below ``alpha`` over those components it fails (structure beyond white noise).
    alpha : float
    """
    shortfalls, remaining, limit, not_judged = [], {}, {}, {}
    removed = excess = 0.0
    over = []
    for label, h, noise in held or []:
        for name, rms in h["rms"].items():
            ref = noise.get(name, {})
            key = f"{name}{label}"
            if not ref.get("sd"):
                not_judged[key] = ref.get("why", "its noise is not known")
                continue
            n = max(int(h["n"].get(name, 1)), 1)
            ratio = rms / ref["sd"]
            rel = math.hypot(ref.get("rel_se", 0.0), 1.0 / math.sqrt(2.0 * n))
            remaining[key] = ratio
            limit[key] = RMS_FACTOR * math.exp(NOISE_Z * rel)
            if ratio > limit[key]:
                over.append(f"{key} {ratio:.2f}")
            base = h["rms_base"].get(name, math.nan) / ref["sd"]
            removed += n * (base**2 - ratio**2)
            excess += n * (base**2 - 1.0)
    if over:
        shortfalls.append("held-out RMS over the noise: " + ", ".join(over) + " noise SD")
    for label, report in patterns:
        if report is not None and report.systematic:
            shortfalls.append(f"a pattern repeated every step in {', '.join(report.systematic)}{label}")
    finite = [(label, {k: v for k, v in (misfit or {}).items() if math.isfinite(v.get("z", math.nan))})
              for label, misfit in features]
    level = alpha / max(sum(len(f) for _, f in finite), 1)
    for label, misfit in finite:
        missed = sorted((k for k, v in misfit.items() if feature_p(v) < level),
                        key=lambda k: feature_p(misfit[k]))
        if missed:
            shortfalls.append("gait features missed: " + ", ".join(
                f"{k} {misfit[k]['z']:+.1f} SE (p = {feature_p(misfit[k]):.2g})" for k in missed[:3]) + label)
    if whiteness:
        level = alpha / len(whiteness)
        coloured = [f"{k} (Ljung-Box p = {p:.2g})" for k, p in whiteness.items() if p < level]
        if coloured:
            shortfalls.append("residuals correlated in time beyond white noise in " + ", ".join(coloured))
    share = removed / excess if excess > 0 and math.isfinite(removed) else math.nan
    return Explanation(list(names), not shortfalls, shortfalls, remaining, limit, not_judged, share)


def noise_reference(obs, noise_sd: dict, noise_source: str) -> dict:
    """Per signal, the noise SD a model's held-out RMS is judged against (:func:`judge`), measured
    without the model: the SD the walk's file or the user gives (``noise_source`` 'file' or
    'given'; taken as stated), else the samples' own scatter within steps
    (:func:`toywalk.sysid.residuals.scatter_noise`, with its standard error from the step-to-step
    spread) where it is white. A residual RMS is never the reference: it holds the base model's
    misfit. Where the scatter is not white (noise correlated from sample to sample has less
    scatter than its SD) the noise is not known, and ``why`` says so."""
    if noise_source in ("file", "given"):
        return {n: {"sd": float(v), "rel_se": 0.0} for n, v in noise_sd.items()}
    scatter = scatter_noise(obs)
    ratio = {n: v["sd_alternate"] / v["sd"] if v["sd"] > 0 else math.inf for n, v in scatter.items()}
    out = {}
    for group in NOISE_GROUPS:
        # the legs' pitches are mirror images with one noise: judged white together, on the
        # less curved one (a fast pitch's curvature alone lifts its ratio: 1.34 on a stable-toy
        # walk with white noise, tests/sysid/test_discrepancy.py)
        here = [n for n in group if n in scatter]
        white = bool(here) and min(ratio[n] for n in here) <= NOISE_WHITENESS
        for name in here:
            v = scatter[name]
            out[name] = ({"sd": v["sd"], "rel_se": v["rel_se"]} if white else
                         {"sd": None, "why": (f"its noise is correlated from sample to sample (scatter over "
                                              f"alternate samples {ratio[name]:.2f} times larger) and no SD "
                                              "was given")})
    return out


def white_components(reference: dict, report, noise_source: str) -> dict:
    """The Ljung-Box p-values of ``report``'s components whose noise is known to be white (the
    scatter's, not a tracker's SDs: a tracker's errors are correlated over a few frames without
    any model error): lean, steer, and the pitches when both legs' are."""
    if noise_source in ("file", "given") or report is None:
        return {}
    known = {n for n, v in reference.items() if v.get("sd")}
    signals = {"lean": ("lean",), "steer": ("steer",), "stance_pitch": ("pitch_left", "pitch_right"),
               "swing_pitch": ("pitch_left", "pitch_right")}
    return {c: float(t["ljung_box_p"]) for c, t in report.tests.items()
            if set(signals.get(c, (c,))) <= known and math.isfinite(t.get("ljung_box_p", math.nan))}


@dataclasses.dataclass
class Decision:
    """The rule's answer (:func:`decide`).

    Attributes
    ----------
    verdict : str
        'discrepancy' or 'partly explained'.
    cause : str
        The named cause, or ``"unexplained"``.
    causes : list of str
        Every named cause (empty unless the verdict names one).
    lead : dict or None
        The candidate's ranking row that led (the named cause, or the effective description).
    explanation : Explanation or None
        :func:`judge` of the leading model, where it got that far.
    reason : str
        Why the rule ended where it did, as an evidence clause.
    tied : bool
        The best was within :data:`SEPARATION` of another significant candidate.
    """

    verdict: str
    cause: str
    causes: list
    lead: dict | None
    explanation: Explanation | None
    reason: str
    tied: bool = False


def decide(rows: list[dict], level: float, *, explain: Callable[[list], Explanation],
           held_out: Callable[[dict], tuple[float, str]] | None = None,
           together: Callable[[dict, dict], bool] | None = None) -> Decision:
    """The naming rule (module docstring) over one analysis's answers.

    Parameters
    ----------
    rows : list of dict
        The fitted candidates' ranking rows, with ``effect``, ``lr`` and ``lr_p``.
    level : float
        ``alpha / K``.
    explain : callable
        ``explain(names) -> Explanation`` of the model with ``names`` added (:func:`judge`).
    held_out : callable, optional
        ``held_out(row) -> (gain, reason)``: the held-out chi-square gain of the candidate over the
        base (NaN with ``reason`` where it could not be scored). None where the data cannot be
        split (the rule then asks the explanation alone).
    together : callable, optional
        ``together(best, runner) -> bool``: is the runner-up, added to the best, significant at
        ``alpha / (K - 1)``.
    """
    passing = sorted((r for r in rows if math.isfinite(r.get("lr", math.nan)) and r.get("lr_p", 1.0) < level),
                     key=lambda r: -r["lr"])
    if not passing:
        return Decision("discrepancy", "unexplained", [], None, None,
                        "no candidate's likelihood ratio is significant")
    best = passing[0]
    runner = passing[1] if len(passing) > 1 else None
    if runner is not None and best["lr"] - runner["lr"] < SEPARATION:
        return Decision("discrepancy", "unexplained", [], best, None,
                        f"{best['effect']} and {runner['effect']} fit the data about equally well "
                        f"(chi-square {best['lr']:.1f} against {runner['lr']:.1f}; the rule asks "
                        f"{SEPARATION:.1f} apart)", tied=True)
    if held_out is not None:
        gain, why = held_out(best)
        best["held_out_gain"] = gain
        if math.isnan(gain):
            return Decision("discrepancy", "unexplained", [], best, None,
                            f"{best['effect']} fits better but its held-out prediction could not be "
                            f"scored ({why or 'no held-out chi-square'})")
        if gain <= 0:
            return Decision("discrepancy", "unexplained", [], best, None,
                            f"{best['effect']} fits better but does not predict held-out strides better "
                            f"({gain:.1f} in chi-square)")
    names = [best["effect"]]
    if runner is not None and together is not None and together(best, runner):
        names.append(runner["effect"])
    explanation = explain(names)
    if explanation.explains:
        return Decision("discrepancy", names[0], names, best, explanation, "")
    return Decision("partly explained", "unexplained", [], best, explanation, explanation.sentence())


def parameter_note(row: dict, candidate: Candidate) -> str:
    """The evidence clause for a named cause that is a held parameter of the file (the slope, a
    mass offset): the change it asks for, and that a value measured on the walker outranks it;
    empty for an effect."""
    if candidate.kind != "parameter" or candidate.name not in row.get("estimate", {}):
        return ""
    value = row["estimate"][candidate.name]
    return (f"{candidate.name} is named at {value:.6g} where the parameter file says {candidate.base:.6g}: "
            "if the file's value was measured on the walker to better than that, the parameter stands "
            "in for something else and is not the cause")


def rule_text(*, held_out: str | None, explains: str) -> str:
    """The rule in words, for ``report.json``'s ``rule``: ``held_out`` says how the analysis
    predicts held-out data (None: it cannot), ``explains`` what explaining the data means for it."""
    predicts = f", it predicts {held_out} better than the base" if held_out else ""
    return (f"a cause is named when its likelihood ratio is below alpha/K{predicts}, it beats every "
            f"other significant candidate by {SEPARATION:.1f} in chi-square, and the model with it "
            f"explains the data ({explains}); when it improves the model but does not explain the "
            "data the verdict is 'partly explained', the candidate an effective description that may "
            "stand in for physics the library lacks; unexplained when no candidate is significant, "
            "decisive or better on held-out data")
