"""Loading the shipped intention weights and running the network on numpy features.

A weights file is a ``torch.save`` of ``{"format": FORMAT, "architecture": {...}, "state_dict": {...}}``, read
with ``torch.load(weights_only=True)``. A missing, unreadable or incompatible file gives a warning and ``None``:
the planner then keeps its rule-based belief (never a crash).
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import torch

from ...files import read_json_object
from .features import Candidates
from .model import IntentionNet, candidate_probabilities

FORMAT = 1
SHIPPED_WEIGHTS = Path(__file__).with_name("weights") / "intention.pt"
CARD_FILE = "intention.json"  # the card train-intent writes beside the weights


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
    _check_card(path, architecture)
    return IntentionEstimator(net)


def _check_card(weights: Path, architecture: dict) -> None:
    """Warn when the card beside the weights (``intention.json``, written with them by train-intent) describes
    other weights: another file size or architecture; its data and figures are then not these weights'."""
    card_file = weights.with_name(CARD_FILE)
    if not card_file.is_file():
        return
    card = read_json_object(card_file)
    if card is None:
        differs = ["unreadable: not a JSON object"]
    else:
        differs = [f"{key}: card {card.get(key)!r}, weights {actual!r}" for key, actual in
                   (("weights_bytes", weights.stat().st_size),
                    ("architecture", json.loads(json.dumps(dict(architecture)))))  # as JSON holds it
                   if card.get(key) != actual]
    if differs:
        warnings.warn(f"{card_file} does not describe {weights.name} ({'; '.join(differs)}): its data and figures "
                      "are not those of the weights in use", stacklevel=3)
