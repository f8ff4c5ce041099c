"""Training and evaluating the intention network on datasets from dataset.py (CPU, minutes).

The held-out evaluation reports, per scenario family, the top-1 accuracy and mean NLL of the network and of the
planner's rule-based belief (behavior/intention.rule_belief spread over the candidates: each lateral class's
probability split evenly among its candidates), on all samples and on the samples whose target does not hold the
rule's default (the straightest candidate of the agent's own lane): turns, lane changes and merges. A sample's
target is a set of candidates (dataset.py); top-1 counts a hit when the most probable candidate is in it, and
the NLL is −log of the probability of the whole set.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..behavior.intention import rule_belief
from .features import LEFT, RIGHT
from .model import ARCHITECTURE, IntentionNet, candidate_probabilities, nll_loss, real_width

PROBABILITY_FLOOR = 1e-6  # NLL of a zero probability is reported as -log of this


@dataclass(frozen=True)
class TrainSettings:
    epochs: int = 30
    batch_size: int = 256
    learning_rate: float = 2e-3
    seed: int = 0


def rule_probabilities(data: dict[str, np.ndarray]) -> np.ndarray:
    """[n, C] the rule-based belief over each sample's candidates."""
    mask, lateral = data["mask"], data["lateral"]
    has_left = np.any(mask & (lateral == LEFT), axis=1)
    has_right = np.any(mask & (lateral == RIGHT), axis=1)
    belief = rule_belief(data["offset"], data["lat_speed"], has_left, has_right, data["to_lane_end"])  # [n, 3]
    per_class = np.stack([np.sum(mask & (lateral == c), axis=1) for c in range(3)], axis=1)
    share = belief / np.maximum(per_class, 1)
    return np.where(mask, np.take_along_axis(share, lateral.astype(int), axis=1), 0.0)


def _tensors(data: dict[str, np.ndarray]) -> tuple[torch.Tensor, ...]:
    return (torch.as_tensor(data["history"], dtype=torch.float32), torch.as_tensor(data["lanes"], dtype=torch.float32),
            torch.as_tensor(data["mask"]), torch.as_tensor(data["target"]))


def train(data: dict[str, np.ndarray], settings: TrainSettings = TrainSettings(),
          progress: Callable[[int, float], None] | None = None) -> IntentionNet:
    """A network trained on ``data`` with Adam; ``progress(batches_done, loss)`` after every batch.
    Deterministic for a given ``settings.seed`` (single-threaded torch)."""
    torch.manual_seed(settings.seed)
    net = IntentionNet(**ARCHITECTURE)
    history, lanes, mask, target = _tensors(data)
    optimiser = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
    generator = torch.Generator().manual_seed(settings.seed)
    done = 0
    for _ in range(settings.epochs):
        net.train()
        for batch in torch.randperm(target.shape[0], generator=generator).split(settings.batch_size):
            width = real_width(mask[batch])
            loss = nll_loss(net(history[batch], lanes[batch, :width], mask[batch, :width]), target[batch, :width])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            done += 1
            if progress is not None:
                progress(done, loss.item())
    return net.eval()


def batches_per_epoch(samples: int, settings: TrainSettings) -> int:
    return -(-samples // settings.batch_size)


def predict(net: IntentionNet, data: dict[str, np.ndarray], batch_size: int = 2048) -> np.ndarray:
    """[n, C] probabilities of the network for every sample."""
    history, lanes, mask, _ = _tensors(data)
    parts = [slice(start, start + batch_size) for start in range(0, history.shape[0], batch_size)]
    out = [candidate_probabilities(net, history[part], lanes[part], mask[part]) for part in parts]
    return np.concatenate(out) if out else np.zeros(data["mask"].shape)


def _scores(probs: np.ndarray, target: np.ndarray) -> dict[str, float]:
    picked = np.sum(np.where(target, probs, 0.0), axis=1)
    return {"accuracy": float(np.mean(target[np.arange(len(target)), np.argmax(probs, axis=1)])),
            "nll": float(np.mean(-np.log(np.maximum(picked, PROBABILITY_FLOOR))))}


def evaluate(net: IntentionNet, data: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per family (and 'all'): samples, and accuracy / NLL of the network and the rule on all samples and on the
    samples whose target does not hold the rule's default candidate."""
    net_p, rule_p = predict(net, data), rule_probabilities(data)
    target = data["target"]
    metrics: dict[str, dict] = {}
    for family in ["all"] + sorted(set(data["family"].tolist())):
        rows = np.ones(len(target), bool) if family == "all" else data["family"] == family
        changes = rows & ~target[:, 0]
        entry: dict = {"samples": int(rows.sum()), "non_default_samples": int(changes.sum())}
        for name, probs in (("net", net_p), ("rule", rule_p)):
            entry[name] = _scores(probs[rows], target[rows]) if rows.any() else {}
            entry[f"{name}_non_default"] = _scores(probs[changes], target[changes]) if changes.any() else {}
        metrics[family] = entry
    return metrics
