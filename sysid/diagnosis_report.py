"""The report of a discrepancy analysis (``toywalk diagnose``): ``report.json``, ``report.md`` and
figures, written into a folder.

Figures (matplotlib's object API, the caller's backend untouched):

- ``residuals_by_phase.png``: each signal's mean residual in phase bins of the step with its
  standard error over the steps, for the base model and the named cause's;
- ``features.png``: the misfit of each gait feature in standard errors, before and after;
- ``candidates.png``: every candidate's score-test z and, for those fitted, the likelihood ratio.

Every file is written under a temporary name and renamed into place: a killed run leaves no
half-written file.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_figure, atomic_write_json, atomic_write_text, strict_json

from .discrepancy import Diagnosis
from .naming import SEPARATION, percent

__all__ = ["candidates_plot", "explanation_line", "numbers_figure", "verdict_lines", "write_diagnosis",
           "write_summary_diagnosis", "write_walks_diagnosis"]


def write_diagnosis(diagnosis: Diagnosis, folder: Path, inputs: dict | None = None) -> list[Path]:
    """Write report.json, report.md and the figures into ``folder`` (created if missing)."""
    return _write_report(Path(folder), diagnosis, inputs, _markdown(diagnosis), lambda f: [
        _phase_figure(diagnosis, f), _feature_figure(diagnosis, f), _candidate_figure(diagnosis, f)])


def _write_report(folder: Path, diagnosis, inputs: dict | None, markdown: str, figures) -> list[Path]:
    """report.json (strict JSON: NaN, where a gain or an interval was not measured, as null, with
    the command's ``inputs``), report.md and the figures that ``figures(folder)`` draws."""
    folder.mkdir(parents=True, exist_ok=True)
    data = strict_json(diagnosis.to_json())
    if inputs:
        data["input"] = inputs
    written = figures(folder)
    atomic_write_text(folder / "report.md", markdown)
    atomic_write_json(folder / "report.json", data)
    return written + [folder / "report.md", folder / "report.json"]


def _finish(fig, path: Path) -> Path:
    fig.tight_layout()
    atomic_write_figure(path, fig)
    return path


def _phase_panel(ax, name: str, reports) -> None:
    """One signal's mean residual in each phase bin with 2 SE bars, for each ``(label, report,
    colour)`` of ``reports``."""
    bins = reports[0][1].bins
    centre = (np.arange(bins) + 0.5) / bins
    for label, rep, colour in reports:
        mean = np.degrees(rep.phase_mean[name])
        se = np.degrees(rep.phase_se[name])
        ax.errorbar(centre, mean, yerr=2 * se, color=colour, marker="o", ms=3, lw=1, capsize=2,
                    label=f"{label} (p = {rep.tests[name]['pattern_p']:.2g})")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.legend(fontsize=7, loc="upper right")


_PHASE_XLABEL = "phase of the step (bars: 2 SE over the steps; p: pattern repeated every step)"


def _phase_figure(d: Diagnosis, folder: Path) -> Path:
    from matplotlib.figure import Figure

    names = list(d.residuals.phase_mean)
    fig = Figure(figsize=(8, 1.9 * len(names) + 0.6))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)
    for i, name in enumerate(names):
        reports = [("base", d.residuals, "C0")]
        if d.residuals_extended is not None:
            reports.append((" + ".join(d.causes) or "extended", d.residuals_extended, "C3"))
        _phase_panel(axes[i, 0], name, reports)
        axes[i, 0].set_ylabel(f"{name}\n(deg)", fontsize=8)
    axes[-1, 0].set_xlabel(_PHASE_XLABEL)
    return _finish(fig, folder / "residuals_by_phase.png")


def _feature_figure(d: Diagnosis, folder: Path) -> Path:
    from matplotlib.figure import Figure

    keys = [k for k, v in d.features.items() if math.isfinite(v.get("z", math.nan))]
    fig = Figure(figsize=(8, 0.28 * len(keys) + 1.2))
    ax = fig.subplots()
    y = np.arange(len(keys))
    ax.barh(y + 0.2, [d.features[k]["z"] for k in keys], height=0.4, color="C0", label="base")
    if d.features_extended is not None:
        ax.barh(y - 0.2, [d.features_extended[k]["z"] for k in keys], height=0.4, color="C3",
                label=" + ".join(d.causes))
    for x in (-3, 3):
        ax.axvline(x, color="k", ls="--", lw=0.6)
    ax.set_yticks(y, keys, fontsize=7)
    ax.set_xlabel("measured minus model, in standard errors over the steps")
    ax.legend(fontsize=7)
    return _finish(fig, folder / "features.png")


def _candidate_figure(d: Diagnosis, folder: Path) -> Path:
    return candidates_plot(d.ranking, d.alpha, "likelihood ratio (fitted)", folder / "candidates.png")


def candidates_plot(rows: list, alpha: float, fitted_label: str, path: Path) -> Path:
    """Each candidate's score statistic z^2 (screening) and, where fitted, its likelihood ratio,
    strongest at the top, against the rule's chi-square at alpha / K; the legend beside the axes."""
    from matplotlib.figure import Figure
    from scipy import special

    def strength(r):
        return max(r.get("score_z", 0.0) ** 2, r.get("lr", 0.0) or 0.0)

    rows = sorted(rows, key=strength, reverse=True)
    k = len(rows)
    fig = Figure(figsize=(10, 0.3 * k + 1.4))
    ax = fig.subplots()
    y = np.arange(k)[::-1]
    ax.barh(y + 0.2, [r.get("score_z", 0.0) ** 2 for r in rows], height=0.4, color="C7",
            label="score statistic z^2 (screening)")
    ax.barh(y - 0.2, [max(r.get("lr", 0.0), 0.0) for r in rows], height=0.4, color="C2", label=fitted_label)
    level = special.chdtri(1, alpha / k)
    ax.axvline(level, color="k", ls="--", lw=0.8, label=f"significance: alpha / K = {alpha:g} / {k}")
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlim(0, 1.5 * max([level] + [strength(r) for r in rows]))  # every bar ends inside
    ax.set_yticks(y, [r["effect"] for r in rows], fontsize=7)
    ax.set_xlabel("chi-square (likelihood ratio or score statistic against the base model)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the bars, never on one
    return _finish(fig, path)


def _markdown(d: Diagnosis) -> str:
    lines = ["# Discrepancy analysis", "",
             *verdict_lines(d),
             f"Rule: {d.rule} (alpha = {d.alpha:g}, K = {len(d.ranking)} candidates).", "",
             "## Base model", "",
             f"Model: {_model_words(d.base.model)}, used by every fit of the analysis. Free: "
             f"{', '.join(d.base.free) or 'none'}; chi-square {d.base.chi2:.1f} over "
             f"{d.base.n_residuals} residuals; noise {d.base.noise_source}." + _shared_words(d), "",
             "| signal | RMS (deg) | repeated pattern p | Ljung-Box p | runs p |", "|---|---|---|---|---|"]
    for name, t in d.residuals.tests.items():
        lines.append(f"| {name} | {math.degrees(t['rms']):.3f} | {t['pattern_p']:.3g} | "
                     f"{t['ljung_box_p']:.3g} | {t['runs_p']:.3g} |")
    untested = [name for name, t in d.residuals.tests.items() if not math.isfinite(t["pattern_p"])]
    lines += ["", f"Repeated pattern: {d.residuals.bins} phase bins a step"
              + (f"; not tested ({', '.join(untested)}): fewer than three steps with a sample in "
                 "every bin" if untested else "") + "."]
    lines += ["", "![residuals by phase](residuals_by_phase.png)", "", "## Gait features", "",
              "| feature | measured | model | z (base) | z (extended) |", "|---|---|---|---|---|"]
    for key, v in d.features.items():
        after = f"{d.features_extended[key]['z']:+.2f}" if d.features_extended else ""
        lines.append(f"| {key} | {_in_report_units(v['measured'], v['unit'])} | "
                     f"{_in_report_units(v['model'], v['unit'])} | {v['z']:+.2f} | {after} |")
    lines += ["", "![features](features.png)", "", "## Candidates", "",
              "| candidate | score z | LR | LR p | held-out gain | estimate [95 %] | log BF |",
              "|---|---|---|---|---|---|---|"]
    for r in d.ranking:
        est = ", ".join(f"{v:.4g} [{r['interval'][k][0]:.4g}, {r['interval'][k][1]:.4g}]"
                        for k, v in r["estimate"].items())
        lines.append(f"| {r['effect']} | {r['score_z']:+.2f} | {r.get('lr', math.nan):.1f} | "
                     f"{r.get('lr_p', math.nan):.2g} | {r.get('held_out_gain', math.nan):.1f} | "
                     f"{est} | {r.get('log_bayes_factor', math.nan):.1f} |")
    lines += ["", "![candidates](candidates.png)", ""]
    if d.next_walk:
        lines += _next_walk_markdown(d.next_walk)
    if d.missing_force is not None:
        lines += missing_force_markdown(d.missing_force)
    if d.gain:
        g = d.gain
        lines += ["## Gain", "", f"{g['metric']}: base {g['base']:.1f}, extended {g['extended']:.1f}.",
                  "", "| signal | held-out RMS base (deg) | extended (deg) |", "|---|---|---|"]
        for name, v in g["held_out_rms"]["base"].items():
            lines.append(f"| {name} | {math.degrees(v):.3f} | "
                         f"{math.degrees(g['held_out_rms']['extended'][name]):.3f} |")
        eig = g["max_abs_eigenvalue"]
        lines += ["", f"Predicted stability: max |eigenvalue| {eig['base']:#.4g} (base) -> "
                      f"{eig['extended']:#.4g} (extended).", ""]
    return "\n".join(lines) + "\n"


def missing_force_markdown(found) -> list[str]:
    """The report's section on the shape of the missing force (sysid/missing_force.py)."""
    from .missing_force import RULE, term_sentence

    lines = ["## The shape of the missing force", "",
             "No cause of the library explains the walk, so the dictionary of generalised forces at "
             "the walker's ports (docs/formats.md, \"Ports and forms\") was searched through the fit.", ""]
    if found.terms:
        lines += ["The walk selects, in this order (coefficients of the model with all of them, 95 %):", ""]
        lines += [f"{k}. {term_sentence(t)}; held-out gain {t['held_out_gain']:.1f}"
                  for k, t in enumerate(found.terms, start=1)]
        g = found.gain
        eig = g["max_abs_eigenvalue"]
        lines += ["", f"{g['metric']}: base {g['base']:.1f}, with the terms {g['selected']:.1f}. "
                  f"Predicted stability: max |eigenvalue| {eig['base']:#.4g} (base) -> "
                  f"{eig['selected']:#.4g}.", ""]
    else:
        lines += ["No term of the dictionary is singled out.", ""]
    lines += [f"Stopped: {found.stop}.", "", "| step | term | score z | LR | LR p |", "|---|---|---|---|---|"]
    for k, step in enumerate(found.steps, start=1):
        for r in step["tried"]:
            lines.append(f"| {k} | {r['parameter']} | {r['score_z']:+.2f} | {r['lr']:.1f} | "
                         f"{r['lr_p']:.2g} |")
    lines += ["", f"Rule: {RULE}.", ""]
    return lines


def _next_walk_markdown(further: dict) -> list[str]:
    """The report's section on the further walk that would break a tie."""
    names = " and ".join(further["tied"])
    lines = ["## Which further walk would tell them apart", ""]
    if "reason" in further:
        return lines + [f"{names} are tied; the further walks could not be weighed: "
                        f"{further['reason']}.", ""]
    lines += [f"{names} are tied. Weighed by {further['method']}. Gap: the hidden "
              f"cause's likelihood ratio less its nearest rival's (the rule asks for {SEPARATION:.1f}), "
              "the least over the tied causes; named: the least share of noise draws in which the "
              "rule names the hidden cause.", "",
              "| further walk | change | its gait's max abs eigenvalue | gap (nearest rival) | named |",
              "|---|---|---|---|---|"]
    same = further["same_again"]
    lines.append(f"| the (first) walk again | none | | {_gap_cell(same)} | {same['named_rate']:.0%} |")
    for r in further["conditions"]:
        change = f"{r['parameter']} {r['from']:.4g} -> {r['to']:.4g}"
        if "reason" in r:
            lines.append(f"| {r['label']} | {change} | | not weighed: {r['reason']} | |")
            continue
        lines.append(f"| {r['label']} | {change} | {r['max_abs_eigenvalue']:.3f}"
                     f"{'' if r['stable'] else ' (unstable)'} | {_gap_cell(r)} | {r['named_rate']:.0%} |")
    lines += ["", (f"Suggested: a further walk with {further['suggestion']}, analysed with these "
                   "(`toywalk diagnose THIS.csv ... NEXT.csv --params THIS.toml ... --params NEXT.toml`)."
                   if further["suggestion"] else
                   "None of these walks would tell them apart; a measurement of the candidates "
                   "themselves (the hinge's friction, the foot's grip) would."), ""]
    return lines


def _gap_cell(row: dict) -> str:
    worst = min(row["results"], key=lambda r: r["gap"])
    return f"{worst['gap']:.1f} ({worst['hidden']} against {worst['nearest']})"


def write_summary_diagnosis(diagnosis, folder: Path, inputs: dict | None = None) -> list[Path]:
    """The report of :func:`toywalk.sysid.summary.diagnose_summary`: report.json, report.md and
    ``numbers.png`` (each measured number's misfit in SDs: the base model, the best candidate and
    the best pair)."""
    return _write_report(Path(folder), diagnosis, inputs, _summary_markdown(diagnosis),
                         lambda f: [numbers_figure(diagnosis, f / "numbers.png")])


def _summary_models(d) -> list[tuple[str, object]]:
    """(label, SummaryFit): the base, the best single candidate and the best pair."""
    models = [("base", d.base)]
    fitted = [r for r in d.ranking if "chi2" in r]
    if fitted:
        models.append((fitted[0]["effect"], d.fits[fitted[0]["effect"]]))
    if d.pairs:
        key = "+".join(d.pairs[0]["pair"])
        models.append((key.replace("+", " + "), d.fits[key]))
    return models


def numbers_figure(d, path: Path) -> Path:
    """Each measured number's misfit in SDs (the base, the best candidate, the best pair) of a
    :class:`toywalk.sysid.summary.SummaryDiagnosis`, written to ``path``."""
    from matplotlib.figure import Figure

    names = list(d.base.residuals)
    models = _summary_models(d)
    fig = Figure(figsize=(11, 0.5 * len(names) + 1.5))
    ax = fig.subplots()
    y = np.arange(len(names))[::-1]
    height = 0.8 / len(models)
    for i, (label, fit) in enumerate(models):
        vals = [fit.residuals[n] for n in names]
        ax.barh(y + 0.4 - (i + 0.5) * height, vals, height=height, color=f"C{i}",
                label=f"{label} (chi-square {fit.chi2:.1f})")
    ax.axvline(0.0, color="k", lw=0.8)
    for s in (-2, 2):
        ax.axvline(s, color="k", ls=":", lw=0.8)
    ax.set_xscale("symlog", linthresh=2)
    reach = max([2.0] + [abs(f.residuals[n]) for _, f in models for n in names])
    ticks = [t for t in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000) if t <= 1.5 * reach]
    ax.set_xticks([-t for t in ticks[::-1]] + [0] + ticks,
                  [f"{-t:g}" for t in ticks[::-1]] + ["0"] + [f"{t:g}" for t in ticks], fontsize=7)
    ax.set_yticks(y, names, fontsize=8)
    ax.set_xlabel("(model - measured) / SD, symmetric log scale; dotted: 2 SD")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _finish(fig, Path(path))


def _in_report_units(value: float, unit: str) -> str:
    """A feature's value as report.md's tables give angles: degrees (the RMS tables' unit)."""
    if unit == "rad":
        return f"{math.degrees(value):.4g} deg"
    return f"{value:.4g} {unit}"


def _shared_words(d: Diagnosis) -> str:
    """report.md's sentence on errors the samples share by phase (a tracker's, carried by
    ``track --accuracy``): how much they widen the standard errors and intervals; empty without."""
    widened = {**d.base.shared_widening,
               **{r["effect"]: r["shared_widening"] for r in d.ranking if r.get("shared_widening")}}
    effects = sorted(((r["design_effect"], r["effect"]) for r in d.ranking
                      if r.get("design_effect", 1.0) > 1.01), reverse=True)
    if not widened and not effects:
        return ""
    words = " The file carries errors shared by each phase of the step (`*_phase_sd`)"
    if widened:
        words += (": every standard error and interval includes them, which widens them (" +
                  ", ".join(f"{n} x{f:.2g}" for n, f in widened.items()) + ")")
    if effects:
        words += ("; each candidate's score statistic and likelihood ratio are divided by its design effect, "
                  "what those errors add to chance (largest " +
                  ", ".join(f"{n} {f:.3g}" for f, n in effects[:3]) + ")")
    return words + "."


def _model_words(model: str) -> str:
    """How report.md names the fit's model of the walk."""
    return {"periodic": "periodic (the walk on the model's limit cycle)",
            "transient": "transient (a free start, the walk converging to or leaving the cycle)",
            }.get(model, model)


def verdict_lines(d) -> list[str]:
    """The head of every analysis's report.md: the verdict, the cause, and whether the model with
    it explains the data (the effective description of a ``partly explained`` verdict, which is
    not a named cause), then the evidence."""
    lines = [f"**Verdict:** {d.verdict}. **Cause:** {d.cause if d.cause is not None else 'none'}"
             + (f" (both: {', '.join(d.causes)})" if len(d.causes) > 1 else "") + ".", ""]
    e = d.effective
    if e:
        who = " + ".join(e["candidates"])
        if e["explains"]:
            lines += [f"The model with {who} explains the data: " + explanation_line(e) + ".", ""]
        else:
            lines += [f"**Partly explained.** {who} is an effective description, not a named cause: it "
                      "may stand in for physics the library lacks. It leaves " + "; ".join(e["shortfalls"])
                      + ". " + explanation_line(e) + ".", ""]
    return lines + [f"Evidence: {d.evidence}.", ""]


def explanation_line(e: dict) -> str:
    """What a model leaves, in words: its share of the base model's excess misfit and each
    signal's held-out RMS in noise SDs against the rule's limit (``Verdict.effective``)."""
    parts = []
    if e.get("share_of_excess_misfit") is not None and math.isfinite(e["share_of_excess_misfit"]):
        parts.append(f"{percent(e['share_of_excess_misfit'])} of the base model's excess misfit removed")
    if e["limit"]:
        parts.append("held-out RMS in noise SDs (limit): " + ", ".join(
            f"{k} {v:.2f} ({e['limit'][k]:.2f})" for k, v in e["remaining_in_noise_sd"].items()))
    elif e["remaining_in_noise_sd"]:
        parts.append("residuals in SDs: " + ", ".join(f"{k} {v:+.2f}"
                                                      for k, v in e["remaining_in_noise_sd"].items()))
    if e["not_judged"]:
        parts.append("not judged: " + "; ".join(f"{k} ({v})" for k, v in e["not_judged"].items()))
    return "; ".join(parts) or "no held-out prediction"


def _num(v, fmt=".3g") -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def _summary_markdown(d) -> str:
    data = d.data
    lines = ["# Discrepancy analysis from summary statistics", "",
             *verdict_lines(d),
             f"Rule: {d.rule} (alpha = {d.alpha:g}, K = {len(d.ranking)} candidates).", "",
             "## The numbers", "",
             "| quantity | measured | SD | base model | (model - measured) / SD |",
             "| --- | --- | --- | --- | --- |"]
    for k, (v, s) in list(data.targets.items()) + list(data.priors.items()):
        model = d.base.features.get(k, d.base.estimates.get(k))
        lines.append(f"| {k} | {v:.4g} | {s:.3g} | {_num(model, '.4g')} | "
                     f"{d.base.residuals[k]:+.2f} |")
    lines += ["", f"Measured: stable = {data.stable}, can stand = {data.can_stand}. Base model: "
              f"max |eigenvalue| per step {d.base.max_abs_eigenvalue:#.4g} "
              f"({'stable' if d.base.stable else 'unstable'}), can stand = {d.base.can_stand}. "
              f"Not used: {', '.join(data.unused) or 'none'}.", "", "![numbers](numbers.png)", ""]
    if d.ranking:
        lines += ["## Candidates", "",
                  "Each freed in turn with the measured parameters; effects bounded to "
                  "physical magnitudes. `alignment`: cosine between the candidate's effect on the "
                  "numbers and the base's misfit (1: it moves them straight towards the "
                  "measurement).", "",
                  "| candidate | chi-square | dof | LR p | estimate | 95 % interval | reaches | "
                  "max abs eig / step | can stand | alignment |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in d.ranking:
            name = r["effect"]
            est = r.get("estimate", {}).get(name)
            iv = r.get("interval", {}).get(name, [math.nan, math.nan])
            lines.append(f"| {name} | {_num(r.get('chi2'), '.2f')} | {r.get('dof', '-')} | "
                         f"{_num(r.get('lr_p'), '.2g')} | {_num(est, '.4g')} | "
                         f"[{_num(iv[0], '.3g')}, {_num(iv[1], '.3g')}] | {r.get('reaches', '-')} | "
                         f"{_num(r.get('max_abs_eigenvalue'), '.4g')} | {r.get('can_stand', '-')} | "
                         f"{_num(r.get('alignment'), '+.2f')} |")
    if d.pairs:
        lines += ["", "## Pairs", "",
                  "| pair | chi-square | dof | estimates | adds to each (p) | max abs eig / step |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for p in d.pairs:
            est = ", ".join(f"{k} = {v:.4g}" for k, v in p["estimate"].items())
            lines.append(f"| {' + '.join(p['pair'])} | {p['chi2']:.2f} | {p['dof']} | {est} | "
                         f"{', '.join(_num(a, '.2g') for a in p['adds_p'])} | "
                         f"{p['max_abs_eigenvalue']:#.4g} |")
    s = d.sensitivity
    if s:
        lines += ["", "## What these numbers can identify", "",
                  f"Singular values of the candidates' sensitivity matrix (the numbers' change in "
                  "SDs per unit: an effect's typical magnitude, a tenth of a leg length, or the file's "
                  f"value): {', '.join(f'{v:.3g}' for v in s['singular_values'])}"
                  f"; {len(s['targets'])} numbers span at most {len(s['targets'])} directions."]
        if s["parallel"]:
            lines.append("Candidates these numbers cannot tell apart (cosine of their "
                         "sensitivities): " + "; ".join(f"{a} and {b} ({c:+.4f})"
                                                        for a, b, c in s["parallel"]) + ".")
        if s["no_gait"]:
            lines.append("No gait a small step from the base for: " + ", ".join(s["no_gait"]) + ".")
    lines += ["", f"Time: {d.seconds.get('total', math.nan):.0f} s.", ""]
    return "\n".join(lines)


def write_walks_diagnosis(diagnosis, folder: Path, inputs: dict | None = None) -> list[Path]:
    """The report of :func:`toywalk.sysid.walks.diagnose_walks` (several walks analysed together):
    report.json, report.md, ``candidates.png`` (each candidate's score statistic and likelihood
    ratio, all walks together) and ``residuals_by_phase.png`` (each walk's residuals by phase of
    the step, base and named cause)."""
    return _write_report(Path(folder), diagnosis, inputs, _walks_markdown(diagnosis),
                         lambda f: [_walks_candidate_figure(diagnosis, f)]
                         + ([_walks_phase_figure(diagnosis, f)] if diagnosis.residuals else []))


def _walks_phase_figure(d, folder: Path) -> Path:
    from matplotlib.figure import Figure

    names = list(d.residuals[0].phase_mean)
    n = len(d.residuals)
    fig = Figure(figsize=(3.2 * n + 1, 1.9 * len(names) + 0.8))
    axes = fig.subplots(len(names), n, sharex=True, squeeze=False)
    for j, base in enumerate(d.residuals):
        reports = [("base", base, "C0")]
        if d.residuals_extended is not None:
            # a picked cause that still left a pattern is unexplained (the evidence names it)
            reports.append((d.causes[0] if d.causes else "picked cause, unexplained",
                            d.residuals_extended[j], "C3"))
        for i, name in enumerate(names):
            _phase_panel(axes[i, j], name, reports)
        axes[0, j].set_title(f"walk {j + 1}", fontsize=9)
    for i, name in enumerate(names):
        axes[i, 0].set_ylabel(f"{name}\n(deg)", fontsize=8)
    fig.supxlabel(_PHASE_XLABEL, fontsize=8)
    return _finish(fig, folder / "residuals_by_phase.png")


def _walks_candidate_figure(d, folder: Path) -> Path:
    return candidates_plot(d.ranking, d.alpha, "likelihood ratio (fitted, all walks)",
                           folder / "candidates.png")


def _walks_markdown(d) -> str:
    lines = [f"# Discrepancy analysis of {len(d.base.walks)} walks together", "",
             *verdict_lines(d),
             f"Rule: {d.rule} (alpha = {d.alpha:g}, K = {len(d.ranking)} candidates).", "",
             "## The walks (base fit)", "",
             f"Model: {_model_words(d.base.walks[0].model)}, used by every fit of the analysis.", "",
             "| walk | chi-square | residuals | noise (rad) | noise from | max abs eigenvalue | "
             "pattern repeated every step |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for k, w in enumerate(d.base.walks, start=1):
        noise = ", ".join(f"{n} {v:.3g}" for n, v in w.noise_sd.items())
        pattern = ", ".join(d.residuals[k - 1].systematic) or "none" if d.residuals else "-"
        lines.append(f"| {k} | {w.chi2:.1f} | {w.n_residuals} | {noise} | {w.noise_source} | "
                     f"{_num(w.gait.get('max_abs_eigenvalue'), '.4g')} | {pattern} |")
    lines += ["", f"Base: chi-square {d.base.chi2:.1f} on {d.base.n_residuals} residuals "
              f"({d.base.status}); shared changes: "
              + (", ".join(f"{n} {d.base.change[n]:+.4g} +- {d.base.std[n]:.2g}" for n in d.base.free)
                 or "none") + ".", "",
              "![residuals by phase](residuals_by_phase.png)", ""]
    held = d.gain.get("held_out")
    if held:
        by_base, by_ext = held["by_walk"]["base"], held["by_walk"]["extended"]
        # a fold that failed leaves its model no per-walk chi-squares
        pairs = zip(by_base, by_ext, strict=True) if len(by_base) == len(by_ext) else ()
        walks = ", ".join(f"walk {i + 1} {b:.1f} to {e:.1f}" for i, (b, e) in enumerate(pairs))
        lines += [f"Held-out prediction by stride (alternate strides of every walk in two folds, the "
                  f"walks fitted together on each): chi-square {_num(held['base'], '.1f')} for the base, "
                  f"{_num(held['extended'], '.1f')} with {held['candidate']}"
                  + (f" ({walks})" if walks else "") + ".", ""]
    if d.features:
        n = len(d.features)
        after = d.features_extended
        lines += ["## Gait features", "",
                  "Each walk's misfit of each gait feature in standard errors (measured minus model; "
                  + ("base / the picked cause" if after else "base") + ").", "",
                  "| feature | " + " | ".join(f"walk {k + 1}" for k in range(n)) + " |",
                  "| --- |" + " --- |" * n]
        for key in d.features[0]:
            cells = [_num(f[key].get("z"), "+.1f")
                     + (f" / {_num(after[k][key].get('z'), '+.1f')}" if after else "")
                     for k, f in enumerate(d.features)]
            lines.append(f"| {key} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Candidates", "", "![candidates](candidates.png)", "",
              "| candidate | score z | likelihood ratio | p | estimate | 95 % interval |",
              "| --- | --- | --- | --- | --- | --- |"]
    for r in d.ranking:
        name = r["effect"]
        est = r.get("estimate", {}).get(name)
        low, high = r.get("interval", {}).get(name, (None, None))
        lines.append(f"| {name} | {_num(r.get('score_z'), '+.2f')} | {_num(r.get('lr'), '.1f')} | "
                     f"{_num(r.get('lr_p'), '.2g')} | {_num(est, '.4g')} | "
                     + (f"[{low:.4g}, {high:.4g}]" if low is not None else "-") + " |")
    lines.append("")
    if d.next_walk:
        lines += _next_walk_markdown(d.next_walk)
    return "\n".join(lines)
