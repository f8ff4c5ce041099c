"""Persons on vehicle lanes (rss.md §10 (ii)): the heading-change wedge, the person without priority. Hand-made FCDs
on the highway (no sidewalks: a person on hw0 walks on the road); lane hw0_0's centre line is y = -8.75, 3.5 m
wide, so with a person 0.478 m wide its strip is |y + 8.75| <= 1.989 m."""
from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from conftest import NETWORKS
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
DT = 0.1  # [s]
HALF_STRIP = 1.75 + 0.5 * 0.478  # [m]


def _fcd(path: Path, steps: int, car_front, person_y, person_speed: float) -> Path:
    """Car c on hw0_0 at 10 m/s (front bumper x = car_front(t)); person p at x = 200 heading north (y =
    person_y(t))."""
    rows = []
    for k in range(steps):
        t = k * DT
        x = car_front(t)
        rows.append(f'<timestep time="{t:.2f}"><vehicle id="c" type="DEFAULT_VEHTYPE" x="{x:.3f}" y="-8.750" '
                    f'angle="90.00" speed="10.000" pos="{x:.3f}" lane="hw0_0" posLat="0.00" acceleration="0.00" '
                    f'speedLat="0.00"/><person id="p" x="200.000" y="{person_y(t):.3f}" angle="0.00" '
                    f'type="DEFAULT_PEDTYPE" speed="{person_speed:.3f}" pos="0.00" edge="hw0"/></timestep>')
    path.write_text("<fcd-export>" + "".join(rows) + "</fcd-export>\n")
    return path


def _audit(fcd: Path):
    vehicles = read_vehicle_info(None, HIGHWAY)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return audit_fcd(fcd, RoadNetwork.from_file(HIGHWAY), ParamResolver("ad_rss", vtype_dynamics=vehicles.dynamics),
                         vehicles=vehicles)


def test_a_person_stepping_onto_the_road_in_front_of_a_car_is_responsible(tmp_path):
    """p walks north at 1.2 m/s from y = -15, 4.261 m short of the strip; it can stop within 1.2·0.5 + ½·2·0.5² +
    2.2²/4 = 2.06 m, so it is able to stop until 4.261 − 1.2 t <= 2.06: the threshold is the step 1.9 s. The car
    (front at 140 + 10 t, 32.8 m short of the wedge then, which needs 34.5 m) has priority and owes nothing; the
    person owes braking from 2.4 s and walks on: onto the strip at 3.55 s, responsible (up to then it could still have
    stopped at its b_max, which a person does within a step: the stay-out rule)."""
    result = _audit(_fcd(tmp_path / "fcd.xml", 45, lambda t: 140.0 + 10.0 * t, lambda t: -15.0 + 1.2 * t, 1.2))
    e = result.episodes
    assert len(e) == 1 and (e.vehicle_a[0], e.vehicle_b[0], e.class_b[0]) == ("c", "p", "person")
    assert e.situation[0] == "intersection-yield" and e.conflict_area[0] == "hw0:jaywalk"
    assert e.t_b_s[0] == pytest.approx(1.9) and e.trigger[0] == "able-to-stop"
    assert e.owed_a[0] == "" and e.owed_b[0] == "int:brake-min" and e.responsible[0] == "b"
    v = result.violations
    assert v.vehicle_id.tolist() == ["p"] and v.constraint.tolist() == ["lon-brake-after-response-time"]
    assert 2.4 <= v.t_start_s[0] <= 2.5 + 1e-9


def test_a_car_that_drives_into_the_wedge_of_a_person_standing_on_its_lane_is_responsible(tmp_path):
    """p stands on lane hw0_0's centre line facing north: its wedge (±45°) covers the strip from x = 200 −
    1.989 m. The car, front at 120 + 10 t, must be able to stop before it (the person is in front on the virtual
    line, as a car standing in a junction): 198.011 − 120 − 10 t <= 34.53 from t = 4.35 s, the threshold 4.4 s; it
    owes braking at 4 m/s² from 5.4 s, keeps its speed and is responsible."""
    result = _audit(_fcd(tmp_path / "fcd.xml", 57, lambda t: 120.0 + 10.0 * t, lambda t: -8.75, 0.0))
    e = result.episodes
    assert len(e) == 1 and e.t_b_s[0] == pytest.approx(4.4) and e.trigger[0] == "in-front"
    assert e.owed_a[0] == "int:brake-min" and e.responsible[0] == "a"
    v = result.violations
    assert v.vehicle_id.tolist() == ["c"] and v.bound.tolist() == [-4.0] and 5.4 <= v.t_start_s[0] <= 5.5 + 1e-9
