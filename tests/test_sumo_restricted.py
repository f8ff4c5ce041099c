"""controller = "sumo_restricted": SUMO's own models drive the ego under its RSS proper-response guard (real libsumo
on the shipped highway). Where the guard never binds the ego drives exactly as SUMO's; where SUMO's model keeps
a gap shorter than RSS asks, the guard holds the ego to RSS and the audit never finds it responsible."""
from __future__ import annotations

import json

import pandas as pd

from conftest import SCENARIOS, write_scenario
from sumo_rss.batch.runner import run_directory, run_one
from sumo_rss.batch.spec import Task, variant_name
from sumo_rss.scenario import load_scenario


def _run(spec, out, controller: str) -> tuple[dict, pd.DataFrame]:
    spec = spec.with_overrides(controller=controller)
    variant = variant_name({"controller": controller})
    run_one(spec, out, variant=variant)
    folder = run_directory(out, Task(spec, variant))
    return json.loads((folder / "summary.json").read_text()), pd.read_csv(folder / "ego_trace.csv")


def test_alone_on_the_road_the_restricted_ego_drives_exactly_as_sumos(tmp_path, valid_scenario):
    data = valid_scenario | {"duration_s": 25.0}
    data["ego"]["vehicle"] = {"sigma": 0.0}  # no dawdling, as in the shipped scenarios
    data["demand"]["flows"][0] |= {"begin_s": 20.0, "end_s": 21.0}  # one car, 1 km behind the ego: never near
    spec = load_scenario(write_scenario(tmp_path, data))
    sumo, sumo_trace = _run(spec, tmp_path / "out", "sumo")
    restricted, restricted_trace = _run(spec, tmp_path / "out", "sumo_restricted")
    assert restricted["ego_controller"] == "sumo_restricted"
    assert restricted["planner"]["capped_steps"] == 0 and restricted["planner"]["lane_changes_refused"] == 0
    pd.testing.assert_frame_equal(sumo_trace, restricted_trace)
    assert sumo_trace["speed_ms"].iloc[-1] > 29.9  # it did accelerate to its desired speed of 30 m/s


def test_the_guard_holds_sumos_ego_to_rss_where_sumo_alone_is_responsible(tmp_path):
    """highway_dense inserts the ego 4-8 m behind a car at 20 m/s, inside its RSS distance (docs/planner.md): SUMO's
    model keeps that gap and is responsible for the episode; restricted, the ego brakes as RSS owes after ρ and
    then keeps at most the RSS-safe speed behind the cars ahead."""
    spec = load_scenario(SCENARIOS / "highway_dense.toml").with_overrides(seed=0, duration_s=55.0)
    sumo, _ = _run(spec, tmp_path / "out", "sumo")
    restricted, trace = _run(spec, tmp_path / "out", "sumo_restricted")
    assert sumo["ego_responsible_episodes"] >= 1
    assert restricted["ego_responsible_episodes"] == 0
    assert not [c for c in restricted["collision_events"] if "ego" in (c["collider"], c["victim"])]
    assert restricted["planner"]["capped_steps"] > 0
    assert trace["speed_ms"].min() < 19.0  # it braked from its 20 m/s insertion to open the gap
