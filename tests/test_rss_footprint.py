"""A car's footprint across its lane turns with its direction of motion, but no further than SUMO turned its body.

tests/data/a10kw_motorway.net.xml (a 1.2 km stretch of eclipse-sumo's A10 motorway, three lanes). In the DRT run of
the real-network regression a car stood still and changed lanes (SUMO moves it sideways at a standstill and turns
its body by up to ~18°): its motion was wholly sideways, and the footprint turned by 90° took 4.5 m of the lane's
width instead of 1.55 m (lateral gap −3.35 m to the car behind it in its lane).
"""
from __future__ import annotations

import numpy as np
import pytest

from lane_snapshots import LENGTH, WIDTH, road_situations
from sumo_runs import DATA
from sumo_rss.road.network import RoadNetwork

NET = DATA / "a10kw_motorway.net.xml"
TURN = np.radians(18.0)


def test_a_car_changing_lanes_at_a_standstill_takes_the_width_of_its_turned_body():
    """S stands 40 m ahead of R in the same lane, moving right at 0.3 m/s, its body turned 18° (SUMO). Verdict: the
    pair is longitudinally dangerous (R at 20 m/s, 35.5 m behind a standing car: d_min 90.8 m) and laterally
    they overlap by the two bodies across the lane, 0.9 m (R) + 1.55 m (S), less the 0.70 m by which S's centre lies
    left of its front bumper (2.25 m · sin 18°): −1.75 m; a footprint turned by the motion's 90° read −2.45 m."""
    net = RoadNetwork.from_file(NET)
    across_s = 0.5 * (LENGTH * np.sin(TURN) + WIDTH * np.cos(TURN))
    cars = [("R", "264306385_1", 100.0, 20.0), ("S", "264306385_1", 140.0, 0.0)]
    turned = road_situations(net, cars, {"S": (0.0, -0.3, -TURN)})
    assert len(turned) == 1
    assert turned.lat_gap[0] == pytest.approx(0.5 * LENGTH * np.sin(TURN) - 0.5 * WIDTH - across_s, abs=0.05)
    sideways = road_situations(net, cars, {"S": (0.0, -0.3, -np.pi / 2)})  # a body SUMO did turn across the lane
    assert sideways.lat_gap[0] == pytest.approx(0.5 * LENGTH - 0.5 * WIDTH - 0.5 * LENGTH, abs=0.05)
    assert turned.dangerous[0]  # R at 20 m/s, 35.5 m behind a standing car: d_min 20 + 1.75 + 23.5²/8 = 90.8 m
