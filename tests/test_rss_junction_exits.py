"""A car leaving a junction with its rear still in a conflict area takes part in that area's situations
(rss/junction_exits.py; docs/rss.md, Junctions). Hand-built snapshots on the shipped intersection_priority network."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, ParamResolver
from sumo_rss.rss.formulas import lon_reach
from sumo_rss.rss.junction_exits import leaving_entries
from sumo_rss.rss.params import RssParams
from sumo_rss.sim.snapshot import WorldSnapshot

NET = NETWORKS / "intersection_priority" / "intersection_priority.net.xml"
V = 13.89  # [m/s] the crossing car's speed, kept


@pytest.fixture(scope="module")
def network() -> RoadNetwork:
    return RoadNetwork.from_file(NET)


def _snapshot(t: float, w_pos: float, s_enter: float) -> WorldSnapshot:
    """w stands with its front bumper ``w_pos`` [m] onto J_E (eastbound, y = -1.6, the lane begins at x = 7.2) after
    the straight link W_in -> J_E; s drives north on S_in (x = 1.6, the lane ends at y = -7.2) at V towards the
    straight link S_in -> J_N, ``s_enter`` [m] from the conflict area J:7x10 (which begins 4.2 m into its link)."""
    to_line = s_enter - V * t - 4.2
    return WorldSnapshot(
        time=t, ids=np.array(["s", "w"]), x=np.array([1.6, 7.2 + w_pos]), y=np.array([-7.2 - to_line, -1.6]),
        heading=np.array([0.5 * np.pi, 0.0]), speed=np.array([V, 0.0]), accel=np.zeros(2), lat_speed=np.zeros(2),
        length=np.full(2, 5.0), width=np.full(2, 1.8), lane_id=np.array(["S_in_0", "J_E_0"]),
        edge_id=np.array(["S_in", "J_E"]), lane_index=np.zeros(2, int), lane_pos=np.array([292.8 - to_line, w_pos]),
        lat_pos=np.zeros(2), vclass=np.array(["background"] * 2), vtype=np.array(["car"] * 2),
        signals=np.zeros(2, int), route_index=np.zeros(2, int), route_edges=(("S_in", "J_N"), ("J_E",)))


def test_the_leaving_car_is_placed_on_the_link_its_rear_is_on(network):
    """w's rear bumper is 5 m behind its front: at x = 2.7 on the straight link W_in -> J_E (14.4 m), the link
    nearest of the three into J_E_0 (the right turn from S_in and the left turn from N_in end there too); its
    front is at 14.4 + 0.5 m along that link. A car wholly on its exit lane is no entry."""
    junctions = JunctionModel.from_file(NET, network)
    snap = _snapshot(0.0, 0.5, 60.0)
    rows, links, pos = leaving_entries(snap, network.lane_indices(snap.lane_id), snap.lane_pos, network, junctions)
    assert rows.tolist() == [1]
    link = junctions.links[links[0]]
    assert (network.lane_ids[link.from_lane], network.lane_ids[link.to_lane]) == ("W_in_0", "J_E_0")
    assert pos[0] == pytest.approx(14.9)
    whole = _snapshot(0.0, 5.5, 60.0)
    assert leaving_entries(whole, network.lane_indices(whole.lane_id), whole.lane_pos, network, junctions)[0].size == 0


@pytest.mark.parametrize("w_pos, expected", [(0.5, True), (1.0, False)])
def test_a_car_crossing_behind_a_leaving_car_that_still_stands_in_the_area_owes_the_yield(network, w_pos, expected):
    """J:7x10 spans [7.4, 10.2] m of w's link (priority: the main road) and [4.2, 7.0] m of s's. w, 0.5 m onto its
    exit lane, has its rear at 14.9 - 5 = 9.9 m: 0.3 m of it still in the area, standing (its latest exit never
    comes). s is D(13.89) + λ + 0.3 = 13.89 + 1.75 + 17.39²/8 + 0.3 m from the area at 0 s: able to stop; at 0.1 s
    it is 1.39 m nearer (margin -1.09 m): dangerous, t_b = 0.1 s, the yielding s owes braking, keeps its speed and
    is responsible from t_b + ρ + 0.1 s = 1.2 s; w owes nothing. With w 1.0 m onto its lane its rear (at 10.4 m) has
    left the area: no episode (before the fix neither case had one)."""
    p = RssParams()
    need = float(lon_reach(V, p, p.lon_brake_min)) + p.min_lon_gap
    auditor = Auditor(network, ParamResolver("ad_rss"), signal_rule=False)
    for k in range(17):
        auditor.observe(_snapshot(round(0.1 * k, 2), w_pos, need + 0.3))
    result = auditor.finish()
    if not expected:
        assert result.episodes.empty
        return
    (episode,) = result.episodes.itertuples()
    assert (episode.conflict_area, episode.t_b_s, episode.trigger, episode.owed_a, episode.owed_b,
            episode.responsible) == ("J:7x10", 0.1, "able-to-stop", "int:brake-min", "", "a")
    assert episode.min_lon_margin_m == pytest.approx(0.3 - 1.6 * V, abs=1e-6)
    (violation,) = result.violations.itertuples()
    assert (violation.vehicle_id, violation.constraint, violation.bound, violation.t_start_s) == \
        ("s", "lon-brake-after-response-time", -4.0, 1.2)
