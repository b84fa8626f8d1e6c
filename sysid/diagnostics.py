"""Figures and a summary page of a sampling run (``toywalk sample --report DIR``).

Trace plots (every walker of every ensemble), a corner plot of the kept draws (after burn-in,
thinned by half an autocorrelation time; ``corner``), the posterior of the gait's max |eigenvalue|
with the stability line, the stride-to-stride return map estimated from the measured strides
beside it (:mod:`toywalk.sysid.returnmap`: the model's stability against the data's, without the
model), and ``report.md`` with the diagnostics table. Every file is written under
a temporary name and renamed into place.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from toywalk.model.files import atomic_write_json, atomic_write_text

__all__ = ["write_report"]


def _chains(path: Path, ensembles: int):
    import emcee

    out = []
    for e in range(ensembles):
        b = emcee.backends.HDFBackend(str(path), name=f"ensemble_{e}", read_only=True)
        out.append((b.get_chain(), b.get_blobs()))
    return out


def _save(fig, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp.png")
    try:
        fig.savefig(tmp, dpi=110)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _predictive(post, draws: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """5 and 95 % quantiles of the model's angle at every observation over posterior draws
    (offsets and time offset at their best values for each draw, as the likelihood profiles
    them)."""
    curves = []
    for theta in draws[rng.choice(len(draws), size=min(40, len(draws)), replace=False)]:
        gait, walker = post.gait(theta)
        if gait is None:
            continue
        curves.append(post.profile(gait, walker)[2])
    curves = np.array(curves)
    return np.percentile(curves, 5, axis=0), np.percentile(curves, 95, axis=0)


def write_report(chain: Path, summary: dict, folder: Path, post=None, table=None) -> list[Path]:
    """Write trace.png, corner.png, eigenvalues.png, report.md and report.json into ``folder``;
    with the log-posterior ``post``, also predictive.png (posterior predictive bands over the
    measured signals); with the measured walk ``table``, also returnmap.png (the stride map's
    multipliers from the measured strides against the posterior's)."""
    # Figures built on matplotlib's object API, never pyplot: the caller's backend (a notebook's
    # inline one) is left as it is.
    import corner
    from matplotlib.figure import Figure

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
    _save(fig, folder / "trace.png")
    written.append(folder / "trace.png")

    draws = np.concatenate([c[burn::thin].reshape(-1, len(names)) for c, _ in runs])
    size = 2.0 * len(names) + 0.8
    fig = corner.corner(draws, fig=Figure(figsize=(size, size)), labels=names,
                        quantiles=[0.05, 0.5, 0.95], show_titles=True, title_fmt=".3g",
                        title_kwargs={"fontsize": 8}, label_kwargs={"fontsize": 8})
    _save(fig, folder / "corner.png")
    written.append(folder / "corner.png")

    if post is not None:
        from toywalk.model.trajectory import SIGNALS

        low, high = _predictive(post, draws, np.random.default_rng(0))
        obs = post.obs
        fig = Figure(figsize=(8, 8))
        axes = fig.subplots(len(SIGNALS), 1, sharex=True)
        for s_i, (ax, name) in enumerate(zip(axes, SIGNALS, strict=True)):
            sel = np.flatnonzero(obs.signal == s_i)
            order = sel[np.argsort(obs.time[sel])]
            ax.fill_between(obs.time[order], np.degrees(low[order]), np.degrees(high[order]),
                            color="C0", alpha=0.35, lw=0, label="model, 5-95 % of the posterior")
            ax.plot(obs.time[order], np.degrees(obs.value[order]), ".", color="k", ms=2,
                    label="measured")
            ax.set_ylabel(f"{name} (deg)", fontsize=8)
        axes[0].legend(fontsize=7, loc="upper right")
        axes[-1].set_xlabel("time (s)")
        fig.tight_layout()
        _save(fig, folder / "predictive.png")
        written.append(folder / "predictive.png")

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
    _save(fig, folder / "eigenvalues.png")
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
             "| parameter | median | 5 % | 95 % | SD | tau | R-hat | ESS (bulk) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for n in names:
        q5, q50, q95 = summary["quantiles_5_50_95"][n]
        rhat = (summary["rhat"] or {}).get(n)
        ess = (summary["ess_bulk"] or {}).get(n)
        tau = summary["autocorrelation_time"][n]
        lines.append(f"| {n} | {q50:.6g} | {q5:.6g} | {q95:.6g} | {summary['std'][n]:.3g} | "
                     f"{'never moved' if tau is None else f'{tau:.1f}'} | "
                     f"{'-' if rhat is None else f'{rhat:.3f}'} | {'-' if ess is None else f'{ess:.0f}'} |")
    if summary.get("probability_stable") is not None:
        lines += ["", f"Probability that the fitted gait is stable: {summary['probability_stable']:.3f}."]
    lines += ["", "![trace](trace.png)", "", "![corner](corner.png)", "",
              "![eigenvalues](eigenvalues.png)", ""]
    if post is not None:
        lines += ["Posterior predictive bands over the measured signals:", "",
                  "![predictive](predictive.png)", ""]
    lines += returnmap_lines
    atomic_write_text(folder / "report.md", "\n".join(lines))
    atomic_write_json(folder / "report.json", summary)
    return written + [folder / "report.md", folder / "report.json"]


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
    _save(fig, folder / "returnmap.png")
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
