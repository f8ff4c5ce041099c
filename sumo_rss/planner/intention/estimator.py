"""Loading the shipped intention weights and running the network on numpy features.

A weights file is a ``torch.save`` of ``{"format": FORMAT, "architecture": {...}, "state_dict": {...}}``, read
with ``torch.load(weights_only=True)``. A missing, unreadable or incompatible file gives a warning and ``None``:
the planner then keeps its rule-based belief (never a crash).
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import torch

from .features import Candidates
from .model import IntentionNet, candidate_probabilities

FORMAT = 1
SHIPPED_WEIGHTS = Path(__file__).with_name("weights") / "intention.pt"


class IntentionEstimator:
    """P(candidate) for agents, from their past trajectory and candidate centrelines (features.py)."""

    def __init__(self, net: IntentionNet):
        self.net = net.eval()

    def probabilities(self, history: np.ndarray, candidates: Candidates) -> np.ndarray:
        """[n, C] probabilities of each agent's candidates (0 where padded); ``history`` [n, T, HISTORY_FEATURES]
        (features.history_in_agent_frame)."""
        return candidate_probabilities(self.net, torch.as_tensor(history, dtype=torch.float32),
                                       torch.as_tensor(candidates.lanes, dtype=torch.float32),
                                       torch.as_tensor(candidates.mask))


def save_weights(net: IntentionNet, architecture: dict, path: Path) -> None:
    payload = {"format": FORMAT, "architecture": dict(architecture),
               "state_dict": {k: v.detach().clone() for k, v in net.state_dict().items()}}
    torch.save(payload, path)


def load_estimator(path: Path | None = None) -> IntentionEstimator | None:
    """The estimator of a weights file (default: the shipped one), or ``None`` with a warning saying why."""
    path = SHIPPED_WEIGHTS if path is None else Path(path)
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        if not isinstance(payload, dict) or payload.get("format") != FORMAT:
            raise ValueError(f"expected a dict with format {FORMAT} (written by sumo-rss train-intent)")
        architecture = payload["architecture"]
        net = IntentionNet(lane_channels=tuple(architecture["lane_channels"]), embedding=architecture["embedding"],
                           hidden=architecture["hidden"], mlp=architecture["mlp"])
        net.load_state_dict(payload["state_dict"])
        if not all(torch.isfinite(value).all() for value in net.state_dict().values()):
            raise ValueError("the weights hold NaN or infinite values")
    except Exception as exc:  # any unusable file means the rules; say why, never crash the planner
        warnings.warn(f"intention weights {path} not usable ({type(exc).__name__}: {exc}); "
                      "using the rule-based intention belief instead", stacklevel=2)
        return None
    return IntentionEstimator(net)
