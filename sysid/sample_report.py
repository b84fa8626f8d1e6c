"""Figures and a summary page of a sampling run (``toywalk sample --report DIR``), and the
posterior predictive checks they show: the sampler's report, as :mod:`toywalk.sysid.diagnosis_report`
is the diagnosis's.

Trace plots (every walker of every ensemble), a corner plot of the kept draws (after burn-in,
thinned by half an autocorrelation time; ``corner``), the posterior of the gait's max |eigenvalue|
with the stability line, the stride-to-stride return map estimated from the measured strides
beside it (:mod:`toywalk.sysid.returnmap`: the model's stability against the data's, without the
model), and ``report.md`` with the diagnostics table, headed by the misfit the intervals ignore
(:func:`misfit_notes`: the fit's warnings, the failing posterior predictive checks). Every file is
written under a temporary name and renamed into place.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_figure, atomic_write_json, atomic_write_text

__all__ = ["CHECKED_FEATURES", "MISFIT_SDS", "PREDICTIVE_DRAWS", "misfit_notes", "predictive_checks",
           "write_report"]


def _chains(path: Path, ensembles: int):
    import emcee

    out = []
    for e in range(ensembles):
        b = emcee.backends.HDFBackend(str(path), name=f"ensemble_{e}", read_only=True)
        out.append((b.get_chain(), b.get_blobs()))
    return out


#: Posterior draws behind the predictive bands and checks (a p-value is then known to 1/40).
PREDICTIVE_DRAWS = 40
#: The statistics of the posterior predictive checks (:func:`predictive_checks`): the gait
#: features of the angles (:func:`toywalk.sysid.residuals.step_features`), averaged over the steps.
CHECKED_FEATURES = ("lean_range", "steer_range", "steer_mean", "stance_pitch_range", "swing_pitch_range")


#: A posterior predictive check fails (:func:`misfit_notes`) when the measured statistic lies more
#: than this many SDs of its replicates from their mean. Under the model a statistic of many samples
#: is about normal: 4 SDs two-sided is 6e-5 a check, and 40 draws estimate the SD to about 11 %,
#: so the line is at least 3.5 true SDs (5e-4 a check, 3e-3 over the six). p itself cannot serve:
#: with 40 draws it is 0 (no replicate as extreme) for 5 % of a two-sided check's walks by chance
#: (tests/sysid/test_predictive.py).
MISFIT_SDS = 4.0


def predictive_checks(post, draws: np.ndarray, rng, n_draws: int = PREDICTIVE_DRAWS) -> dict:
    """Posterior predictive checks (Gelman, Meng & Stern 1996, Statistica Sinica 6:733): for each of
    ``n_draws`` posterior draws, the model's angles at the observations (offsets and time offset at
    their best values, as the likelihood profiles them) and a replicated walk, those angles plus
    noise of the likelihood's SDs; a statistic of the measured walk is then compared with its
    replicates.

    - ``chi2``: the realised discrepancy, sum of squared standardised residuals of the measured
      walk against the draw's model, beside that of the replicate; ``p`` = share of draws whose
      replicate's is at least as large (small: the measured walk is further from the model than
      its noise explains).
    - each of :data:`CHECKED_FEATURES`, averaged over the steps; ``p`` two-sided: twice the
      smaller share of replicates on either side of the measured value.

    Returns
    -------
    dict
        ``draws`` (used; a draw with no gait is skipped), ``low``, ``middle``, ``high`` (5, 50 and
        95 % of the model's angles, per observation), and ``checks``: per statistic ``measured``,
        ``replicated`` (list, one per draw; for chi2 the measured walk's discrepancy per draw),
        ``p`` (NaN for a feature no step has enough samples to measure).
    """
    from .residuals import finite_mean, step_features

    obs, sigma = post.obs, np.asarray(post.sigma, float)[:len(post.obs.value)]
    curves = []
    for theta in draws[rng.choice(len(draws), size=min(n_draws, len(draws)), replace=False)]:
        gait, walker = post.gait(theta)
        if gait is None:
            continue
        curves.append(post.profile(gait, walker)[2][:len(obs.value)])
    curves = np.array(curves)
    if not len(curves):
        return {"draws": 0, "low": None, "middle": None, "high": None, "checks": {}}
    measured = {k: finite_mean(v) for k, v in step_features(obs, obs.value).items() if k in CHECKED_FEATURES}
    chi_obs, chi_rep, features = [], [], {k: [] for k in CHECKED_FEATURES}
    for curve in curves:
        rep = curve + sigma * rng.standard_normal(len(curve))
        chi_obs.append(float(np.sum(((obs.value - curve) / sigma) ** 2)))
        chi_rep.append(float(np.sum(((rep - curve) / sigma) ** 2)))
        for k, v in step_features(obs, rep).items():
            if k in features:
                features[k].append(finite_mean(v))
    chi_obs, chi_rep = np.array(chi_obs), np.array(chi_rep)
    checks = {"chi2": {"measured": chi_obs.tolist(), "replicated": chi_rep.tolist(),
                       "p": float(np.mean(chi_rep >= chi_obs))}}
    for k, reps in features.items():
        reps = np.array(reps)
        if not np.isfinite(measured[k]) or not np.all(np.isfinite(reps)):
            # too few samples in every step to measure the feature (step_features)
            checks[k] = {"measured": measured[k], "replicated": reps.tolist(), "p": math.nan}
            continue
        above, below = np.mean(reps >= measured[k]), np.mean(reps <= measured[k])
        checks[k] = {"measured": measured[k], "replicated": reps.tolist(),
                     "p": float(min(1.0, 2.0 * min(above, below)))}
    low, middle, high = np.percentile(curves, [5, 50, 95], axis=0)
    return {"draws": len(curves), "low": low, "middle": middle, "high": high, "checks": checks}


def _off_by(check: dict) -> float:
    """How far the measured statistic lies from its replicates' mean, in their SDs (signed; NaN
    when it is not measured or the replicates do not vary)."""
    reps = np.asarray(check["replicated"], float)
    measured = float(np.median(check["measured"]))  # chi-square: the measured walk's, per draw
    spread = float(np.std(reps, ddof=1)) if len(reps) > 1 else math.nan
    if not (math.isfinite(measured) and np.all(np.isfinite(reps)) and spread > 0):
        return math.nan
    return (measured - float(np.mean(reps))) / spread


def misfit_notes(fit_warnings=(), predictive: dict | None = None) -> list[str]:
    """What a posterior's reader must know before its intervals: one sentence each (lower case,
    no full stop) for every warning of the fit it starts from, and one naming the posterior
    predictive checks that fail (the measured statistic over :data:`MISFIT_SDS` SDs of its
    replicates from their mean), each with how far and its p. [] when there is nothing to say.

    ``predictive``: the result of :func:`predictive_checks` (None: not checked)."""
    notes = [f"the fit it starts from warns: {w}" for w in fit_warnings]
    failed = {}
    for name, check in ((predictive or {}).get("checks") or {}).items():
        off = _off_by(check)
        if math.isfinite(off) and abs(off) > MISFIT_SDS:
            failed["chi-square" if name == "chi2" else name] = (off, check["p"])
    if failed:
        same_p = len({f"{p:.3f}" for _, p in failed.values()}) == 1
        items = [f"{name} {off:+.3g}" + ("" if same_p else f" (p = {p:.3f})")
                 for name, (off, p) in failed.items()]
        p_note = (f", p = {next(iter(failed.values()))[1]:.3f}{' each' if len(failed) > 1 else ''}"
                  if same_p else "")
        notes.append(
            f"posterior predictive checks fail (the measured walk's statistic in SDs of its "
            f"{predictive['draws']} replicates from their mean; a check fails beyond {MISFIT_SDS:g}): "
            f"{', '.join(items)}{p_note}: the fitted model does not make walks like the measured one, "
            "and the posterior's intervals assume it does; `toywalk diagnose` looks for what the "
            "model lacks")
    return notes


def _checks_figure(result: dict, path: Path) -> None:
    """Each checked statistic's replicates as a histogram with the measured value (chi2: the
    replicated discrepancy against the measured walk's, draw by draw)."""
    from matplotlib.figure import Figure

    checks = result["checks"]
    fig = Figure(figsize=(9, 5.5))
    axes = fig.subplots(2, 3).ravel()
    for ax, (name, c) in zip(axes, checks.items(), strict=False):
        if name == "chi2":
            ax.scatter(c["replicated"], c["measured"], s=8, color="C0")
            lim = [min(c["replicated"] + c["measured"]), max(c["replicated"] + c["measured"])]
            ax.plot(lim, lim, color="k", lw=0.8)
            ax.set_xlabel("chi-square, replicated walk", fontsize=8)
            ax.set_ylabel("chi-square, measured walk", fontsize=8)
        elif not math.isfinite(c["p"]):
            ax.text(0.5, 0.5, f"{name}:\nnot measured\n(too few samples a step)", ha="center",
                    va="center", fontsize=8, transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
        else:
            ax.hist(np.degrees(c["replicated"]), bins=15, color="0.6")
            ax.axvline(np.degrees(c["measured"]), color="r", lw=1.2)
            ax.set_xlabel(f"{name} (deg), mean over steps", fontsize=8)
        ax.set_title(f"p = {c['p']:.3f}", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(checks):]:
        ax.set_visible(False)
    fig.suptitle(f"Posterior predictive checks ({result['draws']} draws; red: measured)", fontsize=9)
    fig.tight_layout()
    atomic_write_figure(path, fig)


def write_report(chain: Path, summary: dict, folder: Path, post=None, table=None,
                 fit_warnings=()) -> list[Path]:
    """Write trace.png, corner.png, eigenvalues.png, report.md and report.json into ``folder``;
    with the log-posterior ``post``, also predictive.png (posterior predictive bands over the
    measured signals, and the measured walk less the model); with the measured walk ``table``,
    also returnmap.png (the stride map's multipliers from the measured strides against the
    posterior's). The misfit (:func:`misfit_notes`: ``fit_warnings``, the warnings of the fit the
    chain starts from, and the failing predictive checks) heads report.md, and is ``misfit`` in
    report.json."""
    # Figures built on matplotlib's object API, never pyplot: the caller's backend (a notebook's
    # inline one) is left as it is.
    import corner
    from matplotlib.figure import Figure
    from toywalk.model.parameters import parameter_unit

    folder.mkdir(parents=True, exist_ok=True)
    names = summary["names"]
    runs = _chains(Path(chain), summary["ensembles"])
    burn, thin = summary["burn_in"], summary["thin"]
    written = []

    fig = Figure(figsize=(7, 1.8 * len(names) + 0.6))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)
    for i, name in enumerate(names):
        ax = axes[i, 0]
        for e, (c, _) in enumerate(runs):
            ax.plot(c[:, :, i], color=f"C{e}", alpha=0.3, lw=0.6)
        ax.axvline(burn, color="k", ls="--", lw=0.8)
        ax.set_ylabel(name, fontsize=8)
    axes[-1, 0].set_xlabel("step (dashed: end of burn-in); colours: independent ensembles")
    fig.tight_layout()
    atomic_write_figure(folder / "trace.png", fig)
    written.append(folder / "trace.png")

    draws = np.concatenate([c[burn::thin].reshape(-1, len(names)) for c, _ in runs])
    size = 2.0 * len(names) + 0.8
    fig = corner.corner(draws, fig=Figure(figsize=(size, size)), labels=names,
                        quantiles=[0.05, 0.5, 0.95], show_titles=True, title_fmt=".3g",
                        title_kwargs={"fontsize": 8}, label_kwargs={"fontsize": 8})
    atomic_write_figure(folder / "corner.png", fig)
    written.append(folder / "corner.png")

    if post is not None:
        predictive = predictive_checks(post, draws, np.random.default_rng(0))
        _predictive_figure(post.obs, predictive, folder / "predictive.png")
        written.append(folder / "predictive.png")
        _checks_figure(predictive, folder / "checks.png")
        written.append(folder / "checks.png")

    eig = np.concatenate([b["max_abs_eigenvalue"][burn::thin].ravel() for _, b in runs])
    eig = eig[np.isfinite(eig)]
    fig = Figure(figsize=(6, 3.2))
    ax = fig.subplots()
    if len(eig):
        ax.hist(eig, bins=40, color="0.5")
    ax.axvline(1.0, color="r", lw=1)
    ax.set_xlabel("max |eigenvalue| of the gait's period map (< 1: stable)")
    ax.set_ylabel("posterior draws")
    fig.tight_layout()
    atomic_write_figure(folder / "eigenvalues.png", fig)
    written.append(folder / "eigenvalues.png")

    summary = dict(summary)
    returnmap_lines = []
    if table is not None:
        returnmap_lines = _return_map(table, eig, summary, folder)
        if (folder / "returnmap.png").exists():
            written.append(folder / "returnmap.png")

    lines = ["# Posterior of the fit's free parameters", "",
             f"{summary['ensembles']} independent ensembles of {summary['walkers']} walkers, "
             f"{summary['length']} steps each; burn-in {burn}, thinned by {thin}.",
             f"Long enough ({summary['stop_rule']}): {summary['long_enough']}.",
             f"Acceptance fractions: {', '.join(f'{a:.2f}' for a in summary['acceptance_fraction'])}.",
             f"Proposals with no gait: {100 * summary['fraction_no_gait']:.2f} %; outside the prior: "
             f"{100 * summary['fraction_outside_prior']:.2f} %.", "",
             "| parameter | unit | median | 5 % | 95 % | SD | tau | R-hat | ESS (bulk) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for n in names:
        q5, q50, q95 = summary["quantiles_5_50_95"][n]
        rhat = (summary["rhat"] or {}).get(n)
        ess = (summary["ess_bulk"] or {}).get(n)
        tau = summary["autocorrelation_time"][n]
        lines.append(f"| {n} | {parameter_unit(n)} | {q50:.6g} | {q5:.6g} | {q95:.6g} | "
                     f"{summary['std'][n]:.3g} | "
                     f"{'never moved' if tau is None else f'{tau:.1f}'} | "
                     f"{'-' if rhat is None else f'{rhat:.3f}'} | {'-' if ess is None else f'{ess:.0f}'} |")
    if summary.get("probability_stable") is not None:
        lines += ["", f"Probability that the fitted gait is stable: {summary['probability_stable']:.3f}."]
    lines += ["", "![trace](trace.png)", "", "![corner](corner.png)", "",
              "![eigenvalues](eigenvalues.png)", ""]
    if post is not None:
        lines += ["Posterior predictive bands over the measured signals:", "",
                  "![predictive](predictive.png)", "",
                  f"Posterior predictive checks ({predictive['draws']} draws, each with a replicated walk: "
                  "the model's angles plus noise of the likelihood's SDs). A small p says the measured "
                  "walk is unlike what the fitted model produces: chi-square, further from the model "
                  "than the noise explains; a feature, outside the replicates' spread.", "",
                  "| statistic | measured | replicated (5-95 %) | p |", "| --- | --- | --- | --- |"]
        for name, c in predictive["checks"].items():
            reps = np.asarray(c["replicated"])
            if name == "chi2":
                lines.append(f"| chi-square | {np.median(c['measured']):.1f} (median over draws) | "
                             f"{np.percentile(reps, 5):.1f} to {np.percentile(reps, 95):.1f} | "
                             f"{c['p']:.3f} |")
            elif not math.isfinite(c["p"]):
                lines.append(f"| {name} (deg) | not measured: too few samples a step | | |")
            else:
                lines.append(f"| {name} (deg) | {np.degrees(c['measured']):.3f} | "
                             f"{np.degrees(np.percentile(reps, 5)):.3f} to "
                             f"{np.degrees(np.percentile(reps, 95)):.3f} | {c['p']:.3f} |")
        lines += ["", "![checks](checks.png)", ""]
        summary["predictive_checks"] = {"draws": predictive["draws"],
                                        "p": {k: c["p"] for k, c in predictive["checks"].items()}}
    lines += returnmap_lines
    # The misfit first: a reader must know it before reading the intervals.
    misfit = misfit_notes(fit_warnings, predictive if post is not None else None)
    summary["misfit"] = misfit
    if misfit:
        lines[1:1] = ["", "## Misfit", "", *(f"- {note[0].upper()}{note[1:]}." for note in misfit)]
    atomic_write_text(folder / "report.md", "\n".join(lines))
    atomic_write_json(folder / "report.json", summary)
    return written + [folder / "report.md", folder / "report.json"]


def _predictive_figure(obs, predictive: dict, path: Path) -> None:
    """predictive.png: per signal, the measured angles (grey dots, under) and the model's 5-95 %
    band (orange, over them, its edges drawn so that a band narrower than a dot still shows);
    beside it the measured walk less the band's middle, where a misfit far smaller than the swing
    shows. The legend sits above the panels, off the data."""
    from matplotlib.figure import Figure
    from toywalk.model.trajectory import SIGNALS

    low, middle, high = (np.degrees(predictive[k]) for k in ("low", "middle", "high"))
    value = np.degrees(obs.value)
    fig = Figure(figsize=(11, 8))
    axes = fig.subplots(len(SIGNALS), 2, sharex=True, gridspec_kw={"width_ratios": [3, 2]})
    for s_i, (row, name) in enumerate(zip(axes, SIGNALS, strict=True)):
        sel = np.flatnonzero(obs.signal == s_i)
        order = sel[np.argsort(obs.time[sel])]
        t = obs.time[order]
        for ax, shift in ((row[0], 0.0), (row[1], middle[order])):
            ax.plot(t, value[order] - shift, ".", color="0.55", ms=2, zorder=1, label="measured")
            ax.fill_between(t, low[order] - shift, high[order] - shift, color="C1", alpha=0.5, lw=0,
                            zorder=2, label="model, 5-95 % of the posterior")
            for edge in (low, high):
                ax.plot(t, edge[order] - shift, color="C1", lw=0.8, zorder=3)
            ax.set_ylabel(f"{name} (deg)", fontsize=8)
            ax.tick_params(labelsize=7)
        row[1].axhline(0.0, color="k", lw=0.5, zorder=0)
    axes[0, 0].set_title("the walk", fontsize=9)
    axes[0, 1].set_title("measured less the model (the band's middle)", fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles[:2], labels[:2], loc="upper center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    atomic_write_figure(path, fig)


def _return_map(table, eig: np.ndarray, summary: dict, folder: Path) -> list[str]:
    """The stride map from the measured strides beside the posterior's stride multiplier; adds
    ``return_map`` to ``summary`` and returns report.md's lines."""
    from matplotlib.figure import Figure

    from .returnmap import ReturnMapError, return_map

    try:
        rm = return_map(table, rng=0)
    except ReturnMapError as err:
        summary["return_map"] = {"error": str(err)}
        return ["## The return map from the measured strides", "", f"Not estimated: {err}.", ""]
    summary["return_map"] = rm.to_json()
    # The posterior's multiplier per stride: a step-periodic gait's step map squared.
    stride = eig ** (2 / summary.get("period", 1)) if len(eig) else eig
    fig = Figure(figsize=(6.5, 3.0))
    ax = fig.subplots()
    if len(stride):  # a band: the posterior is often far narrower than the data's intervals
        low, high = np.percentile(stride, [2.5, 97.5])
        ax.axvspan(low, max(high, low + 1e-3), color="0.8")
        ax.axvline(np.median(stride), color="0.3", label="model (posterior median, 95 %)")
    right = 1.5
    for k, est in enumerate((rm.naive, rm.corrected, rm.instrumental)):
        if np.isfinite(est.max_abs_eigenvalue):
            low, high = est.max_abs_interval
            right = max(right, min(high, 3.0) + 0.1)
            ax.errorbar([est.max_abs_eigenvalue], [k + 1], xerr=[[est.max_abs_eigenvalue - low],
                        [high - est.max_abs_eigenvalue]], fmt="o", color=f"C{k}", capsize=3,
                        label=f"measured strides, {est.method}")
    ax.set_xlim(0.0, right)
    ax.set_ylim(0.3, 4.2)
    ax.axvline(1.0, color="r", lw=1)
    ax.set_xlabel("largest stride multiplier |eigenvalue| (< 1: stable)")
    ax.set_yticks([])
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    atomic_write_figure(folder / "returnmap.png", fig)
    lines = ["## The return map from the measured strides", "",
             f"{rm.n_pairs} stride pairs, {rm.rank} of {len(rm.coordinates)} section directions "
             "above the noise (sysid/returnmap.py).", "",
             "| estimate | max abs eigenvalue | 95 % interval |", "| --- | --- | --- |"]
    for est in (rm.naive, rm.corrected, rm.instrumental):
        low, high = est.max_abs_interval
        lines.append(f"| {est.method} | {est.max_abs_eigenvalue:.3f} | {low:.3f} - {high:.3f} |")
    if len(stride):
        lines.append(f"| model (posterior median) | {np.median(stride):.3f} | "
                     f"{np.percentile(stride, 2.5):.3f} - {np.percentile(stride, 97.5):.3f} |")
    lines += [""] + [f"- {w}" for w in rm.warnings] + ["", "![return map](returnmap.png)", ""]
    return lines
