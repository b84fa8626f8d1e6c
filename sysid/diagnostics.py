"""Figures and a summary page of a sampling run (``toywalk sample --report DIR``).

Trace plots (every walker of every ensemble), a corner plot of the kept draws (after burn-in,
thinned by half an autocorrelation time; ``corner``), the posterior of the gait's max |eigenvalue|
with the stability line, and ``report.md`` with the diagnostics table. Every file is written under
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
    (offsets at their best values for each draw, as the likelihood profiles them)."""
    from .likelihood import model_angles

    curves = []
    for theta in draws[rng.choice(len(draws), size=min(40, len(draws)), replace=False)]:
        gait, walker = post.gait(theta)
        if gait is None:
            continue
        angles, _ = model_angles(gait, post.obs, post.planar, walker)
        if post.offsets:
            b, weights = post._design, 1.0 / post.sigma**2
            best = (b.T @ (weights * (post.obs.value - angles))) / np.maximum(b.T @ weights, 1e-300)
            angles = angles + b @ best
        curves.append(angles)
    curves = np.array(curves)
    return np.percentile(curves, 5, axis=0), np.percentile(curves, 95, axis=0)


def write_report(chain: Path, summary: dict, folder: Path, post=None) -> list[Path]:
    """Write trace.png, corner.png, eigenvalues.png, report.md and report.json into ``folder``;
    with the log-posterior ``post``, also predictive.png (posterior predictive bands over the
    measured signals)."""
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
        rhat = summary["rhat"][n] if summary["rhat"] else float("nan")
        ess = summary["ess_bulk"][n] if summary["ess_bulk"] else float("nan")
        lines.append(f"| {n} | {q50:.6g} | {q5:.6g} | {q95:.6g} | {summary['std'][n]:.3g} | "
                     f"{summary['autocorrelation_time'][n]:.1f} | {rhat:.3f} | {ess:.0f} |")
    if summary.get("probability_stable") is not None:
        lines += ["", f"Probability that the fitted gait is stable: {summary['probability_stable']:.3f}."]
    lines += ["", "![trace](trace.png)", "", "![corner](corner.png)", "",
              "![eigenvalues](eigenvalues.png)", ""]
    if post is not None:
        lines += ["Posterior predictive bands over the measured signals:", "",
                  "![predictive](predictive.png)", ""]
    atomic_write_text(folder / "report.md", "\n".join(lines))
    atomic_write_json(folder / "report.json", summary)
    return written + [folder / "report.md", folder / "report.json"]
