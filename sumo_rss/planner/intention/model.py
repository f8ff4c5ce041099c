"""The intention network (epsilon.md port decision 9, after the EPSILON paper).

- Lane encoder: each candidate centreline (``LANE_POINTS`` points of x, y, beyond-the-end flag) → two 1-D
  convolutions (kernel 3, ReLU) → average pooling over the points.
- Trajectory encoder: each past point (x, y, right blinker, left blinker) → a linear input embedding of size 4 →
  LSTM, hidden size 64.
- Each lane embedding concatenated with the trajectory embedding → MLP with ReLU → one score per lane; a softmax
  over the real candidates (padded ones are masked out) gives P(lane); trained with the negative log-likelihood.

Positions are in metres in the agent's frame and are scaled inside the network (``POSITION_SCALE``).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from .features import HISTORY_FEATURES

POSITION_SCALE = 20.0  # [m] coordinates are divided by this
ARCHITECTURE = {"lane_channels": (32, 64), "embedding": 4, "hidden": 64, "mlp": 64}


class IntentionNet(nn.Module):
    def __init__(self, lane_channels: tuple[int, int] = (32, 64), embedding: int = 4, hidden: int = 64,
                 mlp: int = 64):
        super().__init__()
        c1, c2 = lane_channels
        self.lane_encoder = nn.Sequential(
            nn.Conv1d(3, c1, kernel_size=3, padding=1), nn.ReLU(),
            nn.Conv1d(c1, c2, kernel_size=3, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool1d(1))
        self.embed = nn.Linear(HISTORY_FEATURES, embedding)
        self.lstm = nn.LSTM(embedding, hidden, batch_first=True)
        self.score = nn.Sequential(nn.Linear(c2 + hidden, mlp), nn.ReLU(), nn.Linear(mlp, 1))

    def forward(self, history: torch.Tensor, lanes: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Log-probabilities [n, C] of the candidates; -inf where ``mask`` is False.

        ``history`` [n, T, HISTORY_FEATURES] past points (features.py); ``lanes`` [n, C, P, 3];
        ``mask`` [n, C] bool (≥ 1 True per row).
        """
        n, c, p, f = lanes.shape
        xy_scale = lanes.new_tensor([POSITION_SCALE, POSITION_SCALE, 1.0])
        lane_emb = self.lane_encoder((lanes / xy_scale).reshape(n * c, p, f).transpose(1, 2)).reshape(n, c, -1)
        history_scale = history.new_tensor([POSITION_SCALE, POSITION_SCALE] + [1.0] * (HISTORY_FEATURES - 2))
        _, (h, _) = self.lstm(self.embed(history / history_scale))
        traj_emb = h[-1][:, None, :].expand(n, c, h.shape[-1])
        scores = self.score(torch.cat([lane_emb, traj_emb], dim=2)).squeeze(2)
        return torch.log_softmax(scores.masked_fill(~mask, float("-inf")), dim=1)


def nll_loss(log_probs: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean negative log-likelihood of each sample's target set: −log Σ p over its target candidates
    (``target`` [n, C] bool, ≥ 1 True per row)."""
    return -torch.logsumexp(log_probs.masked_fill(~target, float("-inf")), dim=1).mean()


def real_width(mask: torch.Tensor) -> int:
    """Candidate columns up to the widest row's last real one (real candidates come first, padding after)."""
    return int(mask.sum(dim=1).max())


def candidate_probabilities(net: IntentionNet, history: torch.Tensor, lanes: torch.Tensor,
                            mask: torch.Tensor) -> np.ndarray:
    """[n, C] P(candidate) as float64 (0 on padding), the network run on the real columns only."""
    probs = np.zeros(tuple(mask.shape))
    if mask.shape[0] == 0:
        return probs
    width = real_width(mask)
    with torch.inference_mode():
        probs[:, :width] = torch.exp(net(history, lanes[:, :width], mask[:, :width])).double().numpy()
    return probs
