"""A car standing short of a conflict area is held at junctions (a_acc = 0 while it stands), and one that moves off
into danger owes its braking from t_b with no response time (rss/moving_off.py; docs/rss.md, "Standing cars at
junctions"). Hand-built snapshots on the shipped intersection_priority network: s, on the minor road, on the
straight link S_in -> J_N (:J_7_0, northbound at x = 1.6 from y = -7.2), must yield to w on the main road
(W_in -> J_E, eastbound at y = -1.6, W_in ends at x = -7.2). Their area J:7x10 spans [4.2, 7.0] m of s's link and
[7.4, 10.2] m of w's; cars 5 m long, ad_rss parameters (ρ 1 s, a_acc 3.5, b_min 4, b_max 8 m/s², λ 0)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import NETWORKS
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, CollisionInput, ParamResolver
from sumo_rss.rss.formulas import lon_reach
from sumo_rss.rss.params import RssParams
from sumo_rss.sim.snapshot import WorldSnapshot

NET = NETWORKS / "intersection_priority" / "intersection_priority.net.xml"
V = 13.89  # [m/s] w's speed, kept
WAIT = 4.2 - 0.011  # [m] s's front bumper along its link: 0.011 m short of the area, as MoST's car59
MOVE_OFF = 0.4  # [s] s stands until then, then accelerates at A
A = 2.0  # [m/s²]


@pytest.fixture(scope="module")
def network() -> RoadNetwork:
    return RoadNetwork.from_file(NET)


def _snapshot(t: float, w_enter: float, move_off: float) -> WorldSnapshot:
    """s as above, moving off at ``move_off`` [s] (position, speed and acceleration exact); w ``w_enter`` [m] from
    the area at 0 s."""
    moving = max(t - move_off, 0.0)
    s_pos, s_speed, s_accel = WAIT + 0.5 * A * moving ** 2, A * moving, A if moving > 0.0 else 0.0
    w_x = -7.2 + 7.4 - (w_enter - V * t)  # w's front bumper (its link begins at x = -7.2)
    on_link = w_x > -7.2
    return WorldSnapshot(
        time=t, ids=np.array(["s", "w"]), x=np.array([1.6, w_x]), y=np.array([-7.2 + s_pos, -1.6]),
        heading=np.array([0.5 * np.pi, 0.0]), speed=np.array([s_speed, V]), accel=np.array([s_accel, 0.0]),
        lat_speed=np.zeros(2), length=np.full(2, 5.0), width=np.full(2, 1.8),
        lane_id=np.array([":J_7_0", ":J_10_0" if on_link else "W_in_0"]),
        edge_id=np.array([":J_7", ":J_10" if on_link else "W_in"]), lane_index=np.zeros(2, int),
        lane_pos=np.array([s_pos, w_x + 7.2 if on_link else 292.8 + w_x + 7.2]), lat_pos=np.zeros(2),
        vclass=np.array(["background"] * 2), vtype=np.array(["car"] * 2), signals=np.zeros(2, int),
        route_index=np.zeros(2, int), route_edges=(("S_in", "J_N"), ("W_in", "J_E")))


def _audit(network: RoadNetwork, w_enter: float, steps: int, collision_at: float | None = None,
           move_off: float = MOVE_OFF):
    auditor = Auditor(network, ParamResolver("ad_rss"), signal_rule=False)
    for k in range(steps):
        t = round(0.1 * k, 2)
        hit = [CollisionInput(t, "s", "w", "junction")] if collision_at is not None and t == collision_at else []
        auditor.observe(_snapshot(t, w_enter, move_off), hit)
    return auditor.finish()


def test_a_car_standing_at_its_line_that_creeps_into_a_priority_car_is_responsible(network):
    """w is 20 m from the area at 0 s and could not stop before it (D(13.89) = 13.89 + 1.75 + 17.39²/8 = 53.44 m).
    While s stands 0.011 m short of the area it is held: able to stop (D(0) = 0 < 0.011 m), the pair is safe
    (plain ad_rss: D(0) = 1.75 + 3.5²/8 = 3.28 m, dangerous from the first step, both owing braking). At 0.5 s s
    moves at 0.2 m/s (0.01 m on): it cannot stop (D(0.2) = 0.2 + 1.75 + 3.7²/8 = 3.66 m) and w, 13.05 m away, is not
    far enough behind it to stop either: dangerous, t_b 0.5 s, able-to-stop held before, s yields. Its own moving off
    made the danger, so it owes braking at once: from 0.6 s, still accelerating at 2 m/s² instead of braking at
    4 m/s², it violates (not from t_b + ρ = 1.6 s). w may drive on. The collision at 1.2 s is s's."""
    result = _audit(network, 20.0, 13, collision_at=1.2)
    (episode,) = result.episodes.itertuples()
    assert (episode.conflict_area, episode.t_b_s, episode.trigger, episode.owed_a, episode.owed_b,
            episode.responsible, episode.collision) == ("J:7x10", 0.5, "able-to-stop", "int:brake-min", "", "a", True)
    (violation,) = result.violations.itertuples()
    assert (violation.vehicle_id, violation.constraint, violation.bound, violation.worst_actual,
            violation.t_start_s) == ("s", "lon-brake-after-response-time", -4.0, A, 0.6)
    assert result.collisions.blamed.tolist() == ["s"]


def test_a_priority_car_that_arrives_when_the_creeping_car_could_no_longer_stop_must_brake(network):
    """w is 70 m from the area at 0 s. When s moves off (0.5 s: it can no longer stop, as above) w is 63.05 m away
    and could still stop before the area (53.44 m): s is in front of it on the virtual line and the pair stays safe
    by 'in front' (right of way is given, not taken: s has committed while w could still yield). On the virtual line
    w must stay D(13.89) behind s's rear bumper, 5 m behind s's front (d_enter 0.011 - (t - 0.4)²): at 0.8 s the gap
    is 58.89 + 0.15 - 5 = 54.04 m, at 0.9 s 57.50 + 0.24 - 5 = 52.74 m < 53.44 m: t_b 0.9 s, in-front held
    before, the rear car w owes braking; it keeps its speed and violates from t_b + ρ + 0.1 s = 2.0 s. s, the car
    in front, owes nothing."""
    p = RssParams()
    assert float(lon_reach(V, p, p.lon_brake_min)) == pytest.approx(53.44, abs=0.01)
    result = _audit(network, 70.0, 22)
    (episode,) = result.episodes.itertuples()
    assert (episode.t_b_s, episode.trigger, episode.owed_a, episode.owed_b, episode.responsible) == \
        (0.9, "in-front", "", "int:brake-min", "b")
    (violation,) = result.violations.itertuples()
    assert (violation.vehicle_id, violation.constraint, violation.t_start_s) == \
        ("w", "lon-brake-after-response-time", 2.0)


def test_a_car_that_stands_short_of_the_area_while_the_priority_car_passes_is_no_episode(network):
    """s stands 0.011 m short of the area for 2 s while w (20 m away at 0 s, unable to stop) drives through: s is
    able to stop all along, and nobody owes anything (plain ad_rss: an episode from 0 s, both owing braking)."""
    result = _audit(network, 20.0, 21, move_off=10.0)
    assert result.episodes.empty and result.violations.empty
