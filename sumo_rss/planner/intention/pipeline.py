"""`sumo-rss train-intent`: record the data, train, evaluate on held-out seeds, write weights and their card.

The output folder gets ``train.npz`` and ``test.npz`` (the datasets, reused when ``reuse_data`` and their card
entries match), ``intention.pt`` (weights) and ``intention.json`` (the card: data seeds, settings, metrics).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from ...errors import SumoRssError
from ...files import atomic_path, write_json
from ...scenario import load_scenario
from . import dataset
from .estimator import CARD_FILE, FORMAT, save_weights
from .model import ARCHITECTURE
from .train import TrainSettings, batches_per_epoch, evaluate, train

# The highway has no branching lanes (CFB keeps the rules there), so it gives no samples unless all are recorded.
DEFAULT_SCENARIOS = ("intersection_tls", "intersection_priority", "merge_onramp")
WEIGHTS_FILE = "intention.pt"


@dataclasses.dataclass(frozen=True)
class DataPlan:
    scenarios: tuple[Path, ...]
    train_seeds: tuple[int, ...]
    test_seeds: tuple[int, ...]
    duration_s: float | None  # None: each scenario's own duration
    all_samples: bool = False  # also where lanes do not branch

    def card(self) -> dict:
        return {"scenarios": [p.stem for p in self.scenarios], "train_seeds": list(self.train_seeds),
                "test_seeds": list(self.test_seeds), "duration_s": self.duration_s, "all_samples": self.all_samples}


def _dataset(plan: DataPlan, seeds: tuple[int, ...], path: Path, reuse: bool, workers: int,
             bar: Callable[[], None]) -> dict[str, np.ndarray]:
    stamp = path.with_suffix(".json")
    # The files' contents too: an edited scenario of the same name must not reuse the old recording.
    wanted = {**plan.card(), "seeds": list(seeds),
              "scenario_sha256": [hashlib.sha256(p.read_bytes()).hexdigest() for p in plan.scenarios]}
    if reuse and path.is_file() and stamp.is_file() and json.loads(stamp.read_text()) == wanted:
        for _ in range(len(plan.scenarios) * len(seeds)):
            bar()
        return dataset.load(path)
    data = dataset.generate(list(plan.scenarios), seeds, duration_s=plan.duration_s, workers=workers,
                            all_samples=plan.all_samples, progress=bar)
    if len(data["target"]) == 0:
        raise SumoRssError(f"no samples in {', '.join(str(p) for p in plan.scenarios)} at seeds "
                           f"{', '.join(map(str, seeds))}: only cars whose lane branches or ends give samples (the "
                           "highway gives none without --all-samples), and each needs 2 s of past and 3 s of future")
    dataset.save(data, path)
    write_json(stamp, wanted)
    return data


def train_intent(plan: DataPlan, out: Path, settings: TrainSettings = TrainSettings(), *, workers: int = 1,
                 reuse_data: bool = False, show_progress: bool = True) -> dict:
    """Run the whole pipeline; returns the card (also written to ``out/intention.json``)."""
    from tqdm import tqdm

    overlap = set(plan.train_seeds) & set(plan.test_seeds)
    if overlap:
        raise ValueError(f"held-out seeds must not be training seeds (both: {sorted(overlap)})")
    for path in plan.scenarios:  # before any run: a step the samples cannot use fails every recording
        dataset.check_step(load_scenario(path).step_s, path)
    out.mkdir(parents=True, exist_ok=True)
    runs = len(plan.scenarios) * (len(plan.train_seeds) + len(plan.test_seeds))
    with tqdm(total=runs, unit="run", desc="record", disable=not show_progress) as bar:
        train_data = _dataset(plan, plan.train_seeds, out / "train.npz", reuse_data, workers, bar.update)
        test_data = _dataset(plan, plan.test_seeds, out / "test.npz", reuse_data, workers, bar.update)
    torch.set_num_threads(1)  # deterministic, and what the planner has at run time: one core
    total = settings.epochs * batches_per_epoch(len(train_data["target"]), settings)
    with tqdm(total=total, unit="batch", desc="train", disable=not show_progress) as bar:
        def progress(done: int, loss: float) -> None:
            bar.update(1)
            if done % 50 == 0:
                bar.set_postfix(loss=f"{loss:.3f}")
        net = train(train_data, settings, progress)
    weights = out / WEIGHTS_FILE
    with atomic_path(weights) as tmp:
        save_weights(net, ARCHITECTURE, tmp)
    card = {"format": FORMAT, "architecture": dict(ARCHITECTURE), "data": plan.card(),
            "samples": {"train": len(train_data["target"]), "test": len(test_data["target"])},
            "training": dataclasses.asdict(settings), "torch": torch.__version__,
            "weights_bytes": weights.stat().st_size, "held_out": evaluate(net, test_data)}
    write_json(out / CARD_FILE, card)
    return card


def summary_lines(card: dict) -> list[str]:
    """One line per family: held-out accuracy and NLL of the network vs the rule-based belief."""
    lines = []
    for family, m in card["held_out"].items():
        lines.append(f"{family:>12}: {m['samples']:7d} samples  top-1 net {m['net']['accuracy']:.4f} vs rule "
                     f"{m['rule']['accuracy']:.4f}  NLL net {m['net']['nll']:.4f} vs rule {m['rule']['nll']:.4f}  "
                     f"(turns/changes/merges: {m['non_default_samples']}, net "
                     f"{m['net_non_default'].get('accuracy', float('nan')):.3f} vs rule "
                     f"{m['rule_non_default'].get('accuracy', float('nan')):.3f})")
    return lines
