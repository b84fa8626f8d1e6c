"""When no effect explains a walk: the shape of the missing force, selected through the fit.

After an ``unexplained`` or ``partly explained`` verdict the analysis searches the dictionary of
generalised forces at the walker's ports (:data:`toywalk.model.effects.PORTS`: a torque at the
hinge as a function of the hip angle or its rate, couples at the stance contact, terms of the
collision law) by forward selection, each step made through the model itself (the gait BVP or the
transient model, heel strikes and rolling constraints and all), not by regression on derivatives
of noisy angles:

1. At the current model (the base at first), every term of the dictionary not yet in it is
   screened by its score test (:func:`toywalk.sysid.score.score_tests`: the first-order
   likelihood ratio of freeing it, without a fit), and the :data:`FITTED` best are fitted, each
   added to the current model.
2. The best of them by likelihood ratio is taken when the ratio is significant at ``alpha`` over
   the terms tried (one degree of freedom; a 50:50 mixture with zero for a strength bounded at
   its null), it beats the runner-up by :data:`toywalk.sysid.naming.SEPARATION` in chi-square
   (decisive; else the step reports which terms the walk cannot tell apart and stops), and the
   model with it predicts held-out strides better than the model without
   (:func:`toywalk.sysid.heldout.held_out_tasks`: two folds of alternate strides).
3. Repeat from the model with the term, at most :data:`MAX_TERMS` terms; stop when a step fails.

The selected model is reported as equations with their coefficients, units and 95 % intervals,
its held-out gain over the base and its predicted stability; a term that is a library effect says
so (the hinge's viscous form is hip damping). The rule is the naming rule's, applied term by
term: a term is kept only when the data single it out, never because it is the best of a
dictionary that fits anything.
"""

from __future__ import annotations

import dataclasses
import math

from toywalk.model.effects import PORTS

from .fitresult import FitResult
from .heldout import FitPool, held_out_fits, held_out_score, held_out_tasks, run_fits
from .naming import SEPARATION, DiagnoseError, candidates, lr_p_value
from .problem import gait_period
from .score import score_tests

__all__ = ["FITTED", "MAX_TERMS", "RULE", "MissingForce", "discover", "missing_force_clause",
           "term_sentence"]

#: Terms fitted at each step, the best by their score tests: the score test ranks the
#: dictionary's 15 terms in one pass; fitting each would take 15 fits a step.
FITTED = 3
#: Terms selected at most: a missing force of more than three terms is better described by the
#: walk's residuals than by a dictionary's guess.
MAX_TERMS = 3
RULE = (f"forward selection over the port dictionary: at each step the {FITTED} terms with the "
        "strongest score tests are fitted, each added to the current model; the best is kept when its "
        "likelihood ratio is significant at alpha over the terms tried, it beats the runner-up by "
        f"{SEPARATION:.1f} in chi-square, and the model with it predicts held-out strides (two folds of "
        f"alternate strides) better than the model without; at most {MAX_TERMS} terms")


@dataclasses.dataclass
class MissingForce:
    """What :func:`discover` found.

    Attributes
    ----------
    terms : list of dict
        The selected terms in order: ``port``, ``form``, ``parameter`` (``effects.NAME``),
        ``equation``, ``coefficient``, ``interval`` (95 %), ``std``, ``unit``, ``coincides_with``
        (the library effect the term is, or None), ``lr`` and ``held_out_gain`` of its step.
    steps : list of dict
        Each step's terms fitted (``parameter``, ``score_z``, ``lr``, ``lr_p``) and its outcome.
    stop : str
        Why the selection stopped.
    gain : dict
        Held-out chi-square of the base and of the selected model, and the predicted stability
        (max |eigenvalue|) of both.
    fit : FitResult or None
        The selected model's fit (None when no term was selected).
    """

    terms: list
    steps: list
    stop: str
    gain: dict
    fit: FitResult | None = dataclasses.field(default=None, repr=False)

    def to_json(self) -> dict:
        return {"terms": self.terms, "steps": self.steps, "stop": self.stop, "gain": self.gain, "rule": RULE}


def term_sentence(term: dict) -> str:
    """A selected term as an equation a builder reads: where it acts, the law, the coefficient
    with its interval and unit, and the library effect it is, if any."""
    lo, hi = term["interval"]
    same = f"; this is the library's {term['coincides_with']}" if term["coincides_with"] else ""
    return (f"{term['port']} ({term['form']}): {term['equation']}, k = {term['coefficient']:.4g} "
            f"[{lo:.4g}, {hi:.4g}] {term['unit']}{same}")


def missing_force_clause(found: MissingForce) -> str:
    """The evidence's clause on what the search of the port dictionary found."""
    if not found.terms:
        return f"no term of the port dictionary singled out ({found.stop})"
    terms = "; ".join(term_sentence(t) for t in found.terms)
    gain = found.gain
    return (f"the walk selects from the port dictionary {terms} (held-out chi-square {gain['base']:.1f} -> "
            f"{gain['selected']:.1f}; {found.stop})")


def _dictionary(params, free: list) -> dict:
    """The port terms that can move from the current model, by parameter name (candidates'
    bounds and sides)."""
    names = [f"effects.{p.parameter}" for p in PORTS.values()]
    try:
        movable = candidates(params, free, effects=[n for n in names if n not in free], parameters=[])
    except DiagnoseError:
        return {}
    return {c.name: c for c in movable}


def _screened(table, current: FitResult, names: list, free: list) -> list:
    """``names`` ranked by their score tests at ``current`` (strongest first): (name, z, design
    effect) (:func:`toywalk.sysid.score.score_statistics`)."""
    groups: dict[int, list[str]] = {}
    for name in names:
        groups.setdefault(gait_period(current.params, free + [name]), []).append(name)
    scores = {}
    for group in groups.values():
        scores.update(score_tests(table, current, group))
    z = {n: float(scores[n]["z"]) for n in names}
    return sorted(((n, z[n], float(scores[n]["inflation"])) for n in names),
                  key=lambda t: -abs(t[1]) if math.isfinite(t[1]) else 0.0)


def _fitted(table, current: FitResult, tried: list, free: list, sides: dict, pool: FitPool,
            options: dict) -> list:
    """Each of ``tried`` (name, score z, design effect) fitted added to ``current``: rows with the
    likelihood ratio and its p-value (``fit`` the FitResult), or ``fitted`` False and the reason;
    as in the diagnosis, the ratios are compared on one scale (divided by the largest design
    effect tried) and each p-value takes its own."""
    tasks = [dict(table=table, params=current.params, free=free + [n], check_jacobian=False, warm=current,
                  **options) for n, *_ in tried]
    rows = []
    common = max((d for *_, d in tried), default=1.0)
    for (name, z, design_effect), ext in zip(tried, run_fits(tasks, pool), strict=True):
        row = {"parameter": name, "score_z": z}
        if isinstance(ext, str) or not ext.success or name in ext.undetermined:
            why = ext if isinstance(ext, str) else (ext.status if not ext.success else "not determined")
            row.update(lr=math.nan, lr_p=math.nan, fitted=False, reason=why)
        else:
            drop = current.chi2 - ext.chi2
            row.update(lr=drop / common, lr_p=lr_p_value(drop / design_effect, bool(sides[name])),
                       fitted=True, fit=ext)
        rows.append(row)
    return rows


def discover(table, base: FitResult, free, *, alpha: float, pool: FitPool, noise: dict, say,
             **fit_options) -> MissingForce:
    """Forward selection over the port dictionary from the ``base`` fit of ``table`` (module
    docstring). ``noise`` is the base's noise SD per signal (the held-out folds' weights);
    ``fit_options`` those of the analysis's fits (model, strikes, noise_sd where estimated)."""
    free = list(free)
    by_parameter = {f"effects.{p.parameter}": p for p in PORTS.values()}
    fold_options = {k: v for k, v in fit_options.items() if k != "noise_sd"}
    current, selected, steps, terms = base, [], [], []
    held = {}
    while len(selected) < MAX_TERMS:
        step = len(selected) + 1
        movable = _dictionary(current.params, free + selected)
        if not movable:
            stop = "no term of the dictionary left to add"
            break
        say(f"missing force, step {step}: screening {len(movable)} port terms")
        tried = _screened(table, current, list(movable), free + selected)[:FITTED]
        say(f"missing force, step {step}: fitting {', '.join(n for n, *_ in tried)}")
        rows = _fitted(table, current, tried, free + selected, {n: c.side for n, c in movable.items()}, pool,
                       fit_options)
        record = {"tried": [{k: v for k, v in r.items() if k != "fit"} for r in rows]}
        steps.append(record)
        fitted = sorted((r for r in rows if r["fitted"]), key=lambda r: -r["lr"])
        level = alpha / len(movable)
        if not fitted or not fitted[0]["lr_p"] < level:
            stop = f"no term significant at {level:.2g} (alpha over the {len(movable)} terms tried)"
            record["outcome"] = stop
            break
        best = fitted[0]
        if len(fitted) > 1 and fitted[1]["lr_p"] < level and best["lr"] - fitted[1]["lr"] < SEPARATION:
            stop = (f"{best['parameter']} and {fitted[1]['parameter']} fit the walk about equally well "
                    f"({best['lr']:.1f} and {fitted[1]['lr']:.1f} in chi-square; {SEPARATION:.1f} "
                    "would decide): this walk cannot tell them apart")
            record["outcome"] = stop
            break
        ext = best["fit"]
        say(f"missing force, step {step}: held-out prediction with {best['parameter']}")
        tasks = held_out_tasks(table, ext.params, free + selected + [best["parameter"]], noise, ext,
                               **fold_options)
        if not held:
            tasks = held_out_tasks(table, base.params, free, noise, base, **fold_options) + tasks
        fits = held_out_fits(tasks, pool)
        if not held:
            held["base"] = held["current"] = held_out_score(table, fits[:2], noise)
            fits = fits[2:]
        scored = held_out_score(table, fits, noise)
        gain = held["current"]["chi2"] - scored["chi2"]
        if math.isnan(gain):  # a fold's fit failed: no prediction to compare, said as such
            stop = (f"{best['parameter']} fits better but its held-out prediction could not be scored "
                    f"({scored.get('reason') or held['current'].get('reason') or 'no held-out chi-square'})")
            record["outcome"] = stop
            break
        if not gain > 0:
            stop = (f"{best['parameter']} does not predict held-out strides better (held-out chi-square "
                    f"{held['current']['chi2']:.1f} -> {scored['chi2']:.1f})")
            record["outcome"] = stop
            break
        record["outcome"] = f"{best['parameter']} kept"
        selected.append(best["parameter"])
        current, held["current"] = ext, scored
        port = by_parameter[best["parameter"]]
        terms.append({"port": port.port, "form": port.form, "parameter": best["parameter"],
                      "equation": port.equation, "unit": port.unit, "coincides_with": port.coincides_with,
                      "lr": best["lr"], "held_out_gain": gain})
    else:
        stop = f"{MAX_TERMS} terms selected, the most the search takes"
    for term in terms:  # the coefficients of the final model, all its terms fitted together
        est, se = current.estimates[term["parameter"]], current.std[term["parameter"]]
        term.update(coefficient=est, std=se, interval=[est - 1.96 * se, est + 1.96 * se])
    gain = {}
    if terms:
        gain = {"metric": "held-out chi-square (two folds of alternate strides)",
                "base": held["base"]["chi2"], "selected": held["current"]["chi2"],
                "max_abs_eigenvalue": {"base": base.gait.get("max_abs_eigenvalue"),
                                       "selected": current.gait.get("max_abs_eigenvalue")}}
    return MissingForce(terms, steps, stop, gain, current if terms else None)
