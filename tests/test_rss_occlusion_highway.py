"""RSS rule 4 on a highway with real SUMO (scenarios/highway_truck_cut_in.toml): a 4 m truck in the middle lane
hides `cutter`, 25 m ahead of it, from `follower`, coming up in the left lane at 30 m/s. Closing on a slow car, the
cutter pulls out into the left lane (SUMO's own lane change, 3 s long: lanechange_duration_s's default; its
lateral motion starts at 3.7 s). The hand-worked numbers: docs/rss.md "Rule 4", the truck case."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import SCENARIOS, run_cli
from sumo_rss.batch.runner import param_resolver
from sumo_rss.report.later_rules import OFF, later_rules_table, rules_on
from sumo_rss.report.summary import read_batch_csv
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor
from sumo_rss.rss.occlusion import line_of_sight, vtype_heights
from sumo_rss.rss.records import OCCLUSION_CONSTRAINT
from sumo_rss.scenario import load_scenario

PAIR = "cutter|follower|1"


@pytest.fixture(scope="module")
def audits():
    """8 s of the scenario, audited with its rule 4 and without (the same snapshots), and the sight line of the
    pair per step."""
    from sumo_rss.sim.session import Session
    from sumo_rss.sim.vtypes import running_heights

    spec = load_scenario(SCENARIOS / "highway_truck_cut_in.toml").with_overrides(duration_s=8.0)
    assert spec.rss.occlusion.enabled
    net, resolver = RoadNetwork.from_file(spec.net_file), param_resolver(spec)
    seen = {}
    with Session(spec) as session:
        heights = running_heights()
        assert heights["truck"] == 4.0
        with_rule4 = Auditor(net, resolver, occlusion=spec.rss.occlusion, heights=heights)
        without = Auditor(net, resolver)
        while not session.finished:
            snapshot = session.step()
            t = round(snapshot.time, 6)
            for auditor in (with_rule4, without):
                auditor.observe(snapshot, session.new_collisions)
            if {"cutter", "follower"} <= set(snapshot.ids.tolist()):
                pair = np.array([snapshot.index_of("cutter")]), np.array([snapshot.index_of("follower")])
                seen[t] = bool(line_of_sight(snapshot, *pair, vtype_heights(snapshot, heights),
                                             spec.rss.occlusion.min_height_m, None)[0])
    return with_rule4.finish(), without.finish(), seen


def test_the_truck_hides_the_cut_in_until_the_cutter_clears_its_front_corner(audits):
    result, _, seen = audits
    row = result.occlusion.set_index("episode_key").loc[PAIR]
    assert bool(row.occluded_at_t_b) and row.t_b_s == pytest.approx(3.7)  # the first step of lateral motion
    assert row.exposure_a_s == row.exposure_b_s == pytest.approx(4.0)
    hidden = sorted(t for t, visible in seen.items() if not visible)
    assert hidden == pytest.approx([round(0.1 * k, 1) for k in range(0, 40)])  # behind the truck from the start
    assert result.occlusion.episode_key.tolist() == [PAIR]  # the truck itself is seen by both


def test_the_cutting_car_is_responsible_and_owes_its_response_from_exposure(audits):
    result, without, _ = audits
    episode = result.episodes.set_index("episode_key").loc[PAIR]
    assert (episode.vehicle_a, episode.trigger, episode.responsible) == ("cutter", "lat", "a")
    assert (episode.owed_a, episode.owed_b) == ("lat:brake", "lat:brake")
    broken = result.violations[result.violations.episode_key == PAIR].set_index("constraint")
    assert broken.vehicle_id.tolist() == ["cutter", "cutter"]  # the follower, keeping its lane, complied
    # Hidden from t_b to exposure at 1.167 m/s sideways (3.5 m in 3 s) > occluded_lat_speed_ms = 1 m/s.
    hidden = broken.loc[OCCLUSION_CONSTRAINT]
    assert (hidden.t_start_s, hidden.t_end_s) == (pytest.approx(3.7), pytest.approx(3.9))
    assert hidden.bound == 1.0 and hidden.worst_actual == pytest.approx(3.5 / 3.0)
    # Its lateral response starts at exposure (4.0 s), not at t_b (3.7 s): broken 0.3 s later than without rule 4.
    late = broken.loc["lat-speed-envelope"].t_start_s
    early = without.violations.query("episode_key == @PAIR and constraint == 'lat-speed-envelope'").t_start_s
    assert early.tolist() == [pytest.approx(5.1)] and late == pytest.approx(5.4)
    assert without.episodes.set_index("episode_key").loc[PAIR].responsible == "a"
    assert without.occlusion is None and len(result.collisions) == len(without.collisions) == 0


def test_a_batch_report_counts_the_hidden_cut_in_and_rule_5_as_off(tmp_path):
    """sumo-rss batch of the scenario (6 s, seed 0), then the report's rule 5 / rule 4 table: rule 4 on (the run's
    resolved scenario.toml), one episode hidden at t_b with one unreasonable speed; rule 5 off, not 0."""
    (tmp_path / "batch.toml").write_text(f'[batch]\nscenarios = ["{SCENARIOS / "highway_truck_cut_in.toml"}"]\n'
                                         "seeds = [0]\n")
    proc = run_cli("batch", str(tmp_path / "batch.toml"), "--duration", "6", "--out", str(tmp_path / "out"),
                   "--quiet")
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    table = later_rules_table(rules_on(out, read_batch_csv(out, "batch_summary")), read_batch_csv(out, "collisions"),
                              read_batch_csv(out, "occlusion"), read_batch_csv(out, "violations"))
    assert table.loc["highway_truck_cut_in"].tolist() == [0, OFF, 1, 1, 1]
    proc = run_cli("report", str(out), "--no-views", "--quiet")
    assert proc.returncode == 0 and "rule 4: episodes that began hidden" in (out / "report.html").read_text()
