"""Gaps along lanes with elevation: SUMO's lane lengths (and positions) include it, a lane's 2-D shape does not.

tests/data/ramp: a straight one-lane road, AB 150 m level, BC climbing 30 m over 60 m (a 50 % grade: 2-D shape
60 m, SUMO's length 67.08 m, ratio 0.894, as on 188 of Monaco's 4,424 lanes below 0.9), CD level at 30 m.
"""
from __future__ import annotations

import libsumo
import numpy as np
import pytest

from sumo_runs import CAR, DATA, build_net, hold_speed, run_sumo
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, ParamResolver
from sumo_rss.rss.fcd import FcdReader, read_vehicle_info

SPEED = 21.0  # [m/s]


@pytest.fixture(scope="module")
def ramp(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ramp")
    net = build_net(DATA / "ramp", folder / "ramp.net.xml")
    sumo_gaps: dict[float, float] = {}

    def setup():
        for vid, pos in (("front", "140"), ("rear", "60")):  # 80 m between the front bumpers, 75.5 m gap
            libsumo.vehicle.add(vid, "r", typeID="car", departPos=pos, departSpeed=str(SPEED))
            hold_speed(vid, SPEED)

    def control(time: float) -> None:
        if time > 0.0:  # SUMO's own gap of the rear car to its leader (it subtracts the rear car's minGap)
            sumo_gaps[round(time, 1)] = libsumo.vehicle.getLeader("rear", 500.0)[1] + 2.5

    run = run_sumo(net, folder, CAR + '<route id="r" edges="AB BC CD"/>', 7.0, setup, control)
    return run, sumo_gaps


def test_sumo_length_and_shape_differ_on_the_ramp_and_positions_convert_both_ways(ramp):
    run, _ = ramp
    net = RoadNetwork.from_file(run.net)
    k = net.lane_indices(["BC_0"])
    assert net.lane_length[k[0]] == pytest.approx(67.08, abs=0.01)
    assert net.shapes.cumulative[k[0], net.shapes.count[k[0]] - 1] == pytest.approx(60.0, abs=0.01)
    lanes = np.repeat(k, 3)
    s = net.shapes.shape_s(lanes, np.array([0.0, 33.54, 67.08]))
    np.testing.assert_allclose(s, [0.0, 30.0, 60.0], atol=0.01)
    np.testing.assert_allclose(net.shapes.lane_pos(lanes, s), [0.0, 33.54, 67.08], atol=1e-9)


def test_the_gap_to_a_car_on_the_ramp_is_sumos_and_the_pair_is_safe(ramp):
    """Both at 21 m/s, 75.5 m apart bumper to bumper while the front car climbs the ramp: d_min = 21 + 1.75 +
    24.5²/8 − 21²/16 = 70.22 m, safe by 5.3 m. Scaled by the ramp's shape/length ratio the gap read 66.8 m (the
    whole distance from the rear car counted as if on the ramp): a spurious episode blamed on the rear car."""
    run, sumo_gaps = ramp
    result = run.audit()
    assert result.episodes.empty
    net = RoadNetwork.from_file(run.net)
    vehicles = read_vehicle_info(run.routes, run.net)
    auditor = Auditor(net, ParamResolver())
    on_ramp = 0
    for snapshot in FcdReader(run.fcd, net, vehicles):
        pairs = auditor.observe(snapshot)
        if len(pairs) and round(snapshot.time, 1) in sumo_gaps:
            assert pairs.lon_gap[0] == pytest.approx(sumo_gaps[round(snapshot.time, 1)], abs=0.01), snapshot.time
            assert pairs.lon_d_min[0] == pytest.approx(70.22, abs=0.01)
            on_ramp += int(snapshot.lane_id[snapshot.ids == "front"][0] == "BC_0")
    assert on_ramp >= 25  # the front car spends 3.2 s on the ramp
