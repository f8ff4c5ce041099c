"""Persons on crossings as road users (rss.md §10 (i)): hand-made FCDs on a zebra and on the signalised crossing
of intersection_tls_peds, with hand-worked danger thresholds and blame."""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from dataclasses import replace

from conftest import NETWORKS, SCENARIOS
from sumo_rss import load_scenario
from sumo_rss.batch.runner import param_resolver
from sumo_rss.road.build import build_network
from sumo_rss.road.crossings import CrossingModel
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, CollisionInput, ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info
from sumo_rss.sim.session import Session

ZEBRA_SRC = Path(__file__).parent / "data" / "zebra"
PEDS_NET = NETWORKS / "intersection_tls_peds" / "intersection_tls_peds.net.xml"
DT = 0.1  # [s] FCD step
WEST_EAST = {"c": ("W_in", "E_out")}  # the car's route: straight on (link 10)
D_CAR = 10.0 + 0.5 * 3.5 + 13.5 ** 2 / (2 * 4.0)  # [m] ad_rss car at 10 m/s: 1 s at 3.5 m/s², then 4 m/s² = 34.53125


@pytest.fixture(scope="module")
def zebra_net(tmp_path_factory) -> Path:
    """tests/data/zebra built: a two-way road through node M (x = 0) with a zebra over its east arm."""
    return build_network(ZEBRA_SRC, tmp_path_factory.mktemp("zebra") / "zebra.net.xml")


def _car(vid: str, x: float, y: float, lane: str, pos: float, speed: float) -> str:
    return (f'<vehicle id="{vid}" type="DEFAULT_VEHTYPE" x="{x:.3f}" y="{y:.3f}" angle="90.00" speed="{speed:.3f}" '
            f'pos="{pos:.3f}" lane="{lane}" posLat="0.00" acceleration="0.00" speedLat="0.00"/>')


def _person(pid: str, x: float, y: float, angle: float, speed: float, edge: str) -> str:
    return (f'<person id="{pid}" x="{x:.3f}" y="{y:.3f}" angle="{angle:.2f}" type="DEFAULT_PEDTYPE" '
            f'speed="{speed:.3f}" pos="0.00" edge="{edge}"/>')


def _write_fcd(path: Path, steps: list[tuple[float, list[str]]]) -> Path:
    path.write_text("<fcd-export>" + "".join(f'<timestep time="{t:.2f}">{"".join(users)}</timestep>'
                                             for t, users in steps) + "</fcd-export>\n")
    return path


def _audit(fcd: Path, net: Path, routes: dict[str, tuple[str, ...]] | None = None, **kwargs):
    """audit_fcd of ``fcd`` under ad_rss, with SUMO's vTypes and the vehicles' ``routes`` (edge ids by id)."""
    network = RoadNetwork.from_file(net)
    vehicles = read_vehicle_info(None, net)
    vehicles.routes.update(routes or {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a hand-made FCD without signal states / a net without signals
        return audit_fcd(fcd, network, ParamResolver("ad_rss", vtype_dynamics=vehicles.dynamics), vehicles=vehicles,
                         **kwargs)


def test_the_zebra_crossing_model(zebra_net):
    """The zebra's one crossing area with the eastbound car's link: the whole 3 m internal lane (the crossing strip
    is 3 m wide, x in [-1.5, 1.5]) and, along the crossing from its south end, the 3.2 m car lane; the person has
    priority (SUMO's request: the car's link yields to the crossing's)."""
    network = RoadNetwork.from_file(zebra_net)
    junctions = JunctionModel.from_file(zebra_net, network)
    model = CrossingModel.build(zebra_net, network, junctions)
    assert model.edge_ids.tolist() == [":M_c0"] and model.tls_index.tolist() == [-1]
    east = [k for k in range(len(model)) if network.lane_ids[junctions.links[model.link[k]].from_lane] == "AM_1"]
    assert len(east) == 1 and model.static_priority[east[0]] == -1
    k = east[0]
    assert model.link_start[k] == pytest.approx(0.0, abs=0.2) and model.link_end[k] == pytest.approx(3.0, abs=0.2)
    assert model.cross_start[k] == pytest.approx(0.0, abs=0.2) and model.cross_end[k] == pytest.approx(3.2, abs=0.4)


def test_a_car_that_does_not_yield_at_a_zebra_is_responsible(zebra_net, tmp_path):
    """Car c on AM_1 at a constant 10 m/s from 60 m before the crossing area; person p walks north over the zebra at
    0.5 m/s from its south end, inside the area throughout. The car yields and is able to stop while its distance
    to the area exceeds D = 34.53125 m: 60 − 10 t ≤ D from t = 2.55 s, so the danger threshold is the step 2.6 s.
    It then owes braking at 4 m/s² from t_b + ρ = 3.6 s and does not brake: responsible; the person owes nothing."""
    steps = []
    for k in range(41):
        t = k * DT
        front = -1.5 - (60.0 - 10.0 * t)  # [m] x of the car's front bumper (the area starts at the link's start)
        s = 0.5 * t  # [m] the person along the crossing (from y = -3.2)
        steps.append((t, [_car("c", front, -1.6, "AM_1", front + 100.0, 10.0),
                          _person("p", 0.0, -3.2 + s, 0.0, 0.5, ":M_c0")]))
    result = _audit(_write_fcd(tmp_path / "fcd.xml", steps), zebra_net)
    episodes = result.episodes
    assert len(episodes) == 1
    e = episodes.iloc[0]
    assert (e.vehicle_a, e.class_a, e.vehicle_b, e.class_b) == ("c", "background", "p", "person")
    assert e.situation == "intersection-yield" and e.trigger == "able-to-stop"
    assert e.t_b_s == pytest.approx(2.6) == math.ceil((60.0 - D_CAR - 1e-3) / 10.0 / DT) * DT
    assert e.owed_a == "int:brake-min" and e.owed_b == ""
    assert e.responsible == "a"
    violations = result.violations
    assert violations.vehicle_id.tolist() == ["c"] and violations.vehicle_class.tolist() == ["background"]
    v = violations.iloc[0]
    assert v.constraint == "lon-brake-after-response-time" and v.bound == pytest.approx(-4.0)
    assert 3.6 <= v.t_start_s <= 3.7 + 1e-9 and v.worst_actual == pytest.approx(0.0)
    assert result.params["person/DEFAULT_PEDTYPE"]["response_time"] == 0.5


def _red_light_walk(tmp_path: Path, collide: bool) -> tuple[Path, Path, Path | None]:
    """intersection_tls_peds in the east-west phase (W straight green, the west crossing c3 red): car c on W_in_1 at
    a constant 10 m/s from 40 m before its area with c3; person p walks south over c3 at 1.2 m/s, 4.6 m before
    the car's lane's strip on it; then (``collide``) SUMO reports the car hitting the person at 4.2 s."""
    steps = []
    for k in range(43):
        t = k * DT
        to_area = 40.0 - 10.0 * t  # [m] the car's front bumper to its area on c3, which starts 0.2 m into the link
        front = -10.4 + 0.2 - to_area
        car = _car("c", front, -4.8, "W_in_1", front + 300.0, 10.0) if front <= -10.4 else \
            _car("c", front, -4.8, ":C_10_0", front + 10.4, 10.0)
        s = 5.0 + 1.2 * t  # [m] along c3 from its north end (y = 6.4)
        steps.append((t, [car, _person("p", -8.4, 6.4 - s, 180.0, 1.2, ":C_c3")]))
    fcd = _write_fcd(tmp_path / "fcd.xml", steps)
    states = tmp_path / "tls.xml"
    states.write_text('<tlsStates><tlsState time="0.00" id="C" programID="0" phase="5" state="rrrgGgrrrgGgGrGr"/>'
                      "</tlsStates>")
    collisions = None
    if collide:
        collisions = tmp_path / "collisions.xml"
        collisions.write_text('<collisions><collision time="4.20" type="collision" lane=":C_10_0" pos="2.00" '
                              'collider="c" victim="p" colliderType="DEFAULT_VEHTYPE" victimType="DEFAULT_PEDTYPE" '
                              'colliderSpeed="10.00" victimSpeed="1.20"/></collisions>')
    return fcd, states, collisions


def test_a_person_walking_on_red_into_a_car_that_had_no_chance_is_responsible(tmp_path):
    """The car has priority by the signals (its G over the crossing's r); the person yields. Walking at 1.2 m/s it
    can stop within D = 1.2·0.5 + ½·2·0.5² + 2.2²/(2·2) = 2.06 m, so it is able to stop until its distance to the
    area, 9.6 − 5 − 1.2 t, falls to 2.06 m: t = 2.12 s, the threshold is the step 2.2 s (the car, 18 m away at
    10 m/s, needs 34.5 m: it could not stop, and owes nothing). The person owes braking at 2 m/s² from 2.7 s and
    walks on: responsible, also for the collision that ends the episode."""
    fcd, states, collisions = _red_light_walk(tmp_path, collide=True)
    result = _audit(fcd, PEDS_NET, WEST_EAST, tls_states=states, collisions=collisions)
    episodes = result.episodes
    assert len(episodes) == 1
    e = episodes.iloc[0]
    assert (e.vehicle_a, e.vehicle_b, e.class_b) == ("c", "p", "person")
    assert e.situation == "intersection-priority" and e.conflict_area.startswith("C:10x")
    assert e.t_b_s == pytest.approx(2.2) and e.owed_a == "" and e.owed_b == "int:brake-min"
    assert e.responsible == "b" and bool(e.collision) and e.t_end_s == pytest.approx(4.2)
    v = result.violations
    assert v.vehicle_id.tolist() == ["p"] and v.vehicle_class.tolist() == ["person"]
    assert v.constraint.tolist() == ["lon-brake-after-response-time"] and v.bound.tolist() == [-2.0]
    assert 2.7 <= v.t_start_s.iloc[0] <= 2.8 + 1e-9
    c = result.collisions
    assert c[["collider", "victim", "blamed"]].values.tolist() == [["c", "p", "p"]]


def test_on_green_for_the_person_a_car_that_drives_on_is_responsible(tmp_path):
    """The same walk in the north-south phase: the crossing's G over the car's r gives the person priority. The car
    yields and can stop while 40 − 10 t > D = 34.53 m: the threshold is the step 0.6 s; it drives on at 10 m/s and
    is responsible, the person is not. The pair is evaluated at every step (the audit's pair-steps count it)."""
    fcd, _, _ = _red_light_walk(tmp_path, collide=False)
    states = tmp_path / "tls_green.xml"
    states.write_text('<tlsStates><tlsState time="0.00" id="C" programID="0" phase="0" state="gGgrrrgGgrrrrGrG"/>'
                      "</tlsStates>")
    seen = []
    result = _audit(fcd, PEDS_NET, WEST_EAST, tls_states=states, on_progress=lambda p: seen.append(p.pair_steps))
    e = result.episodes
    assert e.responsible.tolist() == ["a"] and e.t_b_s.tolist() == [pytest.approx(0.6)]
    assert e.owed_a.tolist() == ["int:brake-min"] and e.owed_b.tolist() == [""]
    assert result.violations.vehicle_id.unique().tolist() == ["c"]
    assert seen[-1] == 43  # one situation per step, every step (the car is in the area at 4.2 s, not past it)


def test_utopia_of_the_pedestrian_scenario(tmp_path):
    """The shipped scenario's first 45 s: SUMO's own well-behaved persons (waiting at red, walking on green) are in
    junction situations with the cars, some dangerous, and no person is ever responsible. Where anyone is, it is a
    turning car that owed a person with priority braking and did not brake (SUMO's gap acceptance lets a right-
    or left-turner pass a person RSS says it must wait for: 7 of 136 person episodes in the scenario's 120 s)."""
    spec = replace(load_scenario(SCENARIOS / "intersection_tls_peds.toml"), duration_s=45.0)
    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec), "utopia")
    persons_seen = 0
    with Session(spec) as session:
        while not session.finished:
            snapshot = session.step()
            persons_seen = max(persons_seen, len(snapshot.persons) if snapshot.persons is not None else 0)
            auditor.observe(snapshot, [CollisionInput(c.time, c.collider, c.victim, c.kind)
                                       for c in session.new_collisions])
    result = auditor.finish()
    episodes = result.episodes
    with_person = episodes[(episodes.class_a == "person") | (episodes.class_b == "person")]
    assert persons_seen >= 4 and len(with_person) >= 20
    person_is_a = with_person.class_a == "person"
    person_blamed = (person_is_a & with_person.responsible.isin(["a", "both"])) | \
        (~person_is_a & with_person.responsible.isin(["b", "both"]))
    assert not person_blamed.any(), with_person[person_blamed]
    assert not (result.violations.vehicle_class == "person").any()
    blamed = with_person[with_person.responsible != "none"]
    assert (blamed.owed_a == "int:brake-min").all() and (blamed.class_a != "person").all()  # the cars, owing braking
    assert len(result.collisions) == 0


def test_online_and_offline_audits_agree_with_persons(tmp_path):
    """25 s of the pedestrian scenario audited as it runs and from its FCD (persons as SUMO writes them): the same
    episodes, violations and collisions, with persons in junction situations."""
    spec = replace(load_scenario(SCENARIOS / "intersection_tls_peds.toml"), duration_s=25.0)
    network = RoadNetwork.from_file(spec.net_file)
    online = Auditor(network, param_resolver(spec), "peds")
    run_dir = tmp_path / "run"
    with Session(spec, run_dir, fcd=True) as session:
        while not session.finished:
            snapshot = session.step()
            online.observe(snapshot, [CollisionInput(c.time, c.collider, c.victim, c.kind)
                                      for c in session.new_collisions])
    on = online.finish()
    vehicles = read_vehicle_info([*spec.demand.route_files, run_dir / "routes.rou.xml"], spec.net_file)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the signal states come from the net's (static) program, as SUMO ran it
        off = audit_fcd(run_dir / "fcd.xml", network, param_resolver(spec), vehicles=vehicles,
                        collisions=run_dir / "collisions.xml", run_id="peds")
    assert ((on.episodes.class_a == "person") | (on.episodes.class_b == "person")).sum() >= 3
    for name in ("episodes", "violations", "collisions"):
        assert getattr(on, name).to_csv(index=False) == getattr(off, name).to_csv(index=False), name
