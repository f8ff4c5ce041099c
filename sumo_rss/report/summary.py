"""Batch tables: who was responsible (for the ego, and every pair), per scenario and variant, and which rules were
broken (from the batch CSVs)."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..files import read_csv_table

from ..rss.open_episodes import CONSTRAINTS
from ..rss.signals import SignalConstraint
from ..sim.snapshot import EGO_CLASS

RESPONSIBILITY_CATEGORIES = ["ego", "ego & background", "background", "none"]
# The ego's episodes by who was responsible (columns of ego_table, after 'seeds' and 'episodes').
EGO_CATEGORIES = {"ego": "ego", "ego & background": "ego and the other car", "background": "the other car only",
                  "none": "nobody"}
RULES = [c.value for c in CONSTRAINTS] + [c.value for c in SignalConstraint]  # every rule violations.csv can name
# Columns of names and ids, read as text whatever they look like (a scenario '007', vehicles '7', '1e3').
TEXT_COLUMNS = ("run_id", "scenario", "variant", "episode_key", "vehicle_a", "vehicle_b", "class_a", "class_b",
                "vehicle_id", "vehicle_class", "conflict_area", "collider", "victim", "blamed", "error")


def read_batch_csv(batch_dir: Path, name: str) -> pd.DataFrame:
    """A concatenated batch CSV (empty frame if the batch produced none). Empty cells stay empty strings (a junction
    episode has no lateral margin), so such columns are read whole, not guessed chunk by chunk; names and ids
    (TEXT_COLUMNS) are text."""
    path = Path(batch_dir) / f"{name}.csv"
    if not path.is_file():
        return pd.DataFrame()
    return read_csv_table(path, "'sumo-rss batch'", keep_default_na=False, dtype=dict.fromkeys(TEXT_COLUMNS, str),
                          low_memory=False)


def run_label(frame: pd.DataFrame) -> pd.Series:
    """'scenario' or 'scenario [variant]' per row."""
    variant = frame["variant"].astype(str)
    return frame["scenario"].astype(str) + variant.where(variant == "", " [" + variant + "]")


def responsibility_category(episodes: pd.DataFrame) -> pd.Series:
    """Per episode: whose violation made it someone's responsibility (one of RESPONSIBILITY_CATEGORIES)."""
    a_blamed = episodes.responsible.isin(["a", "both"])
    b_blamed = episodes.responsible.isin(["b", "both"])
    ego = (a_blamed & (episodes.class_a == EGO_CLASS)) | (b_blamed & (episodes.class_b == EGO_CLASS))
    background = (a_blamed & (episodes.class_a != EGO_CLASS)) | (b_blamed & (episodes.class_b != EGO_CLASS))
    return pd.Series(
        [("ego & background" if g else "ego") if e else ("background" if g else "none")
         for e, g in zip(ego, background)], index=episodes.index, dtype=object)


def responsibility_table(episodes: pd.DataFrame, labels: list[str] | None = None) -> pd.DataFrame:
    """Episodes per run label (rows; every one of ``labels``, 0 where a run had none) and responsibility category
    (columns)."""
    if episodes.empty:
        table = pd.DataFrame(columns=RESPONSIBILITY_CATEGORIES, dtype=int)
    else:
        table = pd.crosstab(run_label(episodes), responsibility_category(episodes), rownames=["run"],
                            colnames=["responsible"])
    table = table.reindex(columns=RESPONSIBILITY_CATEGORIES, fill_value=0)
    return table if labels is None else table.reindex(sorted(set(labels) | set(table.index)), fill_value=0)


def ego_table(episodes: pd.DataFrame, summary: pd.DataFrame) -> pd.DataFrame:
    """Per run label of the successful runs of ``summary`` (batch_summary.csv): the seeds pooled, the ego's danger
    episodes and who was responsible in them (EGO_CATEGORIES), and the ego's mean speed over those runs [m/s]."""
    ok = summary[summary.status == "ok"]
    labels = run_label(ok)
    with_ego = episodes.iloc[0:0] if episodes.empty else \
        episodes[(episodes.class_a == EGO_CLASS) | (episodes.class_b == EGO_CLASS)]
    counts = responsibility_table(with_ego, labels.unique().tolist())
    table = pd.DataFrame(index=counts.index)
    table["seeds"] = ok.groupby(labels).seed.apply(lambda s: ", ".join(str(v) for v in sorted(set(s))))
    table["episodes"] = counts.sum(axis=1)
    for category, name in EGO_CATEGORIES.items():
        table[f"responsible: {name}"] = counts[category]
    if "ego_mean_speed_ms" in ok:
        table["ego mean speed [m/s]"] = pd.to_numeric(ok.ego_mean_speed_ms, errors="coerce").groupby(labels).mean()
    table.index.name = "run"
    return table


def violation_table(violations: pd.DataFrame, labels: list[str] | None = None) -> pd.DataFrame:
    """Violation intervals per rule (rows: every rule of RULES, 0 where none was broken) and run label (columns;
    every one of ``labels``, 0 where a run had none)."""
    if violations.empty:
        table = pd.DataFrame(0, index=pd.Index(RULES, name="rule"), columns=pd.Index([], name="run"))
    else:
        table = pd.crosstab(violations.constraint, run_label(violations), rownames=["rule"], colnames=["run"])
        table = table.reindex(RULES + sorted(set(table.index) - set(RULES)), fill_value=0)
    return table if labels is None else table.reindex(columns=sorted(set(labels) | set(table.columns)),
                                                      fill_value=0)
