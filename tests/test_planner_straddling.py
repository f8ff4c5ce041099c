"""An ego half-way between two lanes (on the highway net: hw0's lanes at y = -8.75 / -5.25 / -1.75, 3.5 m apart;
the frame's s runs along +x): which lane it plans from, and how its footprint meets the target lane's cars.
Found on the ramp (merge_onramp seed 16): pulling out from standstill the ego turns ~28°; SUMO put it on the
motorway lane by its front bumper while its centre was still on the acceleration lane, the barrier held it
there, and the motorway cars in the simulation drove through its nose, so every policy collided."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sumo_rss.planner.behavior.forward_sim import Rollouts, SimSettings, Vehicles, simulate
from sumo_rss.planner.epsilon import EpsilonPlanner
from sumo_rss.planner.lanes import CURRENT, LEFT
from sumo_rss.rss import formulas
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.sim.snapshot import WorldSnapshot

HEADING = 0.49  # [rad] the ego's heading against its lane, pulling out from standstill
LENGTH, WIDTH = 4.7, 1.8


def _ego_snapshot(centre_y: float, sumo_lane: str) -> WorldSnapshot:
    one, zero = np.ones(1), np.zeros(1)
    x = 300.0 + 0.5 * LENGTH * np.cos(HEADING)  # SUMO reports the front bumper
    y = centre_y + 0.5 * LENGTH * np.sin(HEADING)
    return WorldSnapshot(time=10.0, ids=np.array(["ego"]), x=np.array([x]), y=np.array([y]), heading=HEADING * one,
                         speed=zero, accel=zero, lat_speed=zero, length=LENGTH * one, width=WIDTH * one,
                         lane_id=np.array([sumo_lane]), edge_id=np.array(["hw0"]),
                         lane_index=np.array([int(sumo_lane[-1])]), lane_pos=np.array([x]), lat_pos=zero,
                         vclass=np.array(["ego"]), vtype=np.array(["car"]), signals=np.zeros(1, int),
                         route_index=np.zeros(1, int), route_edges=(("hw0", "hw1", "hw2"),))


@pytest.mark.parametrize("centre_y, planned", [(-4.0, "hw0_1"), (-3.3, "hw0_2")])
def test_the_ego_plans_from_the_lane_nearest_its_centre_not_the_lane_under_its_front_bumper(highway, centre_y,
                                                                                           planned):
    """epsilon.md §2.5 step 4: the ego's lane is its nearest lane. Its front bumper is over the line into hw0_2
    (SUMO's lane, boundary at y = -3.5) in both cases; the centre decides."""
    net, _ = highway
    snap = _ego_snapshot(centre_y, "hw0_2")
    assert snap.y[0] > -3.5  # the bumper is in hw0_2
    lane, frame = EpsilonPlanner(net, ParamResolver()).planning_lane(snap, 0)
    assert lane == int(net.lane_indices([planned])[0])
    assert lane in frame.chains.lanes[frame.chains.chain_of[CURRENT]]


def _stopped_ego_and_follower(gap: float, follower_speed: float):
    """The ego stopped at s = 200 with its centre 0.79 m left of its lane's centre, turned by HEADING: its
    front-left corner is 0.79 + 0.5·(4.7·sin + 1.8·cos) = 2.6 m left, 0.85 m into the left lane, whose car (1.8 m
    wide, at its centre 3.5 m left) would just touch it. That car comes up behind, ``gap`` m bumper to bumper."""
    s = np.array([200.0, 200.0 - 0.5 * (LENGTH + 4.5) - gap])
    return Vehicles(s, np.array([0.79, 3.5]), np.array([HEADING, 0.0]), np.array([0.0, follower_speed]), np.zeros(2),
                    np.zeros(2), np.array([LENGTH, 4.5]), np.full(2, WIDTH), np.array([CURRENT, LEFT]))


def test_a_car_behind_stops_for_an_ego_sticking_into_its_lane(highway):
    """The left lane's car sees the ego as its leader (its body is in the way, though its centre is 2.7 m from
    the lane's centre line) and stops behind it: the rollout is valid. It used to drive into the ego's nose."""
    _, frame = highway
    p = RssParams()
    vehicles = _stopped_ego_and_follower(40.0, 15.0)
    rollouts = Rollouts(np.full((1, 5), CURRENT), np.zeros(1), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 15.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    assert sim.valid[0]  # without the ego as its leader it keeps 15 m/s and hits it after ~2.7 s
    bumper_gap = sim.s[0, :, 0] - sim.s[0, :, 1] - 0.5 * (LENGTH + 4.5)
    assert np.all(np.diff(sim.speed[0, :, 1]) <= 1e-9) and sim.speed[0, -1, 1] < 2.0 and bumper_gap.min() > 1.0


def test_the_barrier_does_not_hold_an_ego_whose_footprint_is_already_in_the_target_lane(highway):
    """Across the lane the turned ego takes up 4.7·sin + 1.8·cos = 3.62 m, not its 1.8 m width: it is already in
    the way of the left lane's car closing in behind (lon-unsafe: 10 m where 15.8 m are needed), which stops for
    it, so the cut-in rule no longer holds it half-way in that car's lane (it used to: by the centres' offset and
    widths the pair was laterally safe, and the ego stood there for the rest of the run). It moves on into the
    lane."""
    _, frame = highway
    p = RssParams()
    vehicles = _stopped_ego_and_follower(10.0, 5.0)
    assert not formulas.is_safe_distance(10.0, formulas.lon_safe_distance_same_dir(5.0, 0.0, p, p))
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 5.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    assert sim.barrier_steps[0] == 0
    assert sim.speed[0, -1, 0] > 1.0 and sim.d[0, -1, 0] > 2.5
    assert sim.valid[0]


def test_an_upright_ego_short_of_the_line_is_still_held(highway):
    """The same ego straight in its lane (0.79 m left of the centre, 1.8 m wide: 0.81 m from the follower's
    body) is laterally safe to it, so the cut-in rule holds it back while the pair is lon-unsafe."""
    _, frame = highway
    p = RssParams()
    vehicles = replace(_stopped_ego_and_follower(10.0, 5.0), heading=np.zeros(2))
    rollouts = Rollouts(np.full((1, 5), LEFT), np.array([20.0]), np.ones(1), np.zeros(1, bool), 4.2,
                        np.array([[1, LEFT]]), np.array([0.0, 5.0]))
    sim = simulate(frame, vehicles, rollouts, (1.0,) * 5, SimSettings(), p, RssParamArrays.stack([p] * 2))
    assert sim.barrier_steps[0] > 0
