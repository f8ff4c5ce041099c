"""The report's "rule 5 / rule 4" table: per run family (scenario and variant), the collisions whose other car
could have avoided them (rule 5, evasive effort), the episodes that began with the cars hidden from each other and
the hidden cars' unreasonable speeds (rule 4, occlusion). Both rules are opt-in; a family none of whose runs had a
rule on shows "off" for it, never 0 (0 means the rule was judged and found nothing)."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pandas as pd

from ..errors import SumoRssError
from ..rss.records import OCCLUSION_CONSTRAINT
from .summary import run_label

OFF = "off"
# (column, the rule it counts) in table order; "collisions" is every collision, whatever the rules.
RULE_COLUMNS = {"collisions": None,
                "rule 5: collisions the other car could have avoided": "rule5",
                "rule 4: episodes hidden at some step": "rule4",
                "rule 4: episodes that began hidden": "rule4",
                "rule 4: unreasonable-speed violations": "rule4"}


def rules_on(batch_dir: Path, summary: pd.DataFrame) -> pd.DataFrame:
    """Per successful run of ``summary`` (index: run_id): whether rule 5 (``rule5``: ``[rss] evasive_effort``) and
    rule 4 (``rule4``: ``[rss] occlusion``) were on, read from the run's resolved scenario.toml, which writes both
    keys whenever they are not at their default (off). A run without that file counts as both off."""
    ok = summary[summary.status == "ok"]
    rows = []
    for run_id in ok.run_id.astype(str):
        path = Path(batch_dir) / run_id / "scenario.toml"
        rss = {}
        if path.is_file():
            try:
                rss = tomllib.loads(path.read_text(encoding="utf-8")).get("rss", {})
            except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
                raise SumoRssError(f"{path}: not a TOML file as 'sumo-rss batch' writes it ({exc})") from None
        rows.append((run_id, rss.get("evasive_effort") is True, rss.get("occlusion") is True))
    return pd.DataFrame(rows, columns=["run_id", "rule5", "rule4"]).set_index("run_id").assign(
        label=run_label(ok).tolist())


def later_rules_table(on: pd.DataFrame, collisions: pd.DataFrame, occlusion: pd.DataFrame,
                      violations: pd.DataFrame) -> pd.DataFrame:
    """Rows: the run labels of ``on`` (:func:`rules_on`); columns: RULE_COLUMNS. A cell counts the rows of the
    family's runs that had its rule on, "off" where none had, and "N (k of n runs)" where only k of its n runs
    had it on."""
    def per_run(frame: pd.DataFrame, mask_of=None) -> pd.Series:
        """Rows per run_id of ``frame`` (those where ``mask_of(frame)`` holds), 0 for runs without any."""
        if frame.empty:
            return pd.Series(0, index=on.index)
        kept = frame if mask_of is None else frame[mask_of(frame)]
        return kept.run_id.astype(str).value_counts().reindex(on.index, fill_value=0)

    counts = {
        "collisions": per_run(collisions),
        "rule 5: collisions the other car could have avoided": per_run(
            collisions, lambda f: f.could_have_avoided.astype(str) != "" if "could_have_avoided" in f
            else pd.Series(False, index=f.index)),
        "rule 4: episodes hidden at some step": per_run(occlusion),
        "rule 4: episodes that began hidden": per_run(occlusion, lambda f: f.occluded_at_t_b.astype(str) == "True"),
        "rule 4: unreasonable-speed violations": per_run(violations,
                                                         lambda f: f.constraint == OCCLUSION_CONSTRAINT),
    }
    labels = sorted(on.label.unique())
    table = pd.DataFrame(index=pd.Index(labels, name="run"), columns=list(RULE_COLUMNS), dtype=object)
    for column, rule in RULE_COLUMNS.items():
        judged = pd.Series(True, index=on.index) if rule is None else on[rule]
        total = counts[column].where(judged, 0).groupby(on.label).sum()
        runs, with_rule = on.groupby("label").size(), judged.groupby(on.label).sum()
        for label in labels:
            k, n = int(with_rule[label]), int(runs[label])
            table.loc[label, column] = OFF if k == 0 else int(total[label]) if k == n else \
                f"{int(total[label])} ({k} of {n} runs)"
    return table
