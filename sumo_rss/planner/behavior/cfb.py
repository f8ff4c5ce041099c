"""Conditional focused branching (CFB, epsilon.md port decision 1; EUDM paper).

Each key agent has soft intention probabilities P(keep, left, right). Only the agents whose intention matters for
the ego (found by an open-loop pre-check) are branched; every other agent takes its most likely intention. The
scenarios are the ``k`` most likely intention combinations of the branched agents, with probabilities
renormalised to sum to 1; a policy's cost is the weighted sum of its costs in these scenarios.
"""
from __future__ import annotations

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
    deterministic. With no branched agent there is one scenario of weight 1. The combinations are built one agent
    at a time, keeping the best ``k`` (O(m·k) for m branched agents, not 3^m): a combination among the best k
    has its first agents' part among the best k of those parts, since any better part would lead with the same
    remaining intentions to a better combination.
    """
    probabilities = np.asarray(probabilities, dtype=float)
    n = probabilities.shape[0]
    map_intention = np.argmax(probabilities, axis=1)
    idx = np.flatnonzero(branched)
    if idx.size == 0:
        return Scenarios(map_intention[None, :].copy(), np.ones(1))
    choices = len(INTENTIONS)
    combos, combo_p = np.zeros((1, 0), dtype=int), np.ones(1)
    for agent in idx:  # combos stay in combination order: each is followed by its own extensions in turn
        combos = np.concatenate([np.repeat(combos, choices, axis=0),
                                 np.tile(np.arange(choices), len(combos))[:, None]], axis=1)
        combo_p = np.repeat(combo_p, choices) * np.tile(probabilities[agent], len(combo_p))
        possible = np.flatnonzero(combo_p > 0.0)
        best = np.sort(possible[np.argsort(-combo_p[possible], kind="stable")[:k]])
        combos, combo_p = combos[best], combo_p[best]
    order = np.argsort(-combo_p, kind="stable")
    intentions = np.repeat(map_intention[None, :], len(order), axis=0)
    intentions[:, idx] = combos[order]
    weights = combo_p[order] / combo_p[order].sum()
    return Scenarios(intentions.reshape(len(order), n), weights)
