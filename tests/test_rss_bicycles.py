"""Bicycles as road users (rss.md §10): their own parameter row, chosen by SUMO vClass, and class 'bicycle'."""
from __future__ import annotations

import pytest

from conftest import NETWORKS, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.runner import param_resolver
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, ParamResolver
from sumo_rss.rss.fcd import FcdReader, read_vehicle_info
from sumo_rss.rss.params import BICYCLE_PARAMS, PERSON_PARAMS, RssParams
from sumo_rss.sim.session import Session

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
BIKE_LENGTH, CAR_LENGTH = 1.6, 5.0  # [m] SUMO's DEFAULT_BIKETYPE and DEFAULT_VEHTYPE


def _vehicle(vid: str, vtype: str, front_x: float, y: float, lane: str, speed: float) -> str:
    return (f'<vehicle id="{vid}" type="{vtype}" x="{front_x:.2f}" y="{y:.2f}" angle="90.00" '
            f'speed="{speed:.2f}" pos="{front_x:.2f}" lane="{lane}" posLat="0.00" acceleration="0.00" '
            'speedLat="0.00"/>')


def test_bicycles_have_their_own_parameters_and_class(tmp_path):
    """Lane hw0_1: car c at 10 m/s with its front 20 m behind bicycle b's rear (b at 5 m/s). Lane hw0_0, 400 m on:
    bicycle b2 at 5 m/s with its front 5 m behind car c2's rear (c2 at 10 m/s). Hand-worked safe distances:
    - c behind b: c's D = 10·1 + ½·3.5·1² + 13.5²/(2·4) = 34.53125 m; b brakes at most at 4 m/s² (not a car's 8):
      d_min = 34.53125 − 5²/(2·4) = 31.40625 m (with a car's 8 m/s² it would be 32.96875 m);
    - b2 behind c2: b2's D = 5 + ½·1.5 + 6.5²/(2·2) = 16.3125 m (a car's ad_rss row: 5 + 1.75 + 8.5²/8 = 15.78 m);
      d_min = 16.3125 − 10²/(2·8) = 10.0625 m."""
    steps = []
    for k, t in enumerate(("0.00", "0.10")):
        steps.append(f'<timestep time="{t}">' + "".join((
            _vehicle("c", "DEFAULT_VEHTYPE", 100.0 + 1.0 * k, -5.25, "hw0_1", 10.0),
            _vehicle("b", "DEFAULT_BIKETYPE", 100.0 + 20.0 + BIKE_LENGTH + 0.5 * k, -5.25, "hw0_1", 5.0),
            _vehicle("b2", "DEFAULT_BIKETYPE", 500.0 + 0.5 * k, -8.75, "hw0_0", 5.0),
            _vehicle("c2", "DEFAULT_VEHTYPE", 500.0 + 5.0 + CAR_LENGTH + 1.0 * k, -8.75, "hw0_0", 10.0),
        )) + "</timestep>")
    fcd = tmp_path / "fcd.xml"
    fcd.write_text("<fcd-export>" + "".join(steps) + "</fcd-export>\n")
    network = RoadNetwork.from_file(HIGHWAY)
    vehicles = read_vehicle_info(None, HIGHWAY)
    auditor = Auditor(network, ParamResolver("ad_rss", vtype_dynamics=vehicles.dynamics))
    first = None
    for snapshot in FcdReader(fcd, network, vehicles):
        situations = auditor.observe(snapshot)
        first = first or (snapshot, situations)
    snapshot, situations = first
    by_pair = {(str(snapshot.ids[a]), str(snapshot.ids[b])): k for k, (a, b) in enumerate(zip(situations.a,
                                                                                              situations.b))}
    assert set(by_pair) == {("b", "c"), ("b2", "c2")}
    k, k2 = by_pair["b", "c"], by_pair["b2", "c2"]
    assert situations.lon_gap[k] == pytest.approx(20.0) and situations.lon_d_min[k] == pytest.approx(31.40625)
    assert situations.lon_gap[k2] == pytest.approx(5.0) and situations.lon_d_min[k2] == pytest.approx(10.0625)
    result = auditor.finish()
    episodes = result.episodes.set_index("vehicle_a")
    assert episodes.loc["b", "class_a"] == "bicycle" and episodes.loc["b", "class_b"] == "background"
    assert episodes.loc["b2", "class_a"] == "bicycle" and episodes.loc["b2", "responsible"] == "none"
    assert result.params["bicycle/DEFAULT_BIKETYPE"] == BICYCLE_PARAMS.to_dict()


def test_bicycle_and_person_rows_under_each_preset():
    """The bicycle and person rows hold under the car presets; under krauss a bicycle, which SUMO drives with
    Krauss, gets the row of its own vType (ρ = tau, b = decel), a person keeps its row."""
    assert BICYCLE_PARAMS == RssParams(1.0, 1.5, 2.0, 1.5, 4.0, 0.5, 0.5, 0.2)
    assert (PERSON_PARAMS.response_time, PERSON_PARAMS.lon_accel_max, PERSON_PARAMS.lon_brake_min,
            PERSON_PARAMS.lon_brake_max) == (0.5, 2.0, 2.0, 2.0)
    for preset in ("ad_rss", "mobileye_human", "epsilon"):
        assert ParamResolver(preset).get("bicycle", "bike") == BICYCLE_PARAMS
        assert ParamResolver(preset).get("person", "DEFAULT_PEDTYPE") == PERSON_PARAMS
    krauss = ParamResolver("krauss", vtype_dynamics={"bike": (1.4, 3.0)}).get("bicycle", "bike")
    assert (krauss.response_time, krauss.lon_accel_max, krauss.lon_brake_min, krauss.lon_brake_max) == \
        (1.4, 0.0, 3.0, 3.0)
    assert ParamResolver("krauss").get("person", "DEFAULT_PEDTYPE") == PERSON_PARAMS
    # vType overrides still apply to a bicycle's type.
    assert ParamResolver("ad_rss", vtype_overrides={"bike": {"response_time": 0.7}}).get(
        "bicycle", "bike").response_time == 0.7


def test_a_live_run_tells_bicycles_by_their_vclass(tmp_path, valid_scenario):
    """SUMO's bicycles in a session (a route file's vType of vClass bicycle) are class 'bicycle' in the snapshots
    and get the bicycle row; the cars stay 'background'."""
    (tmp_path / "bikes.rou.xml").write_text(
        '<routes><vType id="bike" vClass="bicycle"/><flow id="bikes" type="bike" begin="0" end="10" number="3" '
        'from="hw0" to="hw2" departLane="0"/></routes>')
    valid_scenario["demand"]["route_files"] = ["bikes.rou.xml"]
    valid_scenario["duration_s"] = 12.0
    del valid_scenario["ego"]
    spec = load_scenario(write_scenario(tmp_path, valid_scenario))
    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec))
    classes: dict[str, str] = {}
    with Session(spec) as session:
        while not session.finished:
            snapshot = session.step()
            classes.update(zip(snapshot.ids.tolist(), snapshot.vclass.tolist()))
            auditor.observe(snapshot)
    bikes = {v: c for v, c in classes.items() if v.startswith("bikes.")}
    assert len(bikes) == 3 and set(bikes.values()) == {"bicycle"}
    assert {c for v, c in classes.items() if not v.startswith("bikes.")} == {"background"}
    assert auditor.finish().params["bicycle/bike"] == BICYCLE_PARAMS.to_dict()
