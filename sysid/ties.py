"""Weighing the candidates a diagnosis leaves tied: which further walk would tell them apart.

Where the rule (:func:`toywalk.sysid.naming.decide`) leaves candidates within
:data:`toywalk.sysid.naming.SEPARATION` of each other, the one-walk and the several-walk diagnoses
(:mod:`toywalk.sysid.discrepancy`, :mod:`toywalk.sysid.walks`) ask the design
(:func:`toywalk.sysid.design.next_walk`) which further walk would separate them, and say so in
their evidence (:func:`further_walk_clause`). The design builds on the rule, not on either
diagnosis: this module joins them.
"""

from __future__ import annotations

from .design import DesignError, next_walk
from .heldout import FitPool
from .problem import FitError

__all__ = ["further_walk_clause", "weigh_ties"]


def weigh_ties(tables: list, bases: list, cands: list, close: list[dict], *, pool: FitPool,
               alpha: float, say, **fit_options) -> dict:
    """Which further walk would tell apart the candidates ``close``
    (:func:`toywalk.sysid.naming.tied`) left by the analysis of ``tables`` with base fits
    ``bases``: each hidden at its fitted change from its base value
    (:func:`toywalk.sysid.design.next_walk`); ``tied`` and ``reason`` where the walks cannot be
    weighed."""
    say(f"which further walk would tell apart {' and '.join(r['effect'] for r in close)}")
    by_name = {c.name: c for c in cands}
    hidden = {r["effect"]: r["estimate"][r["effect"]] - by_name[r["effect"]].base for r in close}
    try:
        return next_walk(tables, bases, cands, hidden, pool=pool, alpha=alpha, **fit_options)
    except (DesignError, FitError) as err:
        return {"tied": list(hidden), "reason": str(err)}


def further_walk_clause(further: dict) -> str:
    """The evidence's clause (from ``"; "``) on the further walk that would break a tie, from
    :func:`weigh_ties`'s answer ``further``: the condition suggested, with its first-order gap
    and the rate at which the rule would name the cause, or why none was suggested (the
    one-walk diagnosis, :func:`toywalk.sysid.discrepancy.diagnose`, and the several-walk one,
    :func:`toywalk.sysid.walks.diagnose_walks`)."""
    if "reason" in further:
        return f"; which further walk would tell them apart could not be weighed ({further['reason']})"
    if further["suggestion"] is None:
        return ("; no further walk weighed (a steeper or flatter ramp, the masses moved) would tell "
                "them apart")
    row = next(r for r in further["conditions"] if r["label"] == further["suggestion"])
    return (f"; a further walk with {row['label']} would tell them apart (first order: "
            f"{row['gap']:.0f} in chi-square, named in {100 * row['named_rate']:.0f} % of noise draws; "
            f"the same walk again: {further['same_again']['gap']:.1f})")
