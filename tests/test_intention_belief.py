"""LearnedBelief: the network's belief where lanes branch, with the memory of past positions and signals."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from sumo_rss.planner.intention.belief import LearnedBelief
from sumo_rss.planner.intention.estimator import load_estimator
from sumo_rss.planner.intention.features import BLINKER_LEFT, HISTORY_STEPS
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import networks_root
from sumo_rss.sim.snapshot import WorldSnapshot


def _net(name: str) -> RoadNetwork:
    return RoadNetwork.from_file(networks_root() / name / f"{name}.net.xml")


def _snapshot(time, ids, xs, ys, headings, speeds, lanes, signals):
    n = len(ids)
    f = np.zeros(n)
    return WorldSnapshot(time=time, ids=np.array(ids), x=np.asarray(xs, float), y=np.asarray(ys, float),
                         heading=np.asarray(headings, float), speed=np.asarray(speeds, float), accel=f, lat_speed=f,
                         length=np.full(n, 4.5), width=np.full(n, 1.8), lane_id=np.array(lanes),
                         edge_id=np.array([lane.rsplit("_", 1)[0] for lane in lanes]), lane_index=np.zeros(n, int),
                         lane_pos=f, lat_pos=f, vclass=np.array(["background"] * n), vtype=np.array(["car"] * n),
                         signals=np.asarray(signals, int), route_index=np.zeros(n, int))


@pytest.fixture(scope="module")
def estimator():
    loaded = load_estimator()
    assert loaded is not None
    return loaded


def test_the_memory_interpolates_the_past_and_extrapolates_before_it(estimator):
    belief = LearnedBelief(_net("highway"), estimator)
    for k in range(11):  # 'a' drives east at 10 m/s from x = 100 for 1 s; its left blinker is on from 0.8 s
        t = 0.1 * k
        belief.observe(_snapshot(t, ["a"], [100.0 + 10.0 * t], [-5.25], [0.0], [10.0], ["hw0_1"],
                                 [BLINKER_LEFT if t >= 0.8 - 1e-9 else 0]))
    now = _snapshot(1.0, ["a", "b"], [110.0, 300.0], [-5.25, -1.75], [0.0, 0.0], [10.0, 20.0], ["hw0_1", "hw0_2"],
                    [BLINKER_LEFT, 0])
    belief.observe(now)
    past_x, past_y, signals = belief._history(now, np.array([0, 1]))
    want = 1.0 - 0.2 * np.arange(HISTORY_STEPS)[::-1]
    np.testing.assert_allclose(past_x[0], 100.0 + 10.0 * want, atol=1e-9)  # before 0 s: straight back at 10 m/s
    np.testing.assert_allclose(past_y[0], -5.25)
    assert signals[0].tolist() == [0] * (HISTORY_STEPS - 2) + [BLINKER_LEFT] * 2
    np.testing.assert_allclose(past_x[1], 300.0 - 20.0 * (1.0 - want), atol=1e-9)  # seen once: straight at 20 m/s
    belief.observe(_snapshot(1.1, ["c"], [0.0], [-5.25], [0.0], [0.0], ["hw0_1"], [0]))  # a and b have left
    assert set(belief._row) == {"c"}
    assert np.isnan(belief._memory[belief._row["c"], :, 0]).sum() == belief._memory.shape[1] - 1  # a fresh row


@pytest.mark.parametrize("hz", [10, 20, 50])
def test_the_memory_spans_the_whole_history_however_often_the_planner_is_called(estimator, hz):
    """A fixed 33 calls covered the 2 s history only up to ~16 Hz: at 20 Hz its oldest points were extrapolated
    although the car had been seen there (y -1.6, -1.6, -1.6, -1.4, ... for -2.0, -1.8, ...), at 50 Hz the first
    seven. 'a' drives north at 10 m/s drifting right at 1 m/s for 3 s."""
    period = 1.0 / hz
    belief = LearnedBelief(_net("highway"), estimator, period=period)
    calls = round(3.0 * hz)
    for k in range(calls + 1):
        t = k * period
        belief.observe(_snapshot(t, ["a"], [100.0 + t], [10.0 * t], [np.pi / 2], [10.0], ["hw0_1"], [0]))
    now_t = calls * period
    now = _snapshot(now_t, ["a"], [100.0 + now_t], [10.0 * now_t], [np.pi / 2], [10.0], ["hw0_1"], [0])
    past_x, past_y, _ = belief._history(now, np.array([0]))
    want = now_t - 0.2 * np.arange(HISTORY_STEPS)[::-1]
    np.testing.assert_allclose(past_x[0], 100.0 + want, atol=1e-9)
    np.testing.assert_allclose(past_y[0], 10.0 * want, atol=1e-9)


def test_an_agent_near_the_end_of_the_acceleration_lane_is_expected_to_merge(estimator):
    net = _net("merge")
    k = int(net.lane_indices(np.array(["mw_merge_0"]))[0])
    a, b = net.shapes.points[k, 0], net.shapes.points[k, 1]
    u = (b - a) / np.linalg.norm(b - a)
    length = float(net.lane_length[k])
    belief = LearnedBelief(net, estimator)
    # Two agents on the acceleration lane, 40 m and 230 m before its end, and one on the motorway beside them.
    xs, ys, lanes = [], [], []
    for s, lane, offset in ((length - 40.0, "mw_merge_0", 0.0), (length - 230.0, "mw_merge_0", 0.0),
                            (length - 100.0, "mw_merge_1", 3.5)):
        p = a + s * u + offset * np.array([-u[1], u[0]])
        xs.append(p[0])
        ys.append(p[1])
        lanes.append(lane)
    heading = float(np.arctan2(u[1], u[0]))
    snap = _snapshot(10.0, ["near", "far", "motorway"], xs, ys, [heading] * 3, [12.0, 25.0, 25.0], lanes,
                     [BLINKER_LEFT, 0, 0])
    belief.observe(snap)
    probs, used = belief.lateral_probabilities(snap, np.arange(3), net.lane_indices(np.array(lanes)))
    assert used.tolist() == [True, True, False]  # the motorway lane does not branch: the rules stay there
    np.testing.assert_allclose(probs[:2].sum(axis=1), 1.0, rtol=1e-6)  # the network's float32 probabilities
    assert probs[0, 1] > 0.9  # left: onto the motorway
    assert probs[0, 2] == 0.0  # there is no lane to the right


def test_the_network_is_used_where_the_turns_are_within_reach_as_in_its_training_data(estimator):
    """On intersection_tls, S_in_0 (straight and right, 289.6 m) has one way ahead for a car 250 m before the
    junction: its candidates (to 128 m ahead) cannot tell the turns apart, so the network, trained only where
    they can, is not asked and the rules stay. 60 m before the junction the turns are within reach."""
    net = _net("intersection_tls")
    k = int(net.lane_indices(np.array(["S_in_0"]))[0])
    a, b = net.shapes.points[k, 0], net.shapes.points[k, net.shapes.count[k] - 1]
    u = (b - a) / np.linalg.norm(b - a)
    length = float(net.lane_length[k])
    xs, ys = zip(*(a + s * u for s in (length - 250.0, length - 60.0)))
    heading = float(np.arctan2(u[1], u[0]))
    snap = _snapshot(10.0, ["far", "near"], xs, ys, [heading] * 2, [13.0, 13.0], ["S_in_0"] * 2, [0, 0])
    belief = LearnedBelief(net, estimator)
    belief.observe(snap)
    probs, used = belief.lateral_probabilities(snap, np.arange(2), net.lane_indices(np.array(["S_in_0"] * 2)))
    assert used.tolist() == [False, True]
    np.testing.assert_allclose(probs[1].sum(), 1.0, rtol=1e-6)  # the network's float32 probabilities


def test_the_planner_loads_the_network_only_on_networks_where_lanes_branch():
    """A network where no lane branches or ends never asks the intention network, so torch is not imported (a
    fresh interpreter: the other tests here import it); merges and junctions get the learned belief."""
    probe = ("import sys; from sumo_rss.planner.epsilon import EpsilonPlanner; from sumo_rss.rss.auditor import "
             "ParamResolver; from sumo_rss.road.network import RoadNetwork; from sumo_rss.scenario import "
             "networks_root; name = sys.argv[1]; planner = EpsilonPlanner(RoadNetwork.from_file(networks_root() / "
             "name / f'{name}.net.xml'), ParamResolver()); print(planner.belief is not None, 'torch' in sys.modules)")
    seen = {}
    for name in ("highway", "merge", "intersection_tls"):
        run = subprocess.run([sys.executable, "-c", probe, name], capture_output=True, text=True, check=True)
        seen[name] = run.stdout.split()
    assert seen == {"highway": ["False", "False"], "merge": ["True", "True"], "intersection_tls": ["True", "True"]}
