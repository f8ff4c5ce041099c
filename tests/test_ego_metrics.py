"""sumo_rss.report.ego_metrics on the real highway_exit network: where the acceptance's free-flow check sees a lane
end ahead of the ego."""
from __future__ import annotations

import pytest

from conftest import NETWORKS
from sumo_rss.report.ego_metrics import _clear_ahead
from sumo_rss.road.network import RoadNetwork

TO_RAMP = ("ex_in", "ex_decel", "ex_ramp")
STRAIGHT_ON = ("ex_in", "ex_decel", "ex_main")


@pytest.fixture(scope="module")
def net() -> RoadNetwork:
    return RoadNetwork.from_file(NETWORKS / "highway_exit" / "highway_exit.net.xml")


def _lane(net: RoadNetwork, lane_id: str) -> int:
    return int(net.lane_indices([lane_id])[0])


def test_a_through_lane_beside_the_exit_ends_for_an_ego_that_must_leave_by_the_ramp(net):
    lane = _lane(net, "ex_decel_3")
    end = float(net.lane_length[lane])
    # 50 m before the deceleration lane's end, a 60 m reach: the lane leaves the ego's route there.
    assert not _clear_ahead(net, lane, end - 50.0, 60.0, 30.0, TO_RAMP)
    assert _clear_ahead(net, lane, end - 50.0, 40.0, 30.0, TO_RAMP)  # the end is beyond the reach
    # Going straight on, the same lane continues onto ex_main (33.33 m/s): clear.
    assert _clear_ahead(net, lane, end - 50.0, 60.0, 30.0, STRAIGHT_ON)


def test_the_ramp_lane_is_clear_up_to_the_routes_end(net):
    decel = _lane(net, "ex_decel_0")
    end = float(net.lane_length[decel])
    # onto the ramp (22.22 m/s): clear for a target at its limit, not for a faster one.
    assert _clear_ahead(net, decel, end - 50.0, 60.0, 22.22, TO_RAMP)
    assert not _clear_ahead(net, decel, end - 50.0, 60.0, 30.0, TO_RAMP)
    ramp = _lane(net, "ex_ramp_0")
    # near the ramp's end the route ends: the ego arrives, nothing ends ahead of it.
    assert _clear_ahead(net, ramp, float(net.lane_length[ramp]) - 10.0, 60.0, 22.22, TO_RAMP)
