"""RSS audit speed: our vectorised auditor against Intel's ad_rss (PyPI ``ad-rss`` 5.0.0) driven per pair.

Figures (recorded under ``rss_vs_adrss``):
1. raw same-direction formula on 1,000,000 random pairs [pairs/s] (target >= 50 M/s);
2-3. full audit (candidates + situations + responsibility) of a synthetic 500-vehicle highway, 200 steps of 0.1 s
   [pair-steps/s] (target >= 2 M/s); the same with RSS rules 5 (evasive effort) and 4 (occlusion, its trucks 3.4 m
   high) on, against the rules off, alternately in CPU seconds (the machine is shared): both rules' pair-steps/s
   (issue 50's target >= 2 M/s) and their time ratio to the rules off;
4. the same same-direction situations through ad_rss's RssSituationChecking + RssResponseResolving (a Python
   loop per pair: that is how ad_rss is used from Python), the speed ratio (target >= 50x) and verdict agreement;
5. highway_dense co-simulated with and without auditing every step [real-time factors].
"""
from __future__ import annotations

import sys
import time
import timeit
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402

from sumo_rss import load_scenario  # noqa: E402
from sumo_rss.batch.runner import param_resolver  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.auditor import Auditor, ParamResolver  # noqa: E402
from sumo_rss.rss.formulas import lon_safe_distance_same_dir  # noqa: E402
from sumo_rss.rss.occlusion import OcclusionParams  # noqa: E402
from sumo_rss.rss.params import PARAM_NAMES, EvasiveParams, RssParamArrays, RssParams  # noqa: E402
from sumo_rss.sim.session import Session  # noqa: E402
from sumo_rss.sim.snapshot import BACKGROUND_CLASS, WorldSnapshot  # noqa: E402

FORMULA_PAIRS = 1_000_000
N_VEHICLES, N_STEPS, STEP_S = 500, 200, 0.1
ADRSS_STEPS = 20  # ad_rss is measured on the first steps only (it is slow); its checkers need consecutive steps
LANE_WIDTH_M, LANE_CHANGE_SPEED_MS, LANE_CHANGE_PROB = 3.5, 1.17, 3e-4  # 3.5 m in 3 s; per vehicle and step
CHAINS = [[f"hw0_{k}", f":h1_0_{k}", f"hw1_{k}", f":h2_0_{k}", f"hw2_{k}"] for k in range(3)]  # lane index k
# The synthetic world's trucks have their own RSS parameters (cars: ad_rss's defaults), so the comparison with
# ad_rss tells a rear car's response time and braking from a front car's.
HEIGHTS = {"car": 1.5, "truck": 3.4}  # [m] SUMO's defaults of the passenger and truck vClasses (rule 4's occluders)
TRUCK_RSS = {"response_time": 1.5, "lon_accel_max": 2.0, "lon_brake_min": 3.5, "lon_brake_min_correct": 3.0,
             "lon_brake_max": 6.0}


def world_params() -> ParamResolver:
    return ParamResolver(vtype_overrides={"truck": TRUCK_RSS})


# 1. Raw formula
def random_params(rng: np.random.Generator, n: int) -> RssParamArrays:
    """Per-pair random but valid parameters (b_corr <= b_min <= b_max)."""
    b_corr = rng.uniform(2.0, 4.0, n)
    b_min = b_corr + rng.uniform(0.0, 2.0, n)
    values = dict(response_time=rng.uniform(0.2, 2.0, n), lon_accel_max=rng.uniform(0.0, 4.0, n),
                  lon_brake_min=b_min, lon_brake_min_correct=b_corr, lon_brake_max=b_min + rng.uniform(0, 4, n),
                  lat_accel_max=rng.uniform(0.1, 1.0, n), lat_brake_min=rng.uniform(0.5, 2.0, n),
                  lat_fluctuation_margin=rng.uniform(0.0, 0.5, n), min_lon_gap=rng.uniform(0.0, 2.0, n),
                  max_speed_on_accel=rng.uniform(30.0, 100.0, n))
    return RssParamArrays(**{name: values[name] for name in PARAM_NAMES})


def measure_formula() -> dict:
    """lon_safe_distance_same_dir on 1 M random pairs, per-pair parameters (and one shared set), best of 5."""
    rng = np.random.default_rng(0)
    v_rear, v_front = rng.uniform(0.0, 40.0, FORMULA_PAIRS), rng.uniform(0.0, 40.0, FORMULA_PAIRS)
    p_rear, p_front = random_params(rng, FORMULA_PAIRS), random_params(rng, FORMULA_PAIRS)
    per_pair = min(timeit.repeat(lambda: lon_safe_distance_same_dir(v_rear, v_front, p_rear, p_front), number=1,
                                 repeat=5))  # best of 5 [s]
    shared = min(timeit.repeat(lambda: lon_safe_distance_same_dir(v_rear, v_front, RssParams(), RssParams()),
                               number=1, repeat=5))
    rate = FORMULA_PAIRS / per_pair
    return {"formula_pairs_per_s": rate, "formula_target_50M": bool(rate >= 50e6),
            "formula_pairs_per_s_one_param_set": FORMULA_PAIRS / shared}


# 2. Synthetic 500-vehicle highway
def synthetic_world(net: RoadNetwork, seed: int = 1) -> tuple[list[WorldSnapshot], float]:
    """200 snapshots of 500 vehicles on the shipped 3-lane highway, a ring: who drives off hw2 re-enters hw0;
    and the mean initial gap [m] bumper to bumper (the ring length fixes it: ~11 m, not 15, for 500 vehicles).

    Each vehicle has a chain position S [m, lane-length units] of its front bumper, a lateral position y [m]
    from lane 0's centre line (lane = round(y / 3.5)), a speed v [m/s] and a desired speed (lane 0: 20-25,
    1: 24-29, 2: 28-33 m/s). Per step: random smoothed acceleration towards the desired speed, capped so the
    gap to the leader in the same lane closes to 2 m at most over 2 s (braking <= 8 m/s²); rare lane changes
    at 1.17 m/s.
    """
    rng = np.random.default_rng(seed)
    chain_lanes = np.array([net.lane_indices(np.array(c)) for c in CHAINS])  # [3 lane indices, 5 segments]
    starts = np.concatenate([np.zeros((3, 1)), np.cumsum(net.lane_length[chain_lanes], axis=1)], axis=1)
    ring_m = float(starts[:, -1].min())
    lane = np.arange(N_VEHICLES) % 3
    truck = (lane == 0) & (rng.random(N_VEHICLES) < 0.3)  # ~10% trucks, kept right
    length, width = np.where(truck, 12.0, 4.5), np.where(truck, 2.5, 1.8)
    s_pos = np.zeros(N_VEHICLES)
    for k in range(3):  # fill each lane: random gaps (>= 2 m) that add up to the ring
        rows = np.flatnonzero(lane == k)
        spare = ring_m - length[rows].sum() - 2.0 * len(rows)
        gaps = 2.0 + spare * rng.dirichlet(np.full(len(rows), 2.0))
        s_pos[rows] = np.cumsum(gaps + length[rows])
    v_des = np.where(truck, rng.uniform(20.0, 24.0, N_VEHICLES), rng.uniform(20.0, 25.0, N_VEHICLES) + 4.0 * lane)
    v, accel, y = v_des.copy(), np.zeros(N_VEHICLES), lane * LANE_WIDTH_M
    target = lane.copy()
    ids = np.array([f"v{i:03d}" for i in range(N_VEHICLES)])
    snapshots = []
    for step in range(N_STEPS):
        lane = np.clip(np.rint(y / LANE_WIDTH_M), 0, 2).astype(int)
        # Leader in the same lane (ring): gap bumper to bumper [m].
        order = np.lexsort((s_pos, lane))
        nxt = np.roll(order, -1)
        group_end = np.r_[lane[order][1:] != lane[order][:-1], True]
        group_first = order[np.searchsorted(lane[order], lane[order])]
        leader = np.empty(N_VEHICLES, dtype=int)
        leader[order] = np.where(group_end, group_first, nxt)
        gap = np.mod(s_pos[leader] - length[leader] - s_pos, ring_m)
        wish = np.clip(0.9 * accel + rng.normal(0.0, 0.2, N_VEHICLES) + 0.1 * (v_des - v), -3.0, 2.0)
        v_new = np.minimum(v + wish * STEP_S, v[leader] + (gap - 2.0) / 2.0)
        v_new = np.clip(np.maximum(v_new, v - 8.0 * STEP_S), 0.0, 36.0)  # brake at most 8 m/s²
        accel, v = (v_new - v) / STEP_S, v_new
        s_pos = np.mod(s_pos + v * STEP_S, ring_m)
        # Lane changes: start rarely, move at 1.17 m/s until on the target lane's centre line.
        idle = (target == lane) & (np.abs(y - lane * LANE_WIDTH_M) < 1e-9)
        start = idle & (rng.random(N_VEHICLES) < LANE_CHANGE_PROB)
        target = np.where(start, np.clip(lane + rng.choice([-1, 1], N_VEHICLES), 0, 2), target)
        v_lat = np.sign(target * LANE_WIDTH_M - y) * LANE_CHANGE_SPEED_MS
        y = np.where(np.abs(target * LANE_WIDTH_M - y) <= LANE_CHANGE_SPEED_MS * STEP_S, target * LANE_WIDTH_M,
                     y + v_lat * STEP_S)
        snapshots.append(_snapshot(net, chain_lanes, starts, step * STEP_S, ids, s_pos, y, v, v_lat, accel,
                                   length, width, truck))
    return snapshots, (3 * ring_m - length.sum()) / N_VEHICLES


def _snapshot(net, chain_lanes, starts, t, ids, s_pos, y, v, v_lat, accel, length, width, truck) -> WorldSnapshot:
    """WorldSnapshot from chain positions: front-bumper centre on the lane shape plus the lateral offset; heading
    from the rear to the front bumper along the lane (as SUMO computes it) turned by the lateral motion."""
    k = np.clip(np.rint(y / LANE_WIDTH_M), 0, 2).astype(int)
    seg = np.clip((starts[k] <= s_pos[:, None]).sum(axis=1) - 1, 0, chain_lanes.shape[1] - 1)
    lane = chain_lanes[k, seg]
    lane_pos = s_pos - starts[k, seg]
    lat_pos = y - k * LANE_WIDTH_M
    scale = net.shapes.cumulative[lane, net.shapes.count[lane] - 1] / net.lane_length[lane]  # SUMO's pos → shape
    front = _on_lane(net.shapes, lane, lane_pos * scale, lat_pos)
    rear = _on_lane(net.shapes, lane, (lane_pos - length) * scale, lat_pos)  # extrapolated before the lane start
    chord = np.arctan2(front[:, 1] - rear[:, 1], front[:, 0] - rear[:, 0])
    n = len(ids)
    return WorldSnapshot(
        time=round(t, 3), ids=ids, x=front[:, 0], y=front[:, 1], heading=chord + np.arctan2(v_lat, v),
        speed=v.copy(), accel=accel.copy(), lat_speed=v_lat.copy(), length=length, width=width,
        lane_id=net.lane_ids[lane], edge_id=net.edge_ids[net.lane_edge[lane]], lane_index=k, lane_pos=lane_pos,
        lat_pos=lat_pos, vclass=np.full(n, BACKGROUND_CLASS), vtype=np.where(truck, "truck", "car"),
        signals=np.zeros(n, dtype=int), route_index=np.full(n, -1), route_edges=None)


def _on_lane(shapes, lane: np.ndarray, s: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Points [n, 2] at distance ``s`` [m] along lanes' shapes (the end segments extended) and ``offset`` [m]
    to the left of them."""
    cum = shapes.cumulative[lane]
    i = np.clip((cum <= s[:, None]).sum(axis=1) - 1, 0, shapes.count[lane] - 2)
    p0, p1 = shapes.points[lane, i], shapes.points[lane, i + 1]
    direction = (p1 - p0) / np.linalg.norm(p1 - p0, axis=1)[:, None]
    normal = np.column_stack([-direction[:, 1], direction[:, 0]])
    return p0 + (s - cum[np.arange(len(lane)), i])[:, None] * direction + offset[:, None] * normal


# 3. Our audit
def measure_audit(net: RoadNetwork, snapshots: list[WorldSnapshot]) -> tuple[dict, list]:
    """Best of 3 fresh auditors over all snapshots; also returns the first steps' PairSituations for ad_rss."""
    best, kept = None, []
    for _ in range(3):
        auditor, kept = Auditor(net, world_params()), []  # only what ad_rss needs (200 steps: ~0.7 GB)
        started = time.perf_counter()
        for snapshot in snapshots:
            situations = auditor.observe(snapshot)
            if len(kept) < ADRSS_STEPS:
                kept.append(situations)
        wall = time.perf_counter() - started
        if best is None or wall < best[0]:
            best = (wall, auditor.pair_steps)
    wall, pair_steps = best
    return {"audit_pair_steps_per_s": pair_steps / wall, "audit_ms_per_step": 1e3 * wall / len(snapshots),
            "pairs_per_step": pair_steps / len(snapshots), "vehicles_per_step": N_VEHICLES, "steps": len(snapshots),
            "audit_target_2M": bool(pair_steps / wall >= 2e6)}, kept


def measure_later_rules(net: RoadNetwork, snapshots: list[WorldSnapshot], repeats: int = 3) -> dict:
    """The audit of ``snapshots`` with rules 5 and 4 on against the rules off, alternately ``repeats`` times each, in
    CPU seconds of this process; the fastest of each kept."""
    best = {"off": np.inf, "both": np.inf}
    pair_steps = 0
    for _ in range(repeats):
        for mode in best:
            on = mode == "both"
            auditor = Auditor(net, world_params(), evasive=EvasiveParams(enabled=True) if on else None,
                              occlusion=OcclusionParams(enabled=True) if on else None, heights=HEIGHTS)
            started = time.process_time()
            for snapshot in snapshots:
                auditor.observe(snapshot)
            auditor.finish()
            best[mode] = min(best[mode], time.process_time() - started)
            pair_steps = auditor.pair_steps
    both = pair_steps / best["both"]
    return {"audit_rules_off_cpu_pair_steps_per_s": pair_steps / best["off"],
            "audit_both_rules_pair_steps_per_s": both, "audit_both_rules_time_ratio": best["both"] / best["off"],
            "audit_both_rules_target_2M": bool(both >= 2e6)}


# 4. ad_rss, per pair
def measure_adrss(net: RoadNetwork, snapshots: list[WorldSnapshot], situations: list, ours_per_s: float) -> dict:
    """ad_rss's RssSituationChecking + RssResponseResolving on our same-direction pairs, step after step.

    ad_rss is ego-centric: one checker per ego vehicle (it remembers each constellation's last safe state, so
    ``time_index`` increases every step), fed one RssSituationSnapshot with one RelativeConstellation per pair
    (ego = car a, object = car b, our gaps and speeds in ad_rss's conventions), then resolved into the ego's
    ProperResponse. Per-vehicle states are built once per step and copied into each pair (a fair use of ad_rss).
    """
    sys.path.insert(0, str(REPO / "tests"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # boost.python: a converter registered twice
        import ad_rss
        from adrss_oracle import _dynamics, _state  # every field filled (defaults are NaN, rss.md §7)
    core, state = ad_rss.rss.core, ad_rss.rss.state
    core.setLogLevel("error")  # ad_rss logs every dangerous state at info level
    resolver, checkers, responder = world_params(), {}, core.RssResponseResolving()
    agreement, pairs, library_s, checking_s = Agreement(), 0, 0.0, 0.0
    started = time.perf_counter()
    for step, (snap, sit) in enumerate(zip(snapshots, situations)):
        params = [resolver.get(c, t) for c, t in zip(snap.vclass, snap.vtype)]
        states = [_state(p, 0.0, 0.0) for p in params]  # speeds are set per pair (reference lane's frame)
        rows = np.flatnonzero(sit.kind == 0)
        rows = rows[np.argsort(sit.a[rows], kind="stable")]
        for a, group in _groups(sit.a[rows], rows):
            request = core.RssSituationSnapshot()
            request.time_index = step + 1
            request.default_ego_vehicle_rss_dynamics = _dynamics(params[a])
            for r in group:
                request.constellations.append(_constellation(ad_rss, sit, r, states[a], states[sit.b[r]]))
            checker = checkers.setdefault(a, core.RssSituationChecking())
            result, response = state.RssStateSnapshot(), state.ProperResponse()
            t0 = time.perf_counter()
            if not (checker.checkSituation(request, result) and responder.provideProperResponse(result, response)):
                raise RuntimeError(f"ad_rss refused step {step}, ego row {a} (its log is on stdout)")
            t1 = time.perf_counter()
            library_s += t1 - t0
            for r, rss in zip(group, result.individual_responses):
                agreement.add(step, snap, sit, r, rss)
            checking_s += time.perf_counter() - t1  # our comparison, not a use of ad_rss: not timed
            pairs += len(group)
    wall = time.perf_counter() - started - checking_s
    ratio = ours_per_s * wall / pairs
    return {"adrss_mode": "situation-checking+response", "adrss_steps": len(situations), "adrss_pair_steps": pairs,
            "adrss_pair_steps_per_s": pairs / wall, "adrss_time_in_library_share": library_s / wall,
            "adrss_library_only_pair_steps_per_s": pairs / library_s,  # inside ad_rss calls only: an upper bound
            "ratio_ours_vs_adrss": ratio, "ratio_target_50x": bool(ratio >= 50),
            "ratio_ours_vs_adrss_library_only": ours_per_s * library_s / pairs, **agreement.figures(pairs)}


class Agreement:
    """ad_rss's verdicts and safe distances against ours, pair by pair."""

    def __init__(self) -> None:
        self.lon = self.lat = 0
        self.lon_diff_m = self.lat_diff_m = 0.0
        self.first_lon_disagreement: dict | None = None

    def add(self, step: int, snap: WorldSnapshot, sit, r: int, rss) -> None:
        """Compare pair ``r`` of ``sit`` with ad_rss's RssState ``rss`` of it."""
        assert rss.object_id == sit.b[r], "ad_rss reordered the constellations"
        lon = rss.longitudinal_state
        d_min = lon.rss_state_information.safe_distance.mDistance
        self.lon += lon.is_safe == sit.lon_safe[r]
        self.lat += (rss.lateral_state_left.is_safe and rss.lateral_state_right.is_safe) == sit.lat_safe[r]
        self.lon_diff_m = max(self.lon_diff_m, abs(d_min - float(sit.lon_d_min[r])))
        if sit.lat_gap[r] > 0:  # ad_rss evaluates the side facing the other car
            side = rss.lateral_state_right if sit.a_is_left[r] else rss.lateral_state_left
            lat_d_min = side.rss_state_information.safe_distance.mDistance
            self.lat_diff_m = max(self.lat_diff_m, abs(lat_d_min - float(sit.lat_d_min[r])))
        if lon.is_safe != sit.lon_safe[r] and self.first_lon_disagreement is None:
            self.first_lon_disagreement = {
                "step": step, "a": str(snap.ids[sit.a[r]]), "b": str(snap.ids[sit.b[r]]),
                "lon_gap_m": float(sit.lon_gap[r]), "ours_d_min_m": float(sit.lon_d_min[r]), "adrss_d_min_m": d_min}

    def figures(self, pairs: int) -> dict:
        return {"lon_verdict_agreement": float(self.lon / pairs), "lat_verdict_agreement": float(self.lat / pairs),
                "lon_d_min_max_abs_diff_m": self.lon_diff_m, "lat_d_min_max_abs_diff_m": self.lat_diff_m,
                "first_lon_disagreement": self.first_lon_disagreement}


def _groups(keys: np.ndarray, rows: np.ndarray):
    """(key, rows) for each run of equal ``keys`` (sorted)."""
    for chunk in np.split(np.arange(len(keys)), np.flatnonzero(np.diff(keys)) + 1):
        if chunk.size:
            yield int(keys[chunk[0]]), rows[chunk]


def _constellation(ad_rss, sit, r: int, state_a, state_b):
    """ad_rss RelativeConstellation of same-direction pair ``r`` (ego = a); gaps are clamped at 0 (overlap)."""
    core, phys = ad_rss.rss.core, ad_rss.physics
    lon_pos, lat_pos = core.LongitudinalRelativePosition, core.LateralRelativePosition
    c = core.RelativeConstellation()
    c.constellation_type = ad_rss.rss.world.ConstellationType.SameDirection
    c.ego_id, c.object_id, c.constellation_id = int(sit.a[r]), int(sit.b[r]), int(sit.b[r])
    c.ego_state = _with_speed(state_a, sit.v_lon_a[r], sit.v_lat_a[r], phys)
    c.other_state = _with_speed(state_b, sit.v_lon_b[r], sit.v_lat_b[r], phys)
    rel, gap, lat = c.relative_position, float(sit.lon_gap[r]), float(sit.lat_gap[r])
    rel.longitudinal_distance, rel.lateral_distance = phys.Distance(max(gap, 0.0)), phys.Distance(max(lat, 0.0))
    if sit.a_is_rear[r]:
        rel.longitudinal_position = lon_pos.AtBack if gap > 0 else lon_pos.OverlapBack
    else:
        rel.longitudinal_position = lon_pos.InFront if gap > 0 else lon_pos.OverlapFront
    if sit.a_is_left[r]:
        rel.lateral_position = lat_pos.AtLeft if lat > 0 else lat_pos.OverlapLeft
    else:
        rel.lateral_position = lat_pos.AtRight if lat > 0 else lat_pos.OverlapRight
    return c


def _with_speed(template, v_lon: float, v_lat: float, phys):
    """Copy of a vehicle's RelativeObjectState with exact speeds; ad_rss lateral speed is + = right."""
    s = type(template)(template)
    vel, lon = s.structured_object_state.velocity, phys.Speed(float(v_lon))
    vel.speed_lon_min = vel.speed_lon_max = s.unstructured_object_state.speed_range.minimum = lon
    s.unstructured_object_state.speed_range.maximum = lon
    vel.speed_lat_min = vel.speed_lat_max = phys.Speed(-float(v_lat))
    return s


# 5. highway_dense co-simulation with auditing
def measure_cosim() -> dict:
    """highway_dense twice: SUMO alone (with snapshots, as in sim_speed.py), then auditing every step."""
    spec = load_scenario(REPO / "scenarios" / "highway_dense.toml")
    started = time.perf_counter()
    with Session(spec) as session:
        while not session.finished:
            session.step()
    sim_only_s = time.perf_counter() - started
    auditor = Auditor(RoadNetwork.from_file(spec.net_file), param_resolver(spec))
    audit_s = step_s = 0.0
    started = time.perf_counter()
    with Session(spec) as session:
        while not session.finished:
            t0 = time.perf_counter()
            snapshot = session.step()
            t1 = time.perf_counter()
            auditor.observe(snapshot)
            step_s, audit_s = step_s + t1 - t0, audit_s + time.perf_counter() - t1
    total_s = time.perf_counter() - started
    simulated, steps = session.steps * spec.step_s, session.steps
    return {"highway_dense_sim_rtf": simulated / sim_only_s, "highway_dense_audit_rtf": simulated / total_s,
            "highway_dense_audit_ms_per_step": 1e3 * audit_s / steps,
            # SUMO's step (incl. the snapshot) alone vs. interleaved with the audit (GC and cache pressure)
            "highway_dense_sim_ms_per_step": 1e3 * sim_only_s / steps,
            "highway_dense_sim_ms_per_step_when_audited": 1e3 * step_s / steps,
            "highway_dense_pairs_per_step": auditor.pair_steps / session.steps,
            "highway_dense_peak_vehicles": session.peak_vehicles}


def main() -> None:
    options = arguments(__doc__, "rss_vs_adrss.py")
    figures = measure_formula()
    net = RoadNetwork.from_file(REPO / "networks" / "highway" / "highway.net.xml")
    snapshots, mean_gap_m = synthetic_world(net)
    figures["world_mean_gap_m"] = mean_gap_m
    audit, situations = measure_audit(net, snapshots)
    figures.update(audit)
    figures.update(measure_later_rules(net, snapshots))
    figures.update(measure_adrss(net, snapshots[:ADRSS_STEPS], situations, audit["audit_pair_steps_per_s"]))
    figures.update(measure_cosim())
    record("rss_vs_adrss", figures, options)
    f = figures
    print(f"formula   {f['formula_pairs_per_s'] / 1e6:8.1f} M pairs/s (target 50 M: {f['formula_target_50M']})")
    print(f"audit     {f['audit_pair_steps_per_s'] / 1e6:8.2f} M pair-steps/s, {f['audit_ms_per_step']:.1f} ms/step, "
          f"{f['pairs_per_step']:.0f} pairs/step (target 2 M: {f['audit_target_2M']})")
    print(f"rules 5+4 {f['audit_both_rules_pair_steps_per_s'] / 1e6:8.2f} M pair-steps/s (CPU), "
          f"{f['audit_both_rules_time_ratio']:.2f}x the rules off ({f['audit_rules_off_cpu_pair_steps_per_s'] / 1e6:.2f} "
          f"M pair-steps/s; target 2 M: {f['audit_both_rules_target_2M']})")
    print(f"ad_rss    {f['adrss_pair_steps_per_s'] / 1e3:8.1f} k pair-steps/s ({f['adrss_mode']}); ours is "
          f"{f['ratio_ours_vs_adrss']:.0f}x faster (target 50x: {f['ratio_target_50x']})")
    print(f"agreement lon {f['lon_verdict_agreement']:.6f}, lat {f['lat_verdict_agreement']:.6f}, "
          f"max |d_min diff| lon {f['lon_d_min_max_abs_diff_m']:.1e} m, lat {f['lat_d_min_max_abs_diff_m']:.1e} m")
    print(f"ad_rss library calls alone {f['adrss_library_only_pair_steps_per_s'] / 1e3:.1f} k pair-steps/s "
          f"({100 * f['adrss_time_in_library_share']:.0f}% of its time; ours "
          f"{f['ratio_ours_vs_adrss_library_only']:.0f}x faster)")
    print(f"highway_dense: sim {f['highway_dense_sim_rtf']:.0f}x, sim+audit {f['highway_dense_audit_rtf']:.0f}x real "
          f"time, audit {f['highway_dense_audit_ms_per_step']:.2f} ms/step, {f['highway_dense_pairs_per_step']:.0f} "
          f"pairs/step")


if __name__ == "__main__":
    main()
