"""Conditional focused branching (CFB, epsilon.md port decision 1; EUDM paper).

Each key agent has soft intention probabilities P(keep, left, right). Only the agents whose intention matters for
the ego (found by an open-loop pre-check) are branched; every other agent takes its most likely intention. The
scenarios are the ``k`` most likely intention combinations of the branched agents, with probabilities
renormalised to sum to 1; a policy's cost is the weighted sum of its costs in these scenarios.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

INTENTIONS = ("keep", "left", "right")  # column order of the probability arrays
UNCERTAINTY_MARGIN = 0.3  # an agent is uncertain when its top two probabilities differ by less than this


@dataclass(frozen=True, eq=False)
class Scenarios:
    """``intentions[k, i]``: index into INTENTIONS of agent i in scenario k; ``weights[k]`` sum to 1."""

    intentions: np.ndarray  # [k, n] int
    weights: np.ndarray  # [k]


def uncertain_agents(probabilities: np.ndarray, margin: float = UNCERTAINTY_MARGIN) -> np.ndarray:
    """Agents whose two most likely intentions are within ``margin`` of each other. ``probabilities``: [n, 3]."""
    top2 = -np.sort(-np.asarray(probabilities, dtype=float), axis=1)[:, :2]
    return (top2[:, 0] - top2[:, 1]) < margin


def branch_scenarios(probabilities: np.ndarray, branched: np.ndarray, k: int = 4) -> Scenarios:
    """The top-``k`` intention combinations of the ``branched`` agents (others at their MAP intention).

    Ties are broken by the combination's order (agents in order, intentions in INTENTIONS order), so the result is
    deterministic. With no branched agent there is one scenario of weight 1.
    """
    probabilities = np.asarray(probabilities, dtype=float)
    n = probabilities.shape[0]
    map_intention = np.argmax(probabilities, axis=1)
    idx = np.flatnonzero(branched)
    if idx.size == 0:
        return Scenarios(map_intention[None, :].copy(), np.ones(1))
    combos = np.array(list(itertools.product(range(len(INTENTIONS)), repeat=idx.size)), dtype=int)
    combo_p = np.prod(probabilities[idx[None, :], combos], axis=1)
    keep = combo_p > 0.0
    combos, combo_p = combos[keep], combo_p[keep]
    order = np.argsort(-combo_p, kind="stable")[:k]
    intentions = np.repeat(map_intention[None, :], len(order), axis=0)
    intentions[:, idx] = combos[order]
    weights = combo_p[order] / combo_p[order].sum()
    return Scenarios(intentions.reshape(len(order), n), weights)
