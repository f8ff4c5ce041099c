"""Closed-loop multi-agent forward simulation of EUDM (epsilon.md §3), vectorised over rollouts and vehicles.

Every (policy x scenario) rollout of a planning cycle is one row of [rollouts, vehicles] arrays (column 0 is the
ego) advanced together in synchronous (Jacobi) steps: each step computes every vehicle's command from the
states at the start of the step, then commits them all. Vehicles live in the planning frame (:class:`RoadFrame`):
s along the ego's lane chain, d across it, heading relative to it; lanes are offset profiles, so nothing is
projected inside the loop. The reference point is the geometric centre (SUMO gives no axle geometry).

Per step and vehicle: pure pursuit on the tracked lane (its target lane; the ego's lane per layer of its policy),
a leader search on the tracked lane and on the lane the vehicle is in now, ACC/IIDM on the nearer leader (a lane
that ends is a stopped leader at its end), the kinematic bicycle with its limits. The ego's lane-change layers
use the gap-informed controller of §3.5 with the port's fix (the current-lane IDM still applies), the RSS
evasive speed-up and an RSS virtual barrier (RSS's cut-in rule, :func:`lane_change_command`). A rollout whose
ego box (inflated) meets another vehicle's box is invalid from that step on.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ...boxes import boxes_overlap
from ...rss import formulas
from ..lanes import LEFT
from ..road_frame import FrameCells, RoadFrame
from .controllers import BicycleState, IdmParams, VehicleLimits, bicycle_step, idm_speed_command, lookahead, \
    pure_pursuit_steer
from .lane_change import GapCars, lane_change_command
from .leaders import following_distance, hardest_braking, lane_end_leader, leaders_ahead, occupied_band, \
    stopped_leader

NO_LEADER_GAP = 100.0  # [m] a free road is a virtual leader 100 + 100·v ahead at the own speed
_IDM_FIELDS = tuple(IdmParams.__dataclass_fields__)


@dataclass(frozen=True)
class SimSettings:
    """Controller settings of the forward simulation (epsilon.md §3.1, §3.5, §3.6)."""

    ego_idm: IdmParams = IdmParams()
    agent_idm: IdmParams = IdmParams(s0=1.0, headway=0.5, accel=2.0, comfort_brake=1.67, hard_brake=4.0)
    ego_limits: VehicleLimits = VehicleLimits()
    agent_limits: VehicleLimits = VehicleLimits(max_accel=2.0, hard_brake=4.0, accel_jerk=5.0, brake_jerk=4.0,
                                                lat_accel=1.5, lat_jerk=3.0)
    ego_pursuit: tuple[float, float, float] = (2.5, 3.0, 100.0)  # gain [s], min, max look-ahead [m]
    agent_pursuit: tuple[float, float, float] = (1.5, 3.0, 50.0)
    ego_radius: float = 2.2  # [m] lateral search radius around a lane's centre line
    agent_radius: float = 1.25
    gap_speed_gain: float = 0.1  # K_v [1/s] of the gap target speed, clipped to [-3, 5] m/s
    track_pos_gain: float = 0.4  # K_s [1/s]
    track_speed_gain: float = 0.8  # K_v' [1/s], tracking acceleration clipped to ±1 m/s²
    preferred_blend: float = 0.1
    evasive_accel: float = 2.0  # [m/s²] speed-up into the gap when the gap-rear car is RSS-unsafe (IDM a, limit)
    evasive_headway: float = 0.6  # [s] the ego's IDM T while it speeds up
    evasive_extra_speed: float = 10.0  # [m/s] its desired speed: the rear car's RSS-safe minimum plus this
    inflation: float = 0.1  # [m] added to length and width in the strict collision check
    lane_end_margin: float = 20.0  # [m] a lane that ends is a stopped leader this far before its end (room to merge)
    commit_time: float = 1.0  # [s] the gap must stay RSS-safe this long at constant speeds before the ego enters it
    rss_following: bool = True  # the ego's IDM headway distance is at least the RSS safe distance to a car ahead
    gap_informed_changes: bool = True  # the ego's lane changes by EPSILON's controller (False: IDM + pure pursuit)


@dataclass(frozen=True, eq=False)
class Vehicles:
    """Initial states in the planning frame; column 0 is the ego. Arrays of shape [n]."""

    s: np.ndarray
    d: np.ndarray
    heading: np.ndarray  # relative to the frame's centre line [rad]
    speed: np.ndarray
    accel: np.ndarray
    curvature: np.ndarray
    length: np.ndarray
    width: np.ndarray
    chain: np.ndarray  # lane chain each vehicle is on (RIGHT/CURRENT/LEFT)

    def __len__(self) -> int:
        return int(self.s.shape[0])


@dataclass(frozen=True, eq=False)
class Rollouts:
    """What differs between rollouts. ``ego_chain[r, layer]``: the lane the ego tracks in each layer;
    ``ego_v0[r]`` its desired speed, ``ego_spacing_scale[r]`` the factor on its s0 and T (0.75 when
    accelerating); ``ego_backup[r]``: the emergency backup (lane keep, braking at ``backup_brake``);
    ``agent_chain[r, i]`` each agent's target lane, ``agent_v0[i]`` its desired speed; ``ego_speed_limit`` the
    road's speed limit [m/s], which the evasive speed-up does not exceed."""

    ego_chain: np.ndarray  # [R, layers] int
    ego_v0: np.ndarray  # [R]
    ego_spacing_scale: np.ndarray  # [R]
    ego_backup: np.ndarray  # [R] bool
    backup_brake: float
    agent_chain: np.ndarray  # [R, n] int (column 0 unused)
    agent_v0: np.ndarray  # [n]
    ego_speed_limit: float = np.inf


@dataclass(frozen=True, eq=False)
class JunctionArea:
    """The first conflict area of the ego's way through a junction, ``beyond`` [m] past its stop point. While it
    approaches the stop, the ego stays able to stop before the area by RSS (D(v) + λ short of it, rss.md §4, with
    ``params``: its RSS parameters [1] while moving), as it keeps the RSS distance behind a car: a car creeping to
    a stop line that is nearer the area than D(0) would owe braking to every car with priority there."""

    beyond: float
    params: Any


@dataclass(frozen=True, eq=False)
class SimResult:
    """Trajectories at the sample times ``t`` (relative to now, t[0] = 0): arrays [R, T+1, n]."""

    t: np.ndarray  # [T+1]
    layer_end: np.ndarray  # [layers] sample index that ends each layer
    s: np.ndarray
    d: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    ego_accel: np.ndarray  # [R, T+1] the ego's acceleration during the step before each sample [m/s²]
    ego_curvature: np.ndarray  # [R, T+1] [1/m]
    valid: np.ndarray  # [R] no collision of the ego with anyone
    # The ego's leader on its tracked lane (at a layer's last sample: on the lane that layer tracked), a car or a
    # standing obstacle (a lane end, a stop line):
    ego_lead_gap: np.ndarray  # [R, T+1] bumper gap [m] (inf: none)
    ego_lead_speed: np.ndarray  # [R, T+1] [m/s]
    ego_lead_held_gap: np.ndarray  # [R, T+1] that leader's ``cut_in_gap`` [m] (inf: none; see simulate)
    ego_lead_is_car: np.ndarray  # [R, T+1] bool: the leader is a car (not a lane end or a stop line)
    barrier_steps: np.ndarray  # [R] steps the virtual barrier held the ego back
    chain: np.ndarray  # [R, T+1, n] int: the lane chain each vehicle is in at each sample


@dataclass(frozen=True, eq=False)
class _Layer:
    """The inputs of one layer of the tree for its G prefixes (:func:`prefix_tree`); arrays [G, n] unless noted."""

    backup: np.ndarray  # [G] bool: the ego's emergency backup
    tracked: np.ndarray  # int: the lane chain each vehicle tracks (the ego's: this layer's of its policy)
    tracked_cells: np.ndarray  # flat indices of ``tracked`` into [3, G, n] arrays
    v0: np.ndarray  # desired speeds [m/s]
    idm: IdmParams  # fields [G, n]
    idm_flat: np.ndarray  # [IDM fields, G·n]
    ending: np.ndarray | None  # [G] the chain the ego tracked in the layer before (None: the same as now)

    @classmethod
    def of(cls, rollouts: Rollouts, layer: int, first: np.ndarray, v0_of_rollout: np.ndarray,
           idm_of_rollout: np.ndarray) -> _Layer:
        """Layer ``layer`` of the prefixes whose representative rollouts are ``first`` [G]."""
        G, n = first.size, v0_of_rollout.shape[1]
        tracked = rollouts.agent_chain[first].copy()
        tracked[:, 0] = rollouts.ego_chain[first, layer]
        idm = idm_of_rollout[:, first]  # [IDM fields, G, n]
        ending = rollouts.ego_chain[first, layer - 1] if layer > 0 else None
        if ending is not None and np.array_equal(ending, tracked[:, 0]):
            ending = None
        return cls(rollouts.ego_backup[first], tracked, tracked * (G * n) + np.arange(G * n).reshape(G, n),
                   v0_of_rollout[first], IdmParams(*idm), idm.reshape(len(_IDM_FIELDS), G * n), ending)


@dataclass(frozen=True, eq=False)
class _Leaders:
    """One step's leaders: bumper gaps [m] (inf: none) and speeds [m/s] on the tracked lane (``*_t``) and on the
    current lane (``*_c``) [G, n], a lane's end and the ego's stop line taking a car's place where nearer; the cars
    alone on each lane looked at (``free_gaps``, their columns ``leader``, n: none) [looks, G, n]; the ego's
    current-lane leader without the waiting margin before a lane end (``gap_go``, ``v_go`` [G], used once a lane
    change is going); and the ego's leader as its sample records it (``ego_*`` [G])."""

    gap_t: np.ndarray
    v_t: np.ndarray
    gap_c: np.ndarray
    v_c: np.ndarray
    free_gaps: np.ndarray
    leader: np.ndarray
    gap_go: np.ndarray
    v_go: np.ndarray
    now_chain: np.ndarray  # [G, n] the lane chain each vehicle is in
    stop_gap: np.ndarray  # [G] the ego's front bumper to its stop line [m] (inf: none)
    ego_band: np.ndarray  # [G] [m] see :func:`occupied_band`
    ego_gap: np.ndarray
    ego_speed: np.ndarray
    ego_is_car: np.ndarray  # bool: the recorded leader is a car (not a lane end or the stop line)
    ego_leader: np.ndarray  # its column (n: none)


def step_times(durations: tuple[float, ...], sim_step: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample times [s] (from 0) and the sample index ending each layer; each layer is cut into equal steps of
    at most ``sim_step``."""
    times, ends, t = [0.0], [], 0.0
    for duration in durations:
        n = max(1, int(np.ceil(duration / sim_step - 1e-9)))
        for _ in range(n):
            t += duration / n
            times.append(t)
        ends.append(len(times) - 1)
    return np.array(times), np.array(ends)


def _per_vehicle(ego: Any, agent: Any, n: int) -> Any:
    """A parameter dataclass whose fields are [n] arrays: the ego's values in column 0, the agents' after."""
    values = {}
    for name in ego.__dataclass_fields__:
        column = np.full(n, float(getattr(agent, name)))
        column[0] = float(getattr(ego, name))
        values[name] = column
    return type(ego)(**values)


def prefix_tree(rollouts: Rollouts) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The DCP-tree's shared prefixes: rollouts whose inputs agree up to the end of a layer are the same rollout
    until then, so each distinct prefix is simulated once. Per layer: the representative rollout of each
    distinct prefix, the prefix's parent in the previous layer (layer 0: the single initial state) and the
    prefix of every rollout."""
    base = np.column_stack([rollouts.ego_v0, rollouts.ego_spacing_scale, rollouts.ego_backup,
                            rollouts.agent_chain[:, 1:]]).astype(float)
    # Rank of each row among the distinct rows, in lexicographic order (np.unique(axis=0)'s inverse, ~8x faster).
    order = np.lexsort(base.T[::-1])
    ordered = base[order]
    code = np.empty(base.shape[0], dtype=np.int64)
    code[order] = np.cumsum(np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]) - 1
    tree, previous = [], np.zeros(base.shape[0], dtype=np.intp)
    for layer in range(rollouts.ego_chain.shape[1]):
        code = code * (LEFT + 1) + rollouts.ego_chain[:, layer]  # the prefix up to this layer, as one integer
        _, first, inverse = np.unique(code, return_index=True, return_inverse=True)
        tree.append((first, previous[first], inverse))
        previous = inverse
    return tree


def simulate(frame: RoadFrame, vehicles: Vehicles, rollouts: Rollouts, durations: tuple[float, ...],
             settings: SimSettings, rss_ego: Any, rss_agents: Any, sim_step: float = 0.2,
             ego_stop_s: float = np.inf, cut_in_gap: np.ndarray | None = None,
             junction_area: JunctionArea | None = None, owed_brake_due: np.ndarray | None = None) -> SimResult:
    """Run every rollout over the layers ``durations`` [s]. ``rss_ego`` / ``rss_agents`` (RssParams /
    RssParamArrays over all n vehicles) drive the evasive override and the virtual barrier; ``ego_stop_s`` [m] is a
    stop line for the ego's front bumper (a stopped leader there: a red light or a yield line). ``cut_in_gap``
    [n] [m]: per car, a gap the ego keeps to it in place of the RSS distance where that is shorter (inf: none): a
    car that cut in, which the ego owes no longitudinal braking, is followed at the gap it left rather than
    braked for at once. ``junction_area``: the conflict area past the stop line, which the ego approaching the
    line stays able to stop before. ``owed_brake_due`` [n] [s from now]: per car, when the ego's response time
    ends in an open episode in which it owes that car longitudinal braking (inf: none); from then on, while the
    pair is RSS-unsafe, the ego brakes at least at its b_min and does not move off once stopped (rss.md §5, as the
    guard will make it), so the plans contain the braking the guard would otherwise apply as a step. Rollouts
    that share a prefix of the tree are simulated once until they branch (:func:`prefix_tree`)."""
    t, layer_end = step_times(durations, sim_step)
    n_steps, n = t.size - 1, len(vehicles)
    tree = prefix_tree(rollouts)
    cols = np.arange(n)
    agent_idm = _per_vehicle(settings.ego_idm, settings.agent_idm, n)
    limits = _per_vehicle(settings.ego_limits, settings.agent_limits, n)
    evasive_max_accel = np.where(cols == 0, np.maximum(settings.evasive_accel, limits.max_accel), limits.max_accel)
    gain, l_min, l_max = (np.where(cols == 0, e, a) for e, a in zip(settings.ego_pursuit, settings.agent_pursuit))
    length, width = vehicles.length, vehicles.width
    widest_agent = float(width[1:].max()) if n > 1 else 0.0
    box_size = ((length[0] + settings.inflation, width[0] + settings.inflation),  # the collision check's boxes
                (length[1:] + settings.inflation, width[1:] + settings.inflation))
    front_worst = hardest_braking(rss_agents.take(cols[1:])) if settings.rss_following and n > 1 else None
    held_gap = np.full(n + 1, np.inf)  # by leader column; n: no car ahead
    if cut_in_gap is not None:
        held_gap[:n] = cut_in_gap
    holding = bool(np.any(np.isfinite(held_gap)))
    # Per rollout: desired speeds [R, n] and IDM parameters [fields, R, n] (the ego's s0 and T scaled per policy).
    v0_of_rollout = np.tile(np.asarray(rollouts.agent_v0, dtype=float), (len(rollouts.ego_v0), 1))
    v0_of_rollout[:, 0] = rollouts.ego_v0
    idm_of_rollout = _idm_per_rollout(agent_idm, rollouts.ego_spacing_scale, n)
    state = BicycleState(*(np.asarray(a, dtype=float)[None, :] for a in (
        vehicles.s, vehicles.d, vehicles.heading, vehicles.speed, vehicles.accel, vehicles.curvature)))
    # Per layer: the prefix of every rollout, and the samples of its prefixes: [samples, 5, G, n] (s, d, heading,
    # speed, chain) and [samples, 6, G] of the ego (acceleration, curvature, leader gap, speed, held gap and
    # whether the leader is a car).
    layers_recorded: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    first_sample = np.concatenate([[0], layer_end[:-1]])
    samples = np.diff(np.append(first_sample, n_steps + 1))
    valid = np.ones(1, dtype=bool)
    barrier_steps = np.zeros(1, dtype=int)
    layer = -1
    cells = frame.locate(state.x)  # where the cars are on the frame's grid (shared by this step's look-ups)
    for k in range(n_steps + 1):
        branching = k < n_steps and (layer < 0 or k >= layer_end[layer])
        if branching:  # a new layer: every prefix continues as its children
            layer += 1
            first, parent, inverse = tree[layer]
            state = BicycleState(*(a[parent] for a in (state.x, state.y, state.heading, state.speed, state.accel,
                                                       state.curvature)))
            valid, barrier_steps = valid[parent], barrier_steps[parent]
            cells = FrameCells(cells.index[parent], cells.fraction[parent])
            lay = _Layer.of(rollouts, layer, first, v0_of_rollout, idm_of_rollout)
            G = first.size
            layers_recorded.append((inverse, np.empty((samples[layer], 5, G, n)),
                                    np.full((samples[layer], 6, G), np.inf)))
        s, d, v = state.x, state.y, state.speed
        if branching:
            lane_slope = frame.slope(lay.tracked, cells)  # direction of each car's tracked lane in the frame [rad]
        hit = boxes_overlap(s[:, :1], d[:, :1], state.heading[:, :1], *box_size[0], s[:, 1:], d[:, 1:],
                            state.heading[:, 1:], *box_size[1])
        valid = valid & ~hit.any(axis=1)
        centres = frame.centres_at(cells)  # [3, G, n]
        offset = np.abs(d - centres)  # [3, G, n] from each chain's centre line [m]
        now_chain = frame.chain_of_offsets(offset, s)
        if branching:
            gap = GapCars.find(centres, s, d, lay.tracked[:, 0], settings.ego_radius, length, width, rss_agents)
        leaders = _find_leaders(frame, lay, state, offset, now_chain, branching, length, width, widest_agent,
                                settings, ego_stop_s)
        _, vehicle_samples, ego_samples = layers_recorded[-1]
        sample = k - first_sample[layer]
        vehicle_samples[sample] = (s, d, state.heading, v, now_chain)
        ego_samples[sample, :4] = (state.accel[:, 0], state.curvature[:, 0], leaders.ego_gap, leaders.ego_speed)
        ego_samples[sample, 5] = leaders.ego_is_car
        if holding:  # the leader's held gap, unless a lane end or a stop line took its place
            ego_samples[sample, 4] = np.where(leaders.ego_is_car, held_gap[leaders.ego_leader], np.inf)
        if k == n_steps:
            break
        dt = t[k + 1] - t[k]
        target_offset = np.zeros((G, n))
        ell = lookahead(v, gain, l_min, l_max)  # pure-pursuit look-ahead [m] (column 0 with the ego's settings)
        lane_target = frame.lane_ahead(centres.ravel().take(lay.tracked_cells), lane_slope, ell)
        # The ego's lane-change layers: gap-informed controller, evasive speed-up, virtual barrier.
        changing = (lay.tracked[:, 0] != now_chain[:, 0]) & ~lay.backup & settings.gap_informed_changes
        any_changing = bool(changing.any())
        hold = evasive = np.zeros(G, dtype=bool)
        evasive_v0 = None
        if any_changing:
            lc_cmd, barrier, evasive_v0 = lane_change_command(frame, lay.tracked[:, 0], state, cells, length, width,
                                                              gap, lay.idm, lay.v0, settings, rss_ego, dt)
            # An ego already in the way of the target lane's cars is not held there: they stop for it (leaders).
            barrier &= np.abs(d[:, 0] - centres.ravel().take(lay.tracked_cells[:, 0])) >= leaders.ego_band
            hold = changing & barrier
            evasive = changing & np.isfinite(evasive_v0)
            evasive_v0 = np.minimum(evasive_v0, rollouts.ego_speed_limit)  # into the gap, within the speed limit
        ev = np.flatnonzero(evasive)
        cmd_t, cmd_c, cmd_go, cmd_ev = _idm_commands(lay, leaders, v, hold, ev, evasive_v0, dt, settings, rss_ego,
                                                     front_worst, held_gap if holding else None, junction_area)
        speed_cmd = np.minimum(cmd_t, cmd_c)
        if any_changing:
            # Waiting for a gap keeps room before the end of an ending lane; once going, all of it may be used.
            current_cap = np.where(hold, cmd_c[:, 0], np.maximum(cmd_c[:, 0], cmd_go))
            current_cap[ev] = np.maximum(current_cap[ev], cmd_ev)
            speed_cmd[:, 0] = np.where(changing, np.minimum(lc_cmd, current_cap), speed_cmd[:, 0])
            barrier_steps = barrier_steps + hold
            target_offset[:, 0] = np.where(hold, d[:, 0] - lane_target[:, 0], 0.0)
        if owed_brake_due is not None:
            owes = _owes_braking(s, d, v, t[k + 1], owed_brake_due, length, width, rss_ego, rss_agents)
            speed_cmd[:, 0] = np.where(owes, np.minimum(speed_cmd[:, 0], np.maximum(v[:, 0] - rss_ego.lon_brake_min
                                                                                    * dt, 0.0)), speed_cmd[:, 0])
        speed_cmd[:, 0] = np.where(lay.backup, np.maximum(v[:, 0] - rollouts.backup_brake * dt, 0.0), speed_cmd[:, 0])
        # Each car follows its lane as SUMO moves it along a polyline: where the lane bends in the frame (a bend of
        # the lane, or of the frame's centre line beside a straight lane) the car turns with it at once, and pure
        # pursuit aims along the lane's direction here, correcting only the offset from it. Aiming at the lane
        # beyond a bend made cars cut it and then overshoot: a motorway car beside the bending on-ramp drifted 3 m
        # into the ramp's lane in the simulation.
        target_d = lane_target + target_offset
        steer = pure_pursuit_steer(s, d, state.heading, s + ell, target_d, settings.ego_limits.wheelbase)
        # The evasive speed-up may use evasive_accel for this step (§3.6).
        max_accel = np.where(evasive[:, None], evasive_max_accel, limits.max_accel) if ev.size else None
        moved = bicycle_step(state, speed_cmd, steer, limits, dt, max_accel)
        cells = frame.locate(moved.x)
        slope_reached = frame.slope(lay.tracked, cells)
        state = BicycleState(moved.x, moved.y, moved.heading + slope_reached - lane_slope, moved.speed, moved.accel,
                             moved.curvature)
        lane_slope = slope_reached
    # Every rollout's samples: each layer's samples of its prefix (one gather per layer), time-major, returned as
    # [R, T+1, ...] views.
    vehicle_samples = np.empty((n_steps + 1, 5, len(rollouts.ego_v0), n))
    ego_samples = np.empty((n_steps + 1, 6, len(rollouts.ego_v0)))
    for (inverse, vehicles_at, ego_at), start, count in zip(layers_recorded, first_sample, samples):
        np.take(vehicles_at, inverse, axis=2, out=vehicle_samples[start:start + count])
        np.take(ego_at, inverse, axis=2, out=ego_samples[start:start + count])
    s, d, heading, speed, chain = vehicle_samples.transpose(1, 2, 0, 3)
    ego_accel, ego_curvature, lead_gap, lead_speed, lead_held_gap, lead_is_car = ego_samples.transpose(1, 2, 0)
    return SimResult(t, layer_end, s, d, heading, speed, ego_accel, ego_curvature, valid[inverse], lead_gap, lead_speed,
                     lead_held_gap, lead_is_car == 1.0, barrier_steps[inverse], chain.astype(np.intp))


def _find_leaders(frame: RoadFrame, lay: _Layer, state: BicycleState, offset: np.ndarray, now_chain: np.ndarray,
                  branching: bool, length: np.ndarray, width: np.ndarray, widest_agent: float, settings: SimSettings,
                  ego_stop_s: float) -> _Leaders:
    """The leaders on the tracked lane and on the lane each vehicle is in now (one search for both), and at a
    layer's first step (``branching``) for the ego on the lane the layer before tracked: that step is also the
    layer before's last sample, whose leader is the one on the lane that layer tracked. ``offset`` [3, G, n]:
    every vehicle's |d − centre| to every chain [m]."""
    s, v = state.x, state.speed
    looks, recorded = np.array([lay.tracked, now_chain]), 0  # recorded: the look the sample records
    if branching and lay.ending is not None:
        looks, recorded = np.concatenate([looks, looks[:1]]), 2
        looks[2, :, 0] = lay.ending
    ego_band = occupied_band(state.heading[:, 0], length[0], width[0], widest_agent, settings.agent_radius)
    free_gaps, free_speeds, leader = leaders_ahead(s, v, offset, looks, length,
                                                   (settings.agent_radius, settings.ego_radius), ego_band)
    lead_gaps, lead_speeds = lane_end_leader(frame, looks, s, length, free_gaps, free_speeds,
                                             settings.lane_end_margin)
    gap_go, v_go = lane_end_leader(frame, now_chain[:, :1], s[:, :1], length[:1], free_gaps[1, :, :1],
                                   free_speeds[1, :, :1], 0.0)
    stop_gap = ego_stop_s - s[:, 0] - 0.5 * length[0]
    if np.isfinite(ego_stop_s):
        lead_gaps[:, :, 0], lead_speeds[:, :, 0] = stopped_leader(stop_gap, lead_gaps[:, :, 0], lead_speeds[:, :, 0])
        gap_go[:, 0], v_go[:, 0] = stopped_leader(stop_gap, gap_go[:, 0], v_go[:, 0])
    ego_gap = lead_gaps[recorded, :, 0]
    return _Leaders(lead_gaps[0], lead_speeds[0], lead_gaps[1], lead_speeds[1], free_gaps, leader, gap_go[:, 0],
                    v_go[:, 0], now_chain, stop_gap, ego_band, ego_gap, lead_speeds[recorded, :, 0],
                    ego_gap == free_gaps[recorded, :, 0], leader[recorded, :, 0])


def _idm_commands(lay: _Layer, leaders: _Leaders, v: np.ndarray, hold: np.ndarray, ev: np.ndarray,
                  evasive_v0: np.ndarray | None, dt: float, settings: SimSettings, rss_ego: Any, front_worst: Any,
                  held_gap: np.ndarray | None, junction_area: JunctionArea | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Speed commands [m/s] of one step's leaders in one IDM call: every vehicle behind its leader on the tracked
    lane ``cmd_t`` and on its current lane ``cmd_c`` [G, n] (the same where the two lanes are one); the ego behind
    its 'going' leader ``cmd_go`` [G]; and, for the rollouts ``ev`` whose ego speeds up evasively (desired speed
    ``evasive_v0`` [G]), behind the leader in its lane (the waiting one where ``hold`` [G], else the going one) with
    the evasive IDM, ``cmd_ev`` [ev]. The ego keeps at least the RSS distance behind a car (``front_worst``, None:
    off; ``held_gap`` by leader column, None: none) and stays able to stop before the ``junction_area``."""
    G, n = v.shape
    gap_t, gap_c, v_t, v_c = leaders.gap_t, leaders.gap_c, leaders.v_t, leaders.v_c
    gap_go, v_go, free_gaps, leader = leaders.gap_go, leaders.v_go, leaders.free_gaps, leaders.leader
    # Rows: every vehicle on its tracked lane; on its current lane where that is another lane (a car changing
    # lanes); the ego's 'going' leader; the evasive ones.
    other = np.flatnonzero(lay.tracked.ravel() != leaders.now_chain.ravel())
    rows = np.concatenate([np.arange(G * n), other, np.arange(G) * n, ev * n])
    gaps = np.concatenate([gap_t.ravel(), gap_c.ravel()[other], gap_go,
                           np.where(hold, gap_c[:, 0], gap_go)[ev]])
    v_leads = np.concatenate([v_t.ravel(), v_c.ravel()[other], v_go,
                              np.where(hold, v_c[:, 0], v_go)[ev]])
    v_rows = v.ravel()[rows]
    free = np.isinf(gaps)
    desired = lay.v0.ravel()[rows]
    params = lay.idm_flat.take(rows, axis=1)  # [IDM fields, rows]
    if ev.size:
        desired[-ev.size:] = evasive_v0[ev]
        params[_IDM_FIELDS.index("s0"), -ev.size:] = settings.ego_idm.s0
        params[_IDM_FIELDS.index("headway"), -ev.size:] = settings.evasive_headway
        params[_IDM_FIELDS.index("accel"), -ev.size:] = settings.evasive_accel
    following = np.zeros(rows.size)
    if front_worst is not None:  # the ego behind a car (not a lane end or stop line): at least the RSS distance,
        # also while it speeds up evasively (it may close in to T = 0.6 s, not into its leader's RSS distance)
        car_go = gap_go == free_gaps[1, :, 0]
        car = np.concatenate([gap_t.ravel() == free_gaps[0].ravel(), (gap_c.ravel() == free_gaps[1].ravel())[other],
                              car_go, np.where(hold, gap_c[:, 0] == free_gaps[1, :, 0], car_go)[ev]])
        behind_car = (rows % n == 0) & car & ~free
        held = np.inf
        if held_gap is not None:
            lead_of_rows = np.concatenate([leader[0].ravel(), leader[1].ravel()[other], leader[1, :, 0],
                                           leader[1, ev, 0]])
            held = held_gap[lead_of_rows[behind_car]]
        following[behind_car] = following_distance(v_rows[behind_car], v_leads[behind_car], rss_ego, front_worst,
                                                   held)
    if junction_area is not None:  # the ego behind its stop line: able to stop before the area beyond it
        at_stop = (rows % n == 0) & ~free & (gaps == leaders.stop_gap[rows // n])
        p = junction_area.params
        following[at_stop] = np.maximum(following[at_stop], formulas.lon_reach(v_rows[at_stop], p, p.lon_brake_min)
                                        + p.min_lon_gap - junction_area.beyond)
    cmd = idm_speed_command(v_rows, desired, np.where(free, v_rows, v_leads),
                            np.where(free, NO_LEADER_GAP + NO_LEADER_GAP * v_rows, gaps), IdmParams(*params), dt,
                            following)
    cmd_t, cmd_go = cmd[:G * n].reshape(G, n), cmd[G * n + other.size:G * n + other.size + G]
    cmd_c = cmd_t.copy()
    cmd_c.ravel()[other] = cmd[G * n:G * n + other.size]
    return cmd_t, cmd_c, cmd_go, cmd[cmd.size - ev.size:]


def _owes_braking(s: np.ndarray, d: np.ndarray, v: np.ndarray, t_end: float, due: np.ndarray, length: np.ndarray,
                  width: np.ndarray, rss_ego: Any, rss_agents: Any) -> np.ndarray:
    """[G] whether the ego owes braking in the step ending at ``t_end`` [s]: its response time has ended
    (``due`` [n], see :func:`simulate`) in an episode with a car that is still ahead of it and RSS-unsafe both
    ways (longitudinally, and laterally at zero lateral speeds: in its lane)."""
    cols = np.flatnonzero(due < t_end - 1e-9)
    if cols.size == 0:
        return np.zeros(s.shape[0], dtype=bool)
    p = rss_agents.take(cols)
    gap = s[:, cols] - s[:, :1] - 0.5 * (length[0] + length[cols])
    lon_unsafe = ~formulas.is_safe_distance(gap, formulas.lon_safe_distance_same_dir(v[:, :1], v[:, cols], rss_ego,
                                                                                      p))
    lat_gap = np.abs(d[:, cols] - d[:, :1]) - 0.5 * (width[0] + width[cols])
    lat_unsafe = ~formulas.is_safe_distance(lat_gap, formulas.lat_safe_distance(0.0, 0.0, rss_ego, p))
    return np.any((s[:, cols] > s[:, :1]) & lon_unsafe & lat_unsafe, axis=1)


def _idm_per_rollout(idm: IdmParams, ego_spacing_scale: np.ndarray, n: int) -> np.ndarray:
    """Per-vehicle IDM parameters ``idm`` ([n] fields) for every rollout as one [fields, R, n] array (fields in
    IdmParams' order), the ego's s0 and T times its rollout's ``ego_spacing_scale`` [R]."""
    scale = np.ones((ego_spacing_scale.shape[0], n))
    scale[:, 0] = ego_spacing_scale
    scaled = replace(idm, s0=idm.s0[None, :] * scale, headway=idm.headway[None, :] * scale)
    return np.stack([np.broadcast_to(np.asarray(getattr(scaled, name), dtype=float), scale.shape)
                     for name in _IDM_FIELDS])
