"""What the effect tests (test_effects.py, the library's effects; test_ports.py, the port terms)
share: the walker with its effects at their typical strengths, random states, and the legs'
partial angular velocities from NumPy rotations, independent of the model's CasADi kinematics."""

import numpy as np
from toywalk.model.effects import EFFECTS
from toywalk.model.kinematics import rotation


def typical(params, names):
    """``params`` with each effect of ``names`` at its typical strength."""
    return params.replace(**{f"effects.{n}": EFFECTS[n].typical for n in names})


def random_states(rng, n, contact=True):
    """``n`` internal states (10,) near a toy's gait: angles about (0.05, 0.08, -0.2, 0.25) rad
    (SD 0.05), rates SD 1.5 rad/s, and (``contact``) contact coordinates SD 0.1 m, else zero."""
    for _ in range(n):
        x = np.zeros(10)
        x[:4] = [0.05, 0.08, -0.2, 0.25] + rng.normal(0, 0.05, 4)
        x[4:8] = rng.normal(0, 1.5, 4)
        if contact:
            x[8:] = rng.normal(0, 0.1, 2)
        yield x


def omega_partials(q):
    """Partial angular velocities W_i (3, 4) of both legs from NumPy rotations (model.kinematics),
    by central differences of R(q) R^T: omega = vee(R' R^T)."""
    h = 1e-6
    out = []
    for leg in (2, 3):
        cols = []
        for j in range(4):
            dq = np.zeros(4)
            dq[j] = h
            rp = rotation(*(q + dq)[[0, 1, leg]])
            rm = rotation(*(q - dq)[[0, 1, leg]])
            skew = (rp - rm) / (2 * h) @ rotation(*q[[0, 1, leg]]).T
            cols.append([skew[2, 1], skew[0, 2], skew[1, 0]])
        out.append(np.array(cols).T)
    return out
