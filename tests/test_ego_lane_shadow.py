"""A placed ego's lane change leaves no obstacle behind (sim/ego.py LaneShadows): libsumo on the highway net's
straight hw0 with ``--lanechange.duration 3``, as the runs use it."""
from __future__ import annotations

import libsumo
import pytest

from conftest import NETWORKS
from sumo_rss.sim import ego as ego_actuation
from sumo_rss.trajectory import TrajectoryState

ROUTES = """<routes><vType id="car" length="4.7" width="1.9"/><route id="r" edges="hw0 hw1"/>
<vehicle id="ego" type="car" route="r" depart="0" departLane="1" departPos="100" departSpeed="0"/>
<vehicle id="follower" type="car" route="r" depart="0" departLane="1" departPos="60" departSpeed="0"/>
</routes>"""
LANE_1_Y, LANE_0_Y = -5.25, -8.75  # [m] lane centres (3.5 m lanes, the edge's left border at y = 0)


def _follower_after_the_ego_changes(tmp_path, shadows: bool) -> float:
    """The ego stands with its front bumper at x = 100 m and moves over from lane 1 to lane 0 in ten 0.1 s steps
    (its body over both lanes meanwhile); the follower sets off in lane 1 from 60 m. Its lane position [m] after 23 s."""
    routes = tmp_path / "r.rou.xml"
    routes.write_text(ROUTES)
    libsumo.start(["sumo", "-n", str(NETWORKS / "highway" / "highway.net.xml"), "-r", str(routes), "--step-length",
                   "0.1", "--lanechange.duration", "3", "--no-step-log", "true", "--no-warnings", "true"])
    try:
        libsumo.simulationStep()
        ego_actuation.take_control("ego")
        libsumo.vehicle.setLaneChangeMode("follower", 0)
        tracker = ego_actuation.LaneShadows("ego")
        ys = [LANE_1_Y] * 5 + [LANE_1_Y - 0.35 * k for k in range(1, 11)] + [LANE_0_Y] * 215
        for y in ys:
            if shadows:
                tracker.before_placing()
            ego_actuation.place("ego", TrajectoryState(100.0, y, 0.0, 0.0, 0.0))
            libsumo.simulationStep()
        assert libsumo.vehicle.getLaneID("ego") == "hw0_0"
        assert libsumo.vehicle.getLateralLanePosition("ego") == pytest.approx(0.0, abs=1e-6)
        return libsumo.vehicle.getLanePosition("follower")
    finally:
        libsumo.close()


def test_the_lane_a_placed_ego_left_is_free_for_the_cars_behind(tmp_path):
    # SUMO alone keeps the ego in lane 1 for the follower, which stops 2.5 m (its minGap) behind where the ego's
    # rear was and stands there, though the ego has been in lane 0 for 21 s (SUMO 1.28). If this fails, SUMO no
    # longer does that and LaneShadows may go.
    assert _follower_after_the_ego_changes(tmp_path, shadows=False) == pytest.approx(100.0 - 4.7 - 2.5, abs=0.1)
    assert _follower_after_the_ego_changes(tmp_path, shadows=True) > 400.0  # passed at ~31 m/s
