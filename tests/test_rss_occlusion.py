"""Rule 4 — occlusion (docs/rss.md "Rule 4"): the line of sight, and hand-made crossings of intersection_occluded,
whose corners are buildings 8 m off both centre lines (SW building: x, y in [−60, −8] m). The major road runs west to
east along y = −1.6 m (13.89 m/s), the minor one south to north along x = +1.6 m (11.11 m/s, yielding); cars 4.5 x
1.8 m, drivers 1.5 m behind the front bumper; ad_rss parameters (ρ 1 s, a_acc 3.5, b_min 4 m/s²); steps of 0.1 s."""
from __future__ import annotations

import json

import numpy as np
import pytest
import tomllib

from conftest import NETWORKS, SCENARIOS, run_cli, write_scenario
from sumo_rss.errors import ScenarioError, SumoRssError
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import Auditor, CollisionInput, ParamResolver
from sumo_rss.rss.occlusion import OccluderEdges, OcclusionParams, line_of_sight, read_occluders, segment_hits_box
from sumo_rss.sim.snapshot import WorldSnapshot

NET = NETWORKS / "intersection_occluded"
POLY = NET / "intersection_occluded.poly.xml"
LENGTH, WIDTH = 4.5, 1.8
RULE4 = OcclusionParams(enabled=True)


@pytest.fixture(scope="module")
def net() -> RoadNetwork:
    return RoadNetwork.from_file(NET / "intersection_occluded.net.xml")


def _place(vid: str, front: float) -> tuple[str, str, float, float, float, float]:
    """(lane id, edge id, lane position [m], x, y [m], heading [rad]) of car ``vid`` ('fast...' drives west to east,
    'minor...' south to north) whose front bumper is ``front`` m along its road from the centre (negative: before)."""
    if vid.startswith("fast"):
        x, y, heading, (incoming, internal, outgoing) = front, -1.6, 0.0, ("W_in", ":J_10", "J_E")
    else:
        x, y, heading, (incoming, internal, outgoing) = 1.6, front, 0.5 * np.pi, ("S_in", ":J_7", "J_N")
    if front < -7.2:
        return f"{incoming}_0", incoming, front + 150.0, x, y, heading
    if front <= 7.2:
        return f"{internal}_0", internal, front + 7.2, x, y, heading
    return f"{outgoing}_0", outgoing, front - 7.2, x, y, heading


def _snapshot(t: float, cars: list[tuple[str, float, float, str, float]]) -> WorldSnapshot:
    """Cars (id, front bumper along its road from the centre [m], speed [m/s], vType, accel [m/s²]) at ``t``
    [s]."""
    n = len(cars)
    placed = [_place(vid, front) for vid, front, *_ in cars]
    routes = tuple(("W_in", "J_E") if c[0].startswith("fast") else ("S_in", "J_N") for c in cars)
    edges = [p[1] for p in placed]
    return WorldSnapshot(
        time=round(t, 6), ids=np.array([c[0] for c in cars]), x=np.array([p[3] for p in placed]),
        y=np.array([p[4] for p in placed]), heading=np.array([p[5] for p in placed]),
        speed=np.array([c[2] for c in cars], dtype=float), accel=np.array([c[4] for c in cars], dtype=float),
        lat_speed=np.zeros(n),
        length=np.full(n, LENGTH), width=np.full(n, WIDTH), lane_id=np.array([p[0] for p in placed]),
        edge_id=np.array(edges), lane_index=np.zeros(n, int), lane_pos=np.array([p[2] for p in placed]),
        lat_pos=np.zeros(n), vclass=np.full(n, "background"), vtype=np.array([c[3] for c in cars]),
        signals=np.zeros(n, int), route_index=np.array([r.index(e) if e in r else -1 for r, e in zip(routes, edges)]),
        route_edges=routes)


def _crossing(net: RoadNetwork, fast_speed: float, fast_start: float, occluded: bool,
              minor_brakes_after: float = np.inf):
    """The fast car from ``fast_start`` m (front bumper, before the centre) at a constant ``fast_speed``; the minor car
    from −26.6 m at 5 m/s, braking at b_min = 4 m/s² at the steps after ``minor_brakes_after`` [s]; until their boxes
    overlap (a collision)."""
    auditor = Auditor(net, ParamResolver("ad_rss"), signal_rule=False, occlusion=RULE4 if occluded else None,
                      occluders=read_occluders([POLY]) if occluded else None)
    ym, v = -26.6, 5.0
    for k in range(80):
        t = round(0.1 * k, 6)
        braking = t > minor_brakes_after + 1e-9
        xf = fast_start + fast_speed * t
        step = _snapshot(t, [("fast", xf, fast_speed, "car", 0.0), ("minor", ym, v, "car", -4.0 if braking else 0.0)])
        contact = 0.7 <= xf <= 2.5 + LENGTH and -2.5 <= ym <= -0.7 + LENGTH
        auditor.observe(step, [CollisionInput(step.time, "fast", "minor", "collision")] if contact else [])
        if contact:
            break
        v_next = max(v - 0.4, 0.0) if round(t + 0.1, 6) > minor_brakes_after + 1e-9 else v
        ym, v = ym + 0.05 * (v + v_next), v_next
    return auditor.finish()


def test_sight_lines_through_buildings_and_tall_vehicles():
    """A 10 x 10 m building from (0, 0): the line (−5, 5) → (15, 5) crosses it, (−5, 12) → (15, 12) passes above it.
    A bus (3.4 m high) with its centre at (50, 0), 12 m along x, stands in the line between cars at (40, 0) and (60,
    0) (drivers 1.5 m behind their fronts at 41.5 and 61.5); a car of 1.5 m in its place does not."""
    edges = OccluderEdges.from_polygons([np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])])
    crossed = edges.crossed(np.array([-5.0, -5.0]), np.array([5.0, 12.0]), np.array([15.0, 15.0]),
                            np.array([5.0, 12.0]))
    assert crossed.tolist() == [True, False]
    snapshot = WorldSnapshot(
        time=0.0, ids=np.array(["a", "bus", "b"]), x=np.array([41.5, 56.0, 61.5]), y=np.zeros(3),
        heading=np.zeros(3), speed=np.zeros(3), accel=np.zeros(3), lat_speed=np.zeros(3),
        length=np.array([4.5, 12.0, 4.5]), width=np.array([1.8, 2.5, 1.8]), lane_id=np.array(["l"] * 3),
        edge_id=np.array(["e"] * 3), lane_index=np.zeros(3, int), lane_pos=np.zeros(3), lat_pos=np.zeros(3),
        vclass=np.full(3, "background"), vtype=np.array(["car", "bus", "car"]), signals=np.zeros(3, int),
        route_index=np.zeros(3, int))
    a, b = np.array([0, 0, 1]), np.array([2, 1, 2])
    assert line_of_sight(snapshot, a, b, np.array([1.5, 3.4, 1.5]), 1.6, None).tolist() == [False, True, True]
    assert line_of_sight(snapshot, a, b, np.array([1.5, 1.5, 1.5]), 1.6, None).tolist() == [True, True, True]


def test_the_grid_finds_every_crossed_edge():
    """Random segments against 200 random triangles: the grid's answer is the brute-force one."""
    rng = np.random.default_rng(7)
    triangles = [rng.uniform(0.0, 500.0, 2) + rng.uniform(-15.0, 15.0, (3, 2)) for _ in range(200)]
    edges = OccluderEdges.from_polygons(triangles)
    ax, ay, bx, by = (rng.uniform(-50.0, 550.0, 500) for _ in range(4))
    brute = np.zeros(500, dtype=bool)
    for tri in triangles:
        for p, q in zip(tri, np.roll(tri, -1, axis=0)):
            brute |= OccluderEdges.from_polygons([np.array([p, q])]).crossed(ax, ay, bx, by)
    assert brute.sum() > 50
    assert (edges.crossed(ax, ay, bx, by) == brute).all()


def test_segment_box_clipping():
    """A box of half sizes 2 x 1 at the origin turned by 90°: spans x in [−1, 1], y in [−2, 2]."""
    hits = segment_hits_box(np.array([-5.0, -5.0, 0.0, 1.5]), np.array([1.9, 2.1, 0.0, -5.0]),
                            np.array([5.0, 5.0, 0.5, 1.5]), np.array([1.9, 2.1, 0.5, 5.0]), 0.0, 0.0, 0.5 * np.pi,
                            2.0, 1.0)
    assert hits.tolist() == [True, False, True, False]


def test_occluder_files_are_checked(tmp_path):
    assert read_occluders([POLY]).count == 4
    other = tmp_path / "other.poly.xml"
    other.write_text('<additional><poly id="p" type="forest" shape="0,0 1,0 1,1"/></additional>')
    assert read_occluders([other]).count == 0  # only buildings by default
    bad = tmp_path / "bad.poly.xml"
    bad.write_text('<additional><poly id="h1" type="building.house" shape="0,0 1,0"/></additional>')
    with pytest.raises(SumoRssError, match=r"bad.poly.xml: <poly id='h1'>: shape: expected three or more points"):
        read_occluders([bad])
    bad.write_text('<additional><poly id="h2" type="building" geo="1" shape="0,0 1,0 1,1"/></additional>')
    with pytest.raises(SumoRssError, match="geo=\"1\": expected network coordinates"):
        read_occluders([bad])


def test_a_car_hidden_at_twice_the_speed_limit_is_responsible(net):
    """The fast car comes from −138.9 m at 27.78 m/s (2 x 13.89), the minor car from −26.6 m at 5 m/s. The pair turns
    dangerous at t_b = 1.6 s, when the minor car, 15.4 m before the conflict area (which begins 3.2 m before the
    centre), can no longer stop in 5·1 + 3.5/2 + 8.5²/8 = 15.78 m (it owes the junction braking). Both are hidden then:
    the sight line from (xf − 1.5, −1.6) to (1.6, ym − 1.5) crosses the SW building's east wall x = −8 at
    y = −1.6 + (ym − 1.5 + 1.6)(−8 − xf + 1.5)/(1.6 − xf + 1.5): at 3.6 s (xf = −38.89, ym = −8.6) at −8.16 m, inside;
    at 3.7 s (−36.11, −8.1) at −7.64 m, past the corner: exposure 3.7 s. From t_b to 3.6 s (21 hidden steps) the fast
    car's mean speed 27.78 m/s exceeds 1.1 x 13.89 = 15.279 m/s by 12.501: `occluded-unreasonable-speed`; the minor
    car's 5 m/s is within its 8.3 m/s near the area. The minor car brakes at b_min from exposure + ρ = 4.7 s on, as it
    owes, and the two collide at 5.1 s: rule 4 blames the fast car only. Without occlusion the same motions blame the
    minor car, which should have braked from t_b + ρ = 2.6 s (its violation from 2.7 s)."""
    hidden = _crossing(net, 27.78, -138.9, occluded=True, minor_brakes_after=4.7)
    (episode,) = hidden.episodes.itertuples()
    assert (episode.t_b_s, episode.responsible, episode.collision) == (pytest.approx(1.6), "a", True)
    (row,) = hidden.violations.itertuples()
    assert (row.vehicle_id, row.constraint) == ("fast", "occluded-unreasonable-speed")
    assert (row.bound, row.worst_actual, row.excess) == pytest.approx((15.279, 27.78, 12.501))
    assert (row.t_start_s, row.t_end_s) == pytest.approx((1.6, 3.6))
    assert hidden.collisions.blamed.tolist() == ["fast"]
    (occluded,) = hidden.occlusion.itertuples()
    assert (occluded.episode_key, occluded.exposure_a_s, occluded.exposure_b_s, occluded.occluded_at_t_b) == \
        ("fast|minor|x1", pytest.approx(3.7), pytest.approx(3.7), True)
    assert hidden.occluded_pair_steps == 21
    seen = _crossing(net, 27.78, -138.9, occluded=False, minor_brakes_after=4.7)
    assert seen.episodes.responsible.tolist() == ["b"] and seen.occlusion is None
    assert seen.violations[["vehicle_id", "t_start_s"]].values.tolist() == [["minor", pytest.approx(2.7)]]


def test_a_car_hidden_at_the_speed_limit_leaves_the_other_to_respond_from_exposure(net):
    """The fast car at the limit, 13.89 m/s, from −68.75 m; the minor car as above, keeping 5 m/s. t_b = 1.6 s again
    (hidden); the sight line clears the corner between 3.2 s (xf = −24.30, ym = −10.6: it meets the wall at −8.42 m)
    and 3.3 s (−22.91, −10.1: at −7.91 m): exposure 3.3 s. 13.89 ≤ 15.279 m/s: a reasonable speed, no rule-4 row. The
    minor car owes braking from exposure + ρ = 4.3 s, breaks it from the next step, 4.4 s, to the collision at 5.0 s
    (without occlusion: from 2.7 s): it alone is responsible."""
    hidden = _crossing(net, 13.89, -68.75, occluded=True)
    (episode,) = hidden.episodes.itertuples()
    assert (episode.t_b_s, episode.responsible) == (pytest.approx(1.6), "b")
    assert hidden.violations[["vehicle_id", "constraint", "t_start_s", "t_end_s"]].values.tolist() == \
        [["minor", "lon-brake-after-response-time", pytest.approx(4.4), pytest.approx(5.0)]]
    assert hidden.occlusion.exposure_a_s.tolist() == [pytest.approx(3.3)]
    assert hidden.occluded_pair_steps == 17
    seen = _crossing(net, 13.89, -68.75, occluded=False)
    assert seen.violations.t_start_s.tolist() == [pytest.approx(2.7)]


def test_online_and_offline_rule4_audits_of_the_occluded_crossing_agree(tmp_path):
    """30 s of intersection_occluded (its [rss] occluders: the corner buildings), audited online and again offline
    from its FCD with its scenario.toml: the same bytes in every CSV, occlusion.csv included; then without the
    scenario, with --occluders and with --occlusion alone."""
    proc = run_cli("run", str(SCENARIOS / "intersection_occluded.toml"), "--duration", "30", "--out",
                   str(tmp_path / "runs"), "--fcd", "--quiet")
    assert proc.returncode == 0, proc.stderr
    run = tmp_path / "runs" / "intersection_occluded" / "0"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["occluded_pair_steps"] > 0
    assert (run / "occlusion.csv").read_bytes().count(b"\n") > 3
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(NET / "intersection_occluded.net.xml"), "--vtypes",
                   str(run / "routes.rou.xml"), "--collisions", str(run / "collisions.xml"), "--scenario",
                   str(run / "scenario.toml"), "--run-id", "intersection_occluded/0", "--out", str(tmp_path / "off"))
    assert proc.returncode == 0, proc.stderr
    assert "episodes hidden at some step" in proc.stdout
    for name in ("episodes.csv", "violations.csv", "collisions.csv", "occlusion.csv"):
        assert (tmp_path / "off" / name).read_bytes() == (run / name).read_bytes(), name
    # Without the scenario: --occluders turns rule 4 on (and cannot be given with --scenario).
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(NET / "intersection_occluded.net.xml"), "--vtypes",
                   str(run / "routes.rou.xml"), "--occluders", str(POLY), "--out", str(tmp_path / "plain"))
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "plain" / "occlusion.csv").read_bytes().count(b"\n") > 3
    # --occlusion alone: rule 4 with tall road users as the only occluders (no buildings: fewer hidden episodes).
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(NET / "intersection_occluded.net.xml"), "--vtypes",
                   str(run / "routes.rou.xml"), "--occlusion", "--out", str(tmp_path / "tall"))
    assert proc.returncode == 0, proc.stderr
    assert "episodes hidden at some step" in proc.stdout
    assert (tmp_path / "tall" / "occlusion.csv").read_bytes().count(b"\n") < \
        (tmp_path / "plain" / "occlusion.csv").read_bytes().count(b"\n")
    proc = run_cli("audit", str(run / "fcd.xml"), "--net", str(NET / "intersection_occluded.net.xml"),
                   "--scenario", str(run / "scenario.toml"), "--occluders", str(POLY), "--out", str(tmp_path / "x"))
    assert proc.returncode != 0 and "leave out" in proc.stderr and "--occluders" in proc.stderr


def test_scenario_occluders_are_read_relative_to_the_scenario_and_checked(tmp_path):
    data = tomllib.loads((SCENARIOS / "intersection_occluded.toml").read_text())
    data["network"] = str(NET / "intersection_occluded.net.xml")
    data["rss"]["occluders"] = ["buildings.poly.xml"]
    (tmp_path / "buildings.poly.xml").write_bytes(POLY.read_bytes())
    from sumo_rss.scenario import load_scenario

    spec = load_scenario(write_scenario(tmp_path, data))
    assert spec.rss.occlusion.enabled and spec.rss.occlusion.occluders == ((tmp_path / "buildings.poly.xml"),)
    data["rss"]["occluders"] = ["missing.poly.xml"]
    with pytest.raises(ScenarioError, match=r"occluders\[0\].*missing.poly.xml"):
        load_scenario(write_scenario(tmp_path, data))
    data["rss"].update(occluders=[], occlusion=True, occluded_speed_factor=0.5)
    with pytest.raises(ScenarioError, match="occluded_speed_factor"):
        load_scenario(write_scenario(tmp_path, data))


def test_a_truck_between_two_cars_hides_them_from_each_other():
    """Highway lane 1 (y = −5.25 m, 33.33 m/s): `rear` at 400 m, a 12 x 2.5 m truck 3.4 m high at 440 m, `front` at
    470 m (front bumpers), all at 25 m/s. Rear to front: gap 65.5 m < d_min = 25 + 1.75 + 28.5²/8 − 25²/16 = 89.2 m,
    dangerous from the first step (the rear car owes braking after ρ); it keeps its speed. The sight line from
    (398.5, −5.25) to (468.5, −5.25) runs through the truck's box [428, 440] x [−6.5, −4.0]: hidden throughout, so the
    rear car owes `front` nothing (without rule 4: responsible from 1.1 s). Its episode with the truck, which it sees,
    is judged as always. A truck of 1.5 m hides nothing."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")

    def audit(heights: dict[str, float] | None):
        auditor = Auditor(net, ParamResolver("ad_rss"), signal_rule=False,
                          occlusion=RULE4 if heights is not None else None, heights=heights)
        for k in range(21):
            t = round(0.1 * k, 6)
            x = np.array([400.0, 440.0, 470.0]) + 25.0 * t
            auditor.observe(WorldSnapshot(
                time=t, ids=np.array(["rear", "truck", "front"]), x=x, y=np.full(3, -5.25), heading=np.zeros(3),
                speed=np.full(3, 25.0), accel=np.zeros(3), lat_speed=np.zeros(3),
                length=np.array([LENGTH, 12.0, LENGTH]), width=np.array([WIDTH, 2.5, WIDTH]),
                lane_id=np.array(["hw0_1"] * 3), edge_id=np.array(["hw0"] * 3), lane_index=np.ones(3, int),
                lane_pos=x, lat_pos=np.zeros(3), vclass=np.full(3, "background"),
                vtype=np.array(["car", "truck", "car"]), signals=np.zeros(3, int), route_index=np.zeros(3, int),
                route_edges=(("hw0", "hw1", "hw2"),) * 3))
        return auditor.finish()

    def blame(result) -> dict[str, str]:
        return dict(zip(result.episodes.episode_key.str.rsplit("|", n=1).str[0], result.episodes.responsible))

    hidden = audit({"car": 1.5, "truck": 3.4})
    assert blame(hidden)["front|rear"] == "none" and blame(hidden)["rear|truck"] == "a"
    assert hidden.occlusion[["episode_key", "occluded_at_t_b"]].values.tolist() == [["front|rear|1", True]]
    assert np.isnan(hidden.occlusion.exposure_a_s[0]) and hidden.occluded_pair_steps == 21
    seen = audit(None)
    assert blame(seen)["front|rear"] == "b"
    assert seen.violations.query("episode_key == 'front|rear|1'").t_start_s.tolist() == [pytest.approx(1.1)]
    low = audit({"car": 1.5, "truck": 1.5})
    assert blame(low)["front|rear"] == "b" and len(low.occlusion) == 0


def test_hidden_and_exposure_steps_of_a_run_are_those_of_the_sight_lines(net):
    """90 s of intersection_occluded (SUMO traffic, several hidden pairs at once): for every occlusion.csv row, the
    drivers' sight line recomputed on its own from the snapshots is blocked at t_b exactly where `occluded_at_t_b`
    says so, open at the exposure step and blocked at the step before it."""
    from sumo_rss.batch.runner import param_resolver
    from sumo_rss.scenario import load_scenario
    from sumo_rss.sim.session import Session
    from sumo_rss.sim.vtypes import running_heights
    from sumo_rss.rss.occlusion import vtype_heights

    spec = load_scenario(SCENARIOS / "intersection_occluded.toml").with_overrides(duration_s=90.0)
    buildings = read_occluders([POLY])
    snapshots = {}
    with Session(spec) as session:
        heights = running_heights()
        auditor = Auditor(net, param_resolver(spec), occlusion=spec.rss.occlusion, heights=heights,
                          occluders=buildings)
        while not session.finished:
            snapshot = session.step()
            snapshots[round(snapshot.time, 6)] = snapshot
            auditor.observe(snapshot, session.new_collisions)
    rows = auditor.finish().occlusion

    def visible(t: float, a: str, b: str) -> bool:
        snapshot = snapshots[round(t, 6)]
        pair = np.array([snapshot.index_of(a)]), np.array([snapshot.index_of(b)])
        return bool(line_of_sight(snapshot, *pair, vtype_heights(snapshot, heights), 1.6, buildings)[0])

    exposed = rows.dropna(subset=["exposure_a_s"])
    assert rows.occluded_at_t_b.sum() >= 5 and len(exposed) >= 3
    for row in rows.itertuples():
        assert visible(row.t_b_s, row.vehicle_a, row.vehicle_b) == (not row.occluded_at_t_b), row.episode_key
    for row in exposed.itertuples():
        assert visible(row.exposure_a_s, row.vehicle_a, row.vehicle_b), row.episode_key
        assert not visible(row.exposure_a_s - spec.step_s, row.vehicle_a, row.vehicle_b), row.episode_key


def test_a_car_cutting_in_hidden_behind_a_truck_at_a_high_lateral_speed_is_responsible():
    """Highway hw0, all at 25 m/s: `keeper` in lane 1 (y = −5.25 m) at 400 m, a 12 x 2.5 m truck 3.4 m high in lane 2
    (y = −1.75 m) at 420.5 m, `cutter` in lane 2 at 430 m moving right at 1.5 m/s into lane 1 (front bumpers). The
    cutter is 25.5 m ahead of the keeper, inside d_min 89.2 m: dangerous from 0 s (the keeper owes braking after ρ).
    In the truck's frame the sight line runs from (398.5, −5.25) to (428.5, −1.66 − 1.5t) (the cutter's driver,
    turned by its lateral motion) and meets the truck's far end x = 420.5 at y = −5.25 + (3.59 − 1.5t)·22/30: −2.95 m
    at 0.3 s, inside the box's side y ≥ −3.0, and −3.06 m at 0.4 s, clear: exposure 0.4 s. Over the 4 hidden steps
    the cutter's mean lateral speed 1.5 m/s exceeds the reasonable 1.0 m/s (its 25 m/s along the lane is within 1.1 x
    33.33): responsible. The keeper owes braking from exposure + ρ = 1.4 s and keeps its speed: a violation from 1.5 s
    (with a low truck: from 1.1 s, and the cutter is not responsible)."""
    net = RoadNetwork.from_file(NETWORKS / "highway" / "highway.net.xml")

    def audit(truck_height: float):
        auditor = Auditor(net, ParamResolver("ad_rss"), signal_rule=False, occlusion=RULE4,
                          heights={"car": 1.5, "truck": truck_height})
        for k in range(21):
            t = round(0.1 * k, 6)
            offset = max(-1.5 * t, -3.5)  # the cutter's, from lane 2's centre
            lane = np.array([1, 2, 2 if offset > -1.75 else 1])
            lat = np.array([0.0, 0.0, -1.5 if offset > -3.5 else 0.0])
            x = np.array([400.0, 420.5, 430.0]) + 25.0 * t
            auditor.observe(WorldSnapshot(
                time=t, ids=np.array(["keeper", "truck", "cutter"]), x=x, y=np.array([-5.25, -1.75, -1.75 + offset]),
                heading=np.arctan2(lat, 25.0), speed=np.full(3, 25.0), accel=np.zeros(3), lat_speed=lat,
                length=np.array([LENGTH, 12.0, LENGTH]), width=np.array([WIDTH, 2.5, WIDTH]),
                lane_id=np.array([f"hw0_{k}" for k in lane]), edge_id=np.array(["hw0"] * 3), lane_index=lane,
                lane_pos=x, lat_pos=np.array([0.0, 0.0, offset if offset > -1.75 else offset + 3.5]),
                vclass=np.full(3, "background"), vtype=np.array(["car", "truck", "car"]), signals=np.zeros(3, int),
                route_index=np.zeros(3, int), route_edges=(("hw0", "hw1", "hw2"),) * 3))
        result = auditor.finish()
        return result, result.violations.query("episode_key == 'cutter|keeper|1'")

    hidden, rows = audit(3.4)
    assert hidden.episodes.set_index("episode_key").responsible["cutter|keeper|1"] == "both"
    assert rows[["vehicle_id", "constraint", "bound", "worst_actual", "t_start_s", "t_end_s"]].values.tolist() == [
        ["cutter", "occluded-unreasonable-speed", 1.0, pytest.approx(1.5), 0.0, pytest.approx(0.3)],
        ["keeper", "lon-brake-after-response-time", -4.0, 0.0, pytest.approx(1.5), pytest.approx(2.0)]]
    assert hidden.occlusion.exposure_a_s.tolist() == [pytest.approx(0.4)]
    seen, rows = audit(1.5)
    assert seen.episodes.set_index("episode_key").responsible["cutter|keeper|1"] == "b"
    assert rows[["vehicle_id", "t_start_s"]].values.tolist() == [["keeper", pytest.approx(1.1)]]
