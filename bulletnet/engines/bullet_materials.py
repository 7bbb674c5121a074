"""Per-body PyBullet contact values that come closest to the paper's per-pair table.

PyBullet has no per-pair material table: each body has one contact stiffness, damping and
friction coefficient, and a contact combines them (measured on 3.2.7): stiffness in series,
1 / k = 1 / k_A + 1 / k_B; damping summed, c = c_A + c_B; friction multiplied,
mu = mu_A mu_B. With five body classes (debris, corner mass, corner / edge / inner node) and
14 pairs (Tables 5-6), the per-body values are least-squares fits, each on relative error:
the compliances 1 / k linearly, the dampings linearly, the friction coefficients in logs.
:func:`fit` reports how close each pair gets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.materials import BODY_CLASSES
from ..model.net import NetModel
from ..model.scenario import Scenario
from ..solver.contact_stage import pair_tables


@dataclass(frozen=True)
class BodyMaterials:
    stiffness: np.ndarray
    """Per-class contact stiffness for PyBullet [N/m], shape (5,) (classes absent: 0)."""
    damping: np.ndarray
    """Per-class contact damping [N s/m], shape (5,)."""
    friction: np.ndarray
    """Per-class lateral friction coefficient [-], shape (5,)."""
    errors: dict
    """Per pair ``"a/b"``: relative error of the combined (k, c, mu) against the table [-]."""


def _least_squares(pairs, target, weight, present):
    """Per-class values v with v_a + v_b ~ target over ``pairs`` (rows weighted)."""
    cols = [k for k in range(5) if present[k]]
    a = np.zeros((len(pairs), len(cols)))
    for row, (i, j) in enumerate(pairs):
        a[row, cols.index(i)] += 1.0
        a[row, cols.index(j)] += 1.0
    sol = np.linalg.lstsq(a * weight[:, None], target * weight, rcond=None)[0]
    out = np.zeros(5)
    out[cols] = sol
    return out


def fit(s: Scenario, model: NetModel, has_debris: bool) -> BodyMaterials:
    """Fit the per-class values (friction to mu_k: PyBullet has one coefficient, and a
    capture slides far more than it sticks)."""
    k, c, _, mu_k = pair_tables(s, model)
    # a node class is in the net iff its pair with itself is in the table
    present = [has_debris] + [bool(k[c, c] > 0) for c in range(1, 5)]
    pairs = [(i, j) for i in range(5) for j in range(i, 5)
             if present[i] and present[j] and not (i == j == 0)]
    kt = np.array([k[i, j] for i, j in pairs])
    ct = np.array([c[i, j] for i, j in pairs])
    mt = np.array([mu_k[i, j] for i, j in pairs])
    compliance = _least_squares(pairs, 1.0 / kt, kt, present)
    damping = _least_squares(pairs, ct, 1.0 / ct, present)
    log_mu = _least_squares(pairs, np.log(np.maximum(mt, 1e-12)), np.ones(len(pairs)),
                            present)
    stiffness = np.where(compliance > 0, 1.0 / np.where(compliance > 0, compliance, 1.0), 0.0)
    friction = np.where(present, np.exp(log_mu), 0.0)
    damping = np.maximum(damping, 0.0)
    errors = {}
    for (i, j), k_ij, c_ij, m_ij in zip(pairs, kt, ct, mt, strict=True):
        k_fit = 1.0 / (compliance[i] + compliance[j])
        errors[f"{BODY_CLASSES[i]}/{BODY_CLASSES[j]}"] = (
            k_fit / k_ij - 1.0, (damping[i] + damping[j]) / c_ij - 1.0,
            friction[i] * friction[j] / m_ij - 1.0 if m_ij > 0 else 0.0)
    return BodyMaterials(stiffness=stiffness, damping=damping, friction=friction,
                         errors=errors)
