"""The documentation names only what the code has: glossary names exist, CSV schemas match the writers."""
from __future__ import annotations

import json
import re

from conftest import REPO
from sumo_rss.rss import auditor, formulas, open_episodes, records, situations
from sumo_rss.rss.params import PARAM_NAMES

OUTPUTS = (REPO / "docs" / "outputs.md").read_text(encoding="utf-8")


def _table(heading: str) -> list[list[str]]:
    section = OUTPUTS.split(heading, 1)[1].split("\n## ", 1)[0]
    rows = [line.strip().strip("|").split("|") for line in section.splitlines() if line.startswith("|")]
    return [[cell.strip() for cell in row] for row in rows[2:]]


def test_every_glossary_code_name_exists():
    known = set(PARAM_NAMES) | set(dir(formulas)) | set(dir(open_episodes)) | set(dir(situations)) | \
        set(records.EPISODE_COLUMNS) | set(auditor.COLLISION_COLUMNS)
    names = [n for row in _table("## Glossary") for n in re.findall(r"`([^`]+)`", row[1])]
    assert len(names) >= 15
    assert [n for n in names if n not in known] == []


def test_documented_columns_are_the_written_columns():
    for heading, columns in (("## `episodes.csv`", records.EPISODE_COLUMNS),
                             ("## `violations.csv`", records.VIOLATION_COLUMNS),
                             ("## `collisions.csv`", auditor.COLLISION_COLUMNS),
                             ("## `occlusion.csv`", records.OCCLUSION_COLUMNS)):
        documented = [n for row in _table(heading) for n in re.findall(r"`([^`]+)`", row[0])]
        assert documented == columns, heading


def test_documented_constraints_and_situations_exist():
    for constraint in (*(c.value for c in open_episodes.Constraint), records.EVASIVE_CONSTRAINT,
                       records.OCCLUSION_CONSTRAINT):
        assert f"`{constraint}`" in OUTPUTS
    for kind in situations.SituationType:
        assert f"`{kind.value}`" in OUTPUTS


def test_the_custom_controller_example_runs_and_writes_a_run(tmp_path, monkeypatch):
    """docs/extending.md's example, run for 150 s (the ego departs at 30 s and drives through the 875 m curve) and
    written to tmp_path. It follows its lane (an earlier example moved straight on along its heading and left the
    road in the curve, silently), and its run does not take the folder of the scenario's own run."""
    import warnings

    import pandas as pd

    text = (REPO / "docs" / "extending.md").read_text(encoding="utf-8")
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    code = code.replace('Path("results/custom")', f"Path({str(tmp_path)!r})").replace("60.0", "150.0")
    assert code.count(str(tmp_path)) == 1 and "150.0" in code
    namespace: dict = {}
    monkeypatch.chdir(REPO)
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*left the road")
        exec(compile(code, "extending.md", "exec"), namespace)
    summary = namespace["summary"]
    assert summary.ego_controller == "custom" and summary.ego_mean_speed_ms > 0
    run = tmp_path / "highway_dense__controller=custom" / "0"
    assert not (tmp_path / "highway_dense").exists()
    trace = pd.read_csv(run / "ego_trace.csv")
    assert trace.lane_id.str.startswith("hw1").any() and trace.lat_pos_m.abs().max() < 0.3
    assert json.loads((run / "summary.json").read_text())["ego_controller"] == "custom"
    assert not (run / "planner.json").exists()  # the example has no summary()
    # The run records its controller: its hash is not the scenario's own, so a batch never adopts it, and its
    # scenario.toml says it alone does not reproduce the run (and still loads).
    from sumo_rss.batch.orchestrator import _unfinished
    from sumo_rss.batch.spec import Task
    from sumo_rss.scenario import load_scenario

    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["custom_controller"] == "builtins.RssFollower"
    spec = namespace["spec"]
    custom = Task(spec, "controller=custom")
    assert manifest["parameter_hash"] == custom.parameter_hash("builtins.RssFollower") != custom.parameter_hash()
    assert _unfinished(tmp_path, custom) == f"{run}: made from other scenario parameters"
    assert (run / "scenario.toml").read_text().startswith("# The ego was driven by the Python controller")
    assert load_scenario(run / "scenario.toml").to_toml_data() == spec.to_toml_data()


def test_the_documented_python_api_exists_with_the_documented_parameters():
    """README and docs: every dotted sumo_rss name resolves; api.md: the documented parameters are the functions'
    own."""
    import importlib
    import inspect

    resolved = {}
    every_doc = "\n".join(p.read_text(encoding="utf-8") for p in [REPO / "README.md", *(REPO / "docs").glob("*.md")])
    for dotted in sorted(set(re.findall(r"sumo_rss(?:\.\w+)+", every_doc))):
        parts = dotted.split(".")
        for k in range(len(parts), 0, -1):  # the longest importable prefix, then attributes
            try:
                target = importlib.import_module(".".join(parts[:k]))
                break
            except ModuleNotFoundError:
                continue
        for name in parts[k:]:
            target = getattr(target, name)
        resolved[parts[-1]] = target
    assert len(resolved) >= 10
    for name, parameters in (("run_one", "spec out_dir variant fcd on_step controller stop"),
                             ("run_batch", "tasks out_dir executor progress"),
                             ("Auditor", "network params run_id trace_class signal_rule raw_episodes junction_brake_min "
                                         "record_states spool evasive occlusion heights occluders"),
                             ("audit_fcd", "fcd network params vehicles collisions tls_states ego_ids run_id "
                                           "signal_rule raw_episodes junction_brake_min trace_class on_progress stop "
                                           "record_states spool on_snapshot evasive occlusion occluders"),
                             ("write_view", "run_dir out net every geometry"),
                             ("EpsilonPlanner", "network params config")):
        assert list(inspect.signature(resolved[name]).parameters) == parameters.split(), name
