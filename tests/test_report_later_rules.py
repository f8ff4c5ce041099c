"""The report's "rule 5 / rule 4" table from a hand-made batch folder (no SUMO): counts per run family of the runs
that had each rule on, "off" where none had, and the count over the runs that had it where only some had."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from sumo_rss.errors import SumoRssError
from sumo_rss.report.html import write_report
from sumo_rss.report.inputs import COLUMNS
from sumo_rss.report.later_rules import OFF, later_rules_table, rules_on

RUNS = [  # run_id, scenario, variant, seed, [rss] table of its scenario.toml (None: no scenario.toml)
    ("hw/0", "hw", "", 0, "evasive_effort = true\nocclusion = true\n"),
    ("hw/1", "hw", "", 1, "evasive_effort = true\nocclusion = true\n"),
    ("plain/0", "plain", "", 0, "preset = \"ad_rss\"\n"),
    ("plain/1", "plain", "", 1, None),
    ("mix__a/0", "mix", "a", 0, "occlusion = true\nevasive_effort = false\n"),
    ("mix__a/1", "mix", "a", 1, "occlusion = false\n"),
]


def _csv(path: Path, name: str, rows: list[dict]) -> None:
    frame = pd.DataFrame(rows, columns=COLUMNS[name] + (["could_have_avoided"] if name == "collisions" else []))
    frame.to_csv(path / f"{name}.csv", index=False)


def _row(name: str, run_id: str, **cells) -> dict:
    scenario, variant, seed = next((s, v, n) for r, s, v, n, _ in RUNS if r == run_id)
    return dict.fromkeys(COLUMNS[name], "0") | {"run_id": run_id, "scenario": scenario, "variant": variant,
                                                 "seed": seed} | cells


@pytest.fixture
def batch(tmp_path: Path) -> Path:
    pd.DataFrame([(r, s, v, n, "ok") for r, s, v, n, _ in RUNS] + [("hw/2", "hw", "", 2, "failed")],
                 columns=["run_id", "scenario", "variant", "seed", "status"]).to_csv(tmp_path / "batch_summary.csv",
                                                                                      index=False)
    for run_id, *_, rss in RUNS:
        (tmp_path / run_id).mkdir(parents=True)
        if rss is not None:
            (tmp_path / run_id / "scenario.toml").write_text(f'network = "highway"\n\n[rss]\n{rss}')
    collision = {"collider": "c", "victim": "v", "sumo_type": "collision", "blamed": "c", "episode_key": "c|v|1"}
    _csv(tmp_path, "collisions", [
        _row("collisions", "hw/0", **collision, could_have_avoided="v"),
        _row("collisions", "hw/0", **collision, could_have_avoided=""),
        _row("collisions", "hw/1", **collision, could_have_avoided="v;w"),
        _row("collisions", "plain/0", **collision, could_have_avoided=""),
        _row("collisions", "mix__a/1", **collision, could_have_avoided=""),
    ])
    hidden = {"episode_key": "a|b|1", "vehicle_a": "a", "vehicle_b": "b", "episode_index": "1",
              "situation": "same_direction", "t_b_s": "3.1", "exposure_a_s": "", "exposure_b_s": ""}
    _csv(tmp_path, "occlusion", [
        _row("occlusion", "hw/0", **hidden, occluded_at_t_b="True"),
        _row("occlusion", "hw/0", **hidden, occluded_at_t_b="False"),
        _row("occlusion", "hw/1", **hidden, occluded_at_t_b="True"),
        _row("occlusion", "mix__a/0", **hidden, occluded_at_t_b="True"),
    ])
    broken = {"episode_key": "a|b|1", "vehicle_id": "a", "vehicle_class": "background", "role": "a", "bound": "1",
              "worst_actual": "2", "excess": "1", "t_start_s": "3.1", "t_end_s": "4.0"}
    _csv(tmp_path, "violations", [
        _row("violations", "hw/1", **broken, constraint="occluded-unreasonable-speed"),
        _row("violations", "hw/1", **broken, constraint="lon-brake-min"),
        _row("violations", "mix__a/0", **broken, constraint="occluded-unreasonable-speed"),
    ])
    return tmp_path


def _table(batch: Path) -> pd.DataFrame:
    summary = pd.read_csv(batch / "batch_summary.csv", dtype=str, keep_default_na=False)
    read = {name: pd.read_csv(batch / f"{name}.csv", dtype=str, keep_default_na=False)
            for name in ("collisions", "occlusion", "violations")}
    return later_rules_table(rules_on(batch, summary), read["collisions"], read["occlusion"], read["violations"])


def test_the_table_counts_only_runs_that_had_the_rule_on_and_says_off_otherwise(batch):
    table = _table(batch)
    assert table.index.tolist() == ["hw", "mix [a]", "plain"]
    assert table.loc["hw"].tolist() == [3, 2, 3, 2, 1]  # both rules on in both ok seeds (failed seed 2 not read)
    assert table.loc["plain"].tolist() == [1, OFF, OFF, OFF, OFF]  # no rule keys / no scenario.toml: off
    # Rule 4 on in seed 0 only: its rows counted, with how many runs judged them; rule 5 off in both.
    assert table.loc["mix [a]"].tolist() == [1, OFF, "1 (1 of 2 runs)", "1 (1 of 2 runs)", "1 (1 of 2 runs)"]


def test_a_batch_without_rule_files_shows_zero_where_a_rule_was_on(batch):
    for name in ("occlusion", "violations", "collisions"):
        (batch / f"{name}.csv").unlink()
    summary = pd.read_csv(batch / "batch_summary.csv", dtype=str, keep_default_na=False)
    table = later_rules_table(rules_on(batch, summary), pd.DataFrame(), pd.DataFrame(), pd.DataFrame())
    assert table.loc["hw"].tolist() == [0, 0, 0, 0, 0] and table.loc["plain"].tolist() == [0, OFF, OFF, OFF, OFF]


def test_report_html_shows_the_rule_table_and_names_a_damaged_occlusion_csv(batch):
    page = write_report(batch, views=False).read_text()
    assert "Rule 5 / rule 4" in page and "rule 4: episodes that began hidden" in page
    assert "<td>1 (1 of 2 runs)</td>" in page and f"<td>{OFF}</td>" in page
    occlusion = (batch / "occlusion.csv").read_text().replace("True", "yes", 1)
    (batch / "occlusion.csv").write_text(occlusion)
    with pytest.raises(SumoRssError, match=r"occlusion\.csv: line 2: column 'occluded_at_t_b': expected one of True"):
        write_report(batch, views=False)
    (batch / "hw" / "0" / "scenario.toml").write_text("[rss\n")
    (batch / "occlusion.csv").write_text(occlusion.replace("yes", "True"))
    with pytest.raises(SumoRssError, match=r"hw/0/scenario\.toml: not a TOML file"):
        write_report(batch, views=False)
