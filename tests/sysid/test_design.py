"""First-order separation of candidate causes by one or more walks (toywalk.sysid.design): against
a slow, obvious least-squares reference on synthetic columns, and against nonlinear fits of a
walk of the stable toy."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.design import DesignError, WalkColumns, separation, walk_columns
from toywalk.sysid.fit import fit
from toywalk.sysid.naming import ALPHA, SEPARATION, Candidate, candidates, lr_p_value

from ..conftest import DATA
from .builders import simulated_walk

NAMES = ["free", "a", "b", "c"]


def _candidate(name: str, side: int) -> Candidate:
    return Candidate(name, "effect", 0.0, (0.0, 1.0) if side else (-1.0, 1.0), side, 1.0, False)


def _columns(rng, rows: int, b_like_a: float) -> WalkColumns:
    """Random whitened columns: one free parameter, candidates a, b (``b_like_a`` of it along a)
    and c, two nuisances."""
    free, a, c, other = rng.normal(size=(4, rows))
    b = b_like_a * a + (1.0 - b_like_a) * other
    return WalkColumns(np.c_[free, a, b, c], rng.normal(size=(rows, 2)), NAMES, 1)


def _lr_by_refit(walks, name: str, data: np.ndarray) -> float:
    """The reference: chi-square of the base (free + each walk's nuisances) less that of the base
    with candidate ``name`` freed, by two least-squares fits of the stacked design."""
    rows = sum(len(w.shared) for w in walks)
    blocks, r0 = [], 0
    for w in walks:
        block = np.zeros((rows, w.nuisance.shape[1]))
        block[r0:r0 + len(w.shared)] = w.nuisance
        blocks.append(block)
        r0 += len(w.shared)
    base = np.hstack([np.vstack([w.shared[:, :1] for w in walks]), *blocks])
    extended = np.hstack([base, np.vstack([w.shared[:, [NAMES.index(name)]] for w in walks])])

    def rss(design):
        coef = np.linalg.lstsq(design, data, rcond=None)[0]
        return float(np.sum((data - design @ coef) ** 2)), coef

    chi_base, _ = rss(base)
    chi_ext, coef = rss(extended)
    return chi_base - chi_ext, float(coef[-1])


def test_separation_equals_refits_of_the_stacked_design():
    """Without noise, each candidate's likelihood ratio is the drop in chi-square of refitting the
    stacked design with it freed (the walks' nuisances each in their own rows); a candidate held
    on its bound gets none when its fit would leave the bound; the gap to a near-copy of the
    hidden column is small, and a second walk where the two differ widens it."""
    rng = np.random.default_rng(3)
    one = [_columns(rng, 60, 0.97)]
    two = one + [_columns(rng, 60, 0.0)]
    cands = [_candidate("a", 1), _candidate("b", 0), _candidate("c", 1)]
    for walks in (one, two):
        change = 0.4
        data = np.vstack([w.shared[:, [1]] for w in walks]).ravel() * change
        row = separation(walks, cands, {"a": change}, draws=10, rng=0)[0]
        lr_a, est_a = _lr_by_refit(walks, "a", data)
        assert_allclose(row["lr"], lr_a, rtol=1e-9)
        assert est_a == pytest.approx(change)
        for name in ("b", "c"):
            lr, est = _lr_by_refit(walks, name, data)
            # a bounded candidate (c: null on its lower bound) that would need a negative value
            # explains nothing, as its one-sided test says
            expected = 0.0 if (name == "c" and est < 0) else lr
            assert_allclose(row["gaps"][name], lr_a - expected, rtol=1e-9, atol=1e-9)
    gap_one = separation(one, cands, {"a": 0.4}, draws=10)[0]["gaps"]["b"]
    gap_two = separation(two, cands, {"a": 0.4}, draws=10)[0]["gaps"]["b"]
    assert gap_one < 0.1 * gap_two  # the second walk sees b along another direction


def test_named_rate_is_the_rules_share_of_noisy_refits():
    """The rate at which the rule names the hidden cause equals that of slow refits of noisy data,
    draw by draw (the same noise: the reference draws in the full space, the module in the
    candidates' span; so compared in distribution, 400 draws each, binomial SD 0.025)."""
    rng = np.random.default_rng(5)
    walks = [_columns(rng, 40, 0.9)]
    cands = [_candidate("a", 1), _candidate("b", 1), _candidate("c", 1)]
    change = 5.0  # expected gap to b 9.8, the rule's margin 9.2: the noise decides
    fast = separation(walks, cands, {"a": change}, draws=4000, rng=1)[0]
    gen = np.random.default_rng(2)
    clean = walks[0].shared[:, 1] * change
    named = 0
    for _ in range(400):
        data = clean + gen.standard_normal(len(clean))
        lr = {}
        for name in ("a", "b", "c"):
            value, est = _lr_by_refit(walks, name, data)
            lr[name] = 0.0 if est < 0 else value
        # significance at alpha / K (one-sided) and the rule's margin
        named += lr_p_value(lr["a"], True) < ALPHA / 3 and lr["a"] - max(lr["b"], lr["c"]) >= SEPARATION
    assert 0.1 < fast["named_rate"] < 0.9  # a case the noise decides, so the rate can disagree
    # 4 binomial SDs of the reference's 400 draws (at most 0.025 each)
    assert abs(named / 400 - fast["named_rate"]) < 0.1


def test_bad_walks_are_refused():
    rng = np.random.default_rng(0)
    w = _columns(rng, 20, 0.5)
    with pytest.raises(DesignError, match="no walks"):
        separation([], [_candidate("a", 1)], {"a": 1.0})
    with pytest.raises(DesignError, match="not among"):
        separation([w], [_candidate("d", 1)], {"a": 1.0})
    other = WalkColumns(w.shared, w.nuisance, ["free", "a", "c", "b"], 1)
    with pytest.raises(DesignError, match="same free parameters"):
        separation([w, other], [_candidate("a", 1)], {"a": 1.0})


SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
FREE = ["foot_radius", "com_offset[1]"]
NOISE = 0.002  # rad, the validation walks' (docs/make_diagnose_validation.py)
#: Hip damping at 3 noise SDs beyond the base (docs/diagnose_effects.csv)
DAMPING = 4.961e-05


def _noise_free(params) -> TrajectoryTable:
    return simulated_walk(params, 12, 0.0, 0)[0]


@pytest.mark.slow
def test_first_order_gaps_agree_with_fits_and_a_second_slope_breaks_a_tie():
    """The stable toy's 12-step walk with hip damping hidden (docs/diagnosis.md, "Which second
    walk breaks the ties"): the first-order likelihood ratios, taken on the base toy's own walk
    before any filming, against nonlinear fits of the walk with the damper, noise-free (the
    expected statistic); then a second walk at 0.8 of the slope separates dry from viscous
    friction, which one walk leaves tied."""
    toy = load_params(DATA / "params" / "stable-toy.toml")
    noise = dict.fromkeys(SIGNALS, NOISE)
    rivals = ["effects.hip_damping", "effects.pivot_friction", "effects.hip_coulomb", "slope"]
    cands = [c for c in candidates(toy, FREE) if c.name in rivals]
    own = walk_columns(_noise_free(toy), toy, FREE, rivals, model="periodic", noise_sd=noise)
    predicted = separation([own], cands, {"effects.hip_damping": DAMPING}, draws=10)[0]
    table = _noise_free(toy.replace(**{"effects.hip_damping": DAMPING}))
    base = fit(table, toy, FREE, model="periodic", noise_sd=noise, check_jacobian=False)
    lr = {}
    for name in rivals:
        ext = fit(table, base.params, FREE + [name], model="periodic", noise_sd=noise,
                  check_jacobian=False, warm=base)
        assert ext.success, name
        lr[name] = base.chi2 - ext.chi2
    # The damper's own ratio: measured 1019.7 fitted, 965.2 first order (its effect on the gait is
    # not quite linear in its strength at 3 SDs)
    assert predicted["lr"] == pytest.approx(lr["effects.hip_damping"], rel=0.1)
    for name in rivals[1:]:
        # The gaps are differences of ratios near 1000 whose second-order parts nearly cancel:
        # measured 1.20, 0.93, 2.74 fitted against 1.3, 1.1, 2.6 first order
        assert predicted["gaps"][name] == pytest.approx(lr["effects.hip_damping"] - lr[name], abs=0.5)
        assert predicted["gaps"][name] < SEPARATION  # one walk leaves them tied
    coulomb = separation([own], cands, {"effects.hip_coulomb": 1.796e-4}, draws=10)[0]
    flatter = toy.replace(slope=0.8 * toy.slope)
    second = walk_columns(_noise_free(flatter), flatter, FREE, rivals, model="periodic", noise_sd=noise)
    both = separation([own, second], cands, {"effects.hip_coulomb": 1.796e-4}, draws=10)[0]
    # dry friction against the viscous damper: 1.0 apart on one walk, 93.9 with the second
    # (docs/tie_design.csv; slope and pivot friction come closer: 74.8 in the full library)
    assert coulomb["gaps"]["effects.hip_damping"] < SEPARATION
    assert both["gaps"]["effects.hip_damping"] > 5 * SEPARATION
