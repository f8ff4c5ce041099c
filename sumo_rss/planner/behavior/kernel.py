"""The forward simulation's step loop, compiled with numba (epsilon.md §3; :func:`.forward_sim.simulate` prepares
its inputs and reads its outputs).

One call runs every prefix of the DCP tree (:func:`.forward_sim.prefix_tree`) through all steps: per step and
prefix, the ego's collision check, where every vehicle is on the frame's lanes, the leaders on the lane each tracks
and the one it is in (a lane that ends and the ego's stop line taking a leader's place), the ego's lane-change
controller with its evasive speed-up and RSS barrier, one IDM command per leader, the braking the ego owes, the
backup, pure pursuit and the bicycle model; then the samples of every rollout. The per-vehicle controllers and
the RSS formulas are the jitable functions the numpy code uses (one source). Units: m, s, m/s, m/s², rad.
"""
from __future__ import annotations

from collections import namedtuple
from typing import NamedTuple

import numpy as np

from ...boxes import box_pair_overlaps
from ...jit import jitable, kernel, rss_row
from ...rss import formulas
from ..lanes import CURRENT, LEFT, RIGHT
from ..road_frame import GRID_STEP
from .controllers import BicycleState, IdmParams, VehicleLimits, bicycle_step, idm_speed_command, lookahead, \
    pure_pursuit_steer
from .lane_change import gap_cars, lane_change_command, ready_offset
from .leaders import find_leaders, following_distance, occupied_band, stopped_leader

IdmRow = namedtuple("IdmRow", tuple(IdmParams.__dataclass_fields__))
LimitsRow = namedtuple("LimitsRow", tuple(VehicleLimits.__dataclass_fields__))
NO_LEADER_GAP = 100.0  # [m] a free road is a virtual leader 100 + 100·v ahead at the own speed
STATE_FIELDS = 6  # s, d, heading, speed, accel, curvature


class KernelSettings(NamedTuple):
    """Scalars of one simulation: :class:`.forward_sim.SimSettings`' of the same names, the ego IDM's s0 and its
    wheelbase [m], the rollouts' backup brake [m/s²] and speed limit [m/s], the ego's stop line [m] (inf: none), the
    widest agent [m], the junction area's distance beyond the stop line [m]; and whether there are a junction area
    and braking the ego owes. ``ego_end_room`` [m]: what the ego keeps before its own lane's end beyond
    ``lane_end_margin`` for the lane changes it must make after the next one (:func:`.forward_sim.ego_end_room`).
    ``has_reference``: the ego's desired speed is capped along its path by the reference profile on the grid
    ``reference_s0`` + g·``reference_step`` [m], read ``reference_preview`` [s] ahead too
    (:class:`.forward_sim.ReferenceProfile`)."""

    ego_radius: float
    agent_radius: float
    inflation: float
    lane_end_margin: float
    ego_end_room: float
    ego_s0: float
    evasive_headway: float
    evasive_accel: float
    ego_wheelbase: float
    backup_brake: float
    speed_limit: float
    ego_stop_s: float
    widest_agent: float
    junction_beyond: float
    rss_following: bool
    gap_informed_changes: bool
    has_junction: bool
    has_owed: bool
    ready_wait: bool
    has_reference: bool
    reference_s0: float
    reference_step: float
    reference_preview: float


@kernel
def run(t, layer_end, firsts, parents, inverses, counts, state0, length, width, idm, v0, limits, pursuit,
        evasive_max_accel, rss_table, rss_ego_row, front_worst_row, junction_row, ego_chain, agent_chain, backup,
        centre, slope_grid, extent, end_s, exists, frame_s0, held_gap, owed_due, reference, reference_limit, ks,
        gs):
    """Run the prefixes; returns the samples of every rollout, [T+1, 5, R, n] (s, d, heading, speed, chain) and
    [T+1, 6, R] (the ego's acceleration, curvature, leader gap, leader speed, the leader's held gap, whether the
    leader is a car), and per rollout whether the ego never collided and how many steps the barrier held it.
    Tree per layer ``l``: the first ``counts[l]`` entries of ``firsts[l]`` / ``parents[l]``, and ``inverses[l]``
    [R]. Per rollout and vehicle: ``idm`` [fields, R, n], ``v0`` [R, n]; per vehicle: ``limits`` [fields, n],
    ``pursuit`` [3, n] (gain, min, max), ``rss_table`` [n, fields]. ``ks``: :class:`KernelSettings`, ``gs``:
    :class:`~.lane_change.GapSettings`; ``reference`` / ``reference_limit`` [3, m]: the ego's reference speed and
    its speed limits' envelope by chain on their grid. (The phases of a step are separate functions: numba's
    compile time grows faster than linearly with a function's size.)"""
    n_steps, n, R = t.size - 1, length.size, ego_chain.shape[0]
    vehicle_out = np.empty((n_steps + 1, 5, R, n))
    ego_out = np.full((n_steps + 1, 6, R), np.inf)
    state = np.empty((STATE_FIELDS, 1, n))  # [fields, G, n]
    for f in range(STATE_FIELDS):
        for i in range(n):
            state[f, 0, i] = state0[f, i]
    valid = np.ones(1, dtype=np.bool_)
    barrier_steps = np.zeros(1, dtype=np.int64)
    cell, frac = _locate(state[0], frame_s0, centre.shape[1])
    layer = -1
    lane_slope = np.empty((1, n))
    tracked_chain = np.empty((1, n), dtype=np.int64)
    gaps = np.zeros((1, 2), dtype=np.int64)
    scratch = np.empty((4, n))  # _step_rollout's per-vehicle temporaries, allocated once
    for k in range(n_steps + 1):
        branching = k < n_steps and (layer < 0 or k >= layer_end[layer])
        if branching:  # a new layer: every prefix continues as its children
            layer += 1
            G = counts[layer]
            state, valid, barrier_steps, cell, frac = _children(parents[layer, :G], state, valid, barrier_steps,
                                                                cell, frac)
            tracked_chain, lane_slope = _tracked(firsts[layer, :G], layer, ego_chain, agent_chain, slope_grid, cell)
        centres, offset, now_chain = _place(state, cell, frac, valid, length, width, centre, exists, extent, ks)
        if branching:
            gaps = _gap_cars(state, centres, tracked_chain, ks.ego_radius)
        ending = branching and layer > 0
        looks, ego_band = _looks(firsts[layer], layer, ending, tracked_chain, now_chain, ego_chain, state, length,
                                 width, ks)
        free_gap, free_speed, leader = find_leaders(state[0], state[3], offset, looks, length, ks.agent_radius,
                                                    ks.ego_radius, ego_band)
        lead_gap, lead_speed, gap_go, v_go, stop_gap = _standing(looks, now_chain, state, free_gap, free_speed,
                                                                 length, end_s, ks)
        _record(k, 2 if ending else 0, inverses[layer], state, now_chain, lead_gap, lead_speed, free_gap, leader,
                held_gap, vehicle_out, ego_out)
        if k == n_steps:
            break
        dt = t[k + 1] - t[k]
        moved = np.empty(state.shape)
        for g in range(state.shape[1]):
            _step_rollout(g, firsts[layer, g], dt, t[k + 1], state, moved, tracked_chain, now_chain, lane_slope,
                          centres, cell, gaps, lead_gap, lead_speed, free_gap, leader, gap_go, v_go, stop_gap,
                          ego_band, barrier_steps, length, width, idm, v0, limits, pursuit, evasive_max_accel,
                          rss_table, rss_ego_row, front_worst_row, junction_row, backup, slope_grid, held_gap,
                          owed_due, end_s, reference, reference_limit, ks, gs, scratch)
        cell, frac = _locate(moved[0], frame_s0, centre.shape[1])
        for g in range(moved.shape[1]):
            for i in range(n):
                reached = slope_grid[tracked_chain[g, i], cell[g, i]]
                moved[2, g, i] = moved[2, g, i] + reached - lane_slope[g, i]
                lane_slope[g, i] = reached
        state = moved
    last = inverses[layer]
    return vehicle_out, ego_out, valid[last], barrier_steps[last]


@jitable
def _tracked(first, layer, ego_chain, agent_chain, slope_grid, cell):
    """The lane chain each vehicle tracks in ``layer`` (the ego's: its policy's in that layer) per prefix (its
    representative rollouts ``first``), and that lane's direction where each is [rad]."""
    G, n = first.size, agent_chain.shape[1]
    tracked = np.empty((G, n), dtype=np.int64)
    lane_slope = np.empty((G, n))
    for g in range(G):
        for i in range(n):
            tracked[g, i] = ego_chain[first[g], layer] if i == 0 else agent_chain[first[g], i]
            lane_slope[g, i] = slope_grid[tracked[g, i], cell[g, i]]
    return tracked, lane_slope


@jitable
def _place(state, cell, frac, valid, length, width, centre, exists, extent, ks):
    """Every vehicle's place on the frame's lanes: the chains' centres at it and its offsets from them [3, G, n],
    the chain it is in [G, n]; ``valid`` turns False where the ego's box (inflated) meets another vehicle's."""
    G, n = state.shape[1], state.shape[2]
    s, d, heading = state[0], state[1], state[2]
    centres, offset = np.empty((3, G, n)), np.empty((3, G, n))
    now_chain = np.empty((G, n), dtype=np.int64)
    grow = ks.inflation
    for g in range(G):
        for i in range(1, n):
            if box_pair_overlaps(s[g, i] - s[g, 0], d[g, i] - d[g, 0], heading[g, 0], length[0] + grow,
                                 width[0] + grow, heading[g, i], length[i] + grow, width[i] + grow):
                valid[g] = False
        for i in range(n):
            for c in range(3):
                centres[c, g, i] = centre[c, cell[g, i]] * (1.0 - frac[g, i]) + centre[c, cell[g, i] + 1] * frac[g, i]
                offset[c, g, i] = np.abs(d[g, i] - centres[c, g, i])
            now_chain[g, i] = _chain_of_offsets(offset[0, g, i], offset[1, g, i], offset[2, g, i], s[g, i], exists,
                                                extent)
    return centres, offset, now_chain


@jitable
def _gap_cars(state, centres, tracked, radius):
    """[G, 2] per prefix the front and rear gap cars' columns on the ego's target lane (0: none)."""
    G = state.shape[1]
    gaps = np.zeros((G, 2), dtype=np.int64)
    for g in range(G):
        gaps[g, 0], gaps[g, 1] = gap_cars(state[0, g], state[1, g], centres[tracked[g, 0], g], radius)
    return gaps


@jitable
def _looks(first, layer, ending, tracked, now_chain, ego_chain, state, length, width, ks):
    """The lanes each vehicle looks for its leader on [looks, G, n]: the one it tracks, the one it is in and, at a
    layer's first step (``ending``), for the ego the lane the layer before tracked (that step is also the layer
    before's last sample); and the band [G] [m] in which the ego is in an agent's way (:func:`occupied_band`)."""
    G, n = tracked.shape
    looks = np.empty((3 if ending else 2, G, n), dtype=np.int64)
    ego_band = np.empty(G)
    for g in range(G):
        ego_band[g] = occupied_band(state[2, g, 0], length[0], width[0], ks.widest_agent, ks.agent_radius)
        for i in range(n):
            looks[0, g, i], looks[1, g, i] = tracked[g, i], now_chain[g, i]
            if ending:
                looks[2, g, i] = ego_chain[first[g], layer - 1] if i == 0 else tracked[g, i]
    return looks, ego_band


@jitable
def _standing(looks, now_chain, state, free_gap, free_speed, length, end_s, ks):
    """The leaders with standing obstacles in their place where nearer [looks, G, n]: a lane's end (less the
    waiting margin; for the ego in its own lane also less the room of the changes after the next one) and, for the
    ego, its stop line; the ego's current-lane leader without the waiting margin, but with that room (``gap_go``,
    ``v_go`` [G], once a lane change is going); and the ego's front bumper to its stop line [G] (inf: none)."""
    G, n = now_chain.shape
    s = state[0]
    lead_gap, lead_speed = free_gap.copy(), free_speed.copy()
    gap_go, v_go, stop_gap = np.empty(G), np.empty(G), np.empty(G)
    for g in range(G):
        for m in range(looks.shape[0]):
            for i in range(n):
                room = ks.ego_end_room if i == 0 and looks[m, g, i] == CURRENT else 0.0
                lead_gap[m, g, i], lead_speed[m, g, i] = stopped_leader(
                    end_s[looks[m, g, i]] - ks.lane_end_margin - room - s[g, i] - 0.5 * length[i],
                    lead_gap[m, g, i], lead_speed[m, g, i])
        room = ks.ego_end_room if now_chain[g, 0] == CURRENT else 0.0
        gap_go[g], v_go[g] = stopped_leader(end_s[now_chain[g, 0]] - room - s[g, 0] - 0.5 * length[0],
                                            free_gap[1, g, 0], free_speed[1, g, 0])
        stop_gap[g] = ks.ego_stop_s - s[g, 0] - 0.5 * length[0]
        if np.isfinite(ks.ego_stop_s):
            for m in range(looks.shape[0]):
                lead_gap[m, g, 0], lead_speed[m, g, 0] = stopped_leader(stop_gap[g], lead_gap[m, g, 0],
                                                                        lead_speed[m, g, 0])
            gap_go[g], v_go[g] = stopped_leader(stop_gap[g], gap_go[g], v_go[g])
    return lead_gap, lead_speed, gap_go, v_go, stop_gap


@jitable
def _record(k, recorded, inverse, state, now_chain, lead_gap, lead_speed, free_gap, leader, held_gap, vehicle_out,
            ego_out):
    """Sample ``k`` of every rollout (its prefix's ``inverse[r]``); the ego's leader as look ``recorded`` found it."""
    n = now_chain.shape[1]
    for r in range(inverse.size):
        g = inverse[r]
        for i in range(n):
            for f in range(4):
                vehicle_out[k, f, r, i] = state[f, g, i]
            vehicle_out[k, 4, r, i] = now_chain[g, i]
        is_car = lead_gap[recorded, g, 0] == free_gap[recorded, g, 0]
        ego_out[k, 0, r], ego_out[k, 1, r] = state[4, g, 0], state[5, g, 0]
        ego_out[k, 2, r], ego_out[k, 3, r] = lead_gap[recorded, g, 0], lead_speed[recorded, g, 0]
        ego_out[k, 4, r] = held_gap[leader[recorded, g, 0]] if is_car else np.inf
        ego_out[k, 5, r] = 1.0 if is_car else 0.0


@jitable
def _step_rollout(g, rollout, dt, t_end, state, moved, tracked, now_chain, lane_slope, centres, cell, gaps,
                  lead_gap, lead_speed, free_gap, leader, gap_go, v_go, stop_gap, ego_band, barrier_steps, length,
                  width, idm, v0, limits, pursuit, evasive_max_accel, rss_table, rss_ego_row, front_worst_row,
                  junction_row, backup, slope_grid, held_gap, owed_due, end_s, reference, reference_limit, ks, gs,
                  scratch):
    """One step of prefix ``g`` (representative rollout ``rollout``) ending at ``t_end`` [s]: every vehicle's
    commands and its move, into ``moved`` [fields, G, n]. ``scratch`` [4, n]: room for its temporaries. The ego's
    desired speed is its rollout's, capped by the reference speed where it is now (:func:`_reference_at`), and
    (but in the evasive speed-up) its speed command by the speed limits' envelope where its front bumper gets to in
    the step: the IDM slows towards a lower desired speed with a lag (docs/planner.md)."""
    n = length.size
    ego_v0 = v0[rollout, 0]
    ego_front = state[0, g, 0] + 0.5 * length[0]
    if ks.has_reference:
        ego_v0 = min(ego_v0, _reference_at(reference[now_chain[g, 0]], ego_front, state[3, g, 0], ks))
    s, d, heading, v = state[0, g], state[1, g], state[2, g], state[3, g]
    rss_ego, front_worst, junction = rss_row(rss_ego_row, 0), rss_row(front_worst_row, 0), rss_row(junction_row, 0)
    ell, lane_target, slope, speed_cmd = scratch[0], scratch[1], scratch[2], scratch[3]
    for i in range(n):
        ell[i] = lookahead(v[i], pursuit[0, i], pursuit[1, i], pursuit[2, i])
        lane_target[i] = centres[tracked[g, i], g, i] + np.tan(lane_slope[g, i]) * ell[i]
    # The ego's lane-change layers: gap-informed controller, evasive speed-up, virtual barrier.
    changing = tracked[g, 0] != now_chain[g, 0] and not backup[rollout] and ks.gap_informed_changes
    hold = evasive = False
    lc_cmd = evasive_v0 = 0.0
    hold_d = d[0]  # where across a held ego keeps its centre
    if changing:
        for i in range(n):
            slope[i] = slope_grid[tracked[g, 0], cell[g, i]]
        front, rear = gaps[g, 0], gaps[g, 1]
        lc_cmd, barrier, evasive_v0 = lane_change_command(front, rear, front > 0, rear > 0, s, d, heading, v, slope,
                                                          length, width, idm[0, rollout, 0], idm[1, rollout, 0],
                                                          ego_v0, gs, rss_ego, rss_table, dt)
        # An ego already in the way of the target lane's cars is not held there: they stop for it (leaders).
        hold = barrier and np.abs(d[0] - centres[tracked[g, 0], g, 0]) >= ego_band[g]
        if hold and ks.ready_wait and np.isfinite(end_s[now_chain[g, 0]]):  # wait ready beside the gap
            for i in range(n):
                scratch[3, i] = heading[i] - slope[i]  # speed_cmd's room, filled only below
            hold_d = ready_offset(front, rear, d, scratch[3], v, width, centres[tracked[g, 0], g, 0], ego_band[g],
                                  rss_ego, rss_table)
        evasive = np.isfinite(evasive_v0)
        evasive_v0 = min(evasive_v0, ks.speed_limit)  # into the gap, within the speed limit
    for i in range(n):
        p = _idm_row(idm, rollout, i)
        ego = i == 0
        desired = ego_v0 if ego else v0[rollout, i]
        cmd_t = _idm_command(v[i], desired, lead_gap[0, g, i], lead_speed[0, g, i], free_gap[0, g, i],
                             leader[0, g, i], p, ego, stop_gap[g], dt, ks, rss_ego, front_worst, junction, held_gap)
        cmd_c = cmd_t
        if tracked[g, i] != now_chain[g, i]:  # a car changing lanes also follows the leader in its lane
            cmd_c = _idm_command(v[i], desired, lead_gap[1, g, i], lead_speed[1, g, i], free_gap[1, g, i],
                                 leader[1, g, i], p, ego, stop_gap[g], dt, ks, rss_ego, front_worst, junction,
                                 held_gap)
        speed_cmd[i] = min(cmd_t, cmd_c)
        if ego and changing:
            # Waiting for a gap keeps room before the end of an ending lane; once going, all of it may be used.
            cmd_go = _idm_command(v[0], ego_v0, gap_go[g], v_go[g], free_gap[1, g, 0], leader[1, g, 0], p,
                                  ego, stop_gap[g], dt, ks, rss_ego, front_worst, junction, held_gap)
            current_cap = cmd_c if hold else max(cmd_c, cmd_go)
            if evasive:  # the evasive IDM behind the leader in its lane (the waiting one where held)
                fast = IdmRow(ks.ego_s0, ks.evasive_headway, ks.evasive_accel, p.comfort_brake, p.hard_brake,
                              p.exponent, p.coolness, p.approach_time)
                cmd_ev = _idm_command(v[0], evasive_v0, lead_gap[1, g, 0] if hold else gap_go[g],
                                      lead_speed[1, g, 0] if hold else v_go[g], free_gap[1, g, 0], leader[1, g, 0],
                                      fast, ego, stop_gap[g], dt, ks, rss_ego, front_worst, junction, held_gap)
                current_cap = max(current_cap, cmd_ev)
            speed_cmd[0] = min(lc_cmd, current_cap)
    if ks.has_reference and not evasive:  # at most the limits' envelope where its front bumper gets to
        speed_cmd[0] = min(speed_cmd[0], _profile_at(reference_limit[now_chain[g, 0]],
                                                     (ego_front + v[0] * dt - ks.reference_s0) / ks.reference_step))
    if hold:
        barrier_steps[g] += 1
    if ks.has_owed and _owes_braking(s, d, v, t_end, owed_due, length, width, rss_ego, rss_table):
        speed_cmd[0] = min(speed_cmd[0], max(v[0] - rss_ego.lon_brake_min * dt, 0.0))
    if backup[rollout]:
        speed_cmd[0] = max(v[0] - ks.backup_brake * dt, 0.0)
    for i in range(n):
        # Each car follows its lane as SUMO moves it along a polyline: where the lane bends in the frame it turns
        # with it at once, and pure pursuit aims along the lane's direction here, correcting only the offset from
        # it (docs/planner.md).
        target_d = lane_target[i] + ((hold_d - lane_target[0]) if i == 0 and hold else 0.0)
        steer = pure_pursuit_steer(s[i], d[i], heading[i], s[i] + ell[i], target_d, ks.ego_wheelbase)
        # The evasive speed-up may use evasive_accel for this step (§3.6).
        max_accel = evasive_max_accel[i] if evasive else limits[1, i]
        after = bicycle_step(BicycleState(s[i], d[i], heading[i], v[i], state[4, g, i], state[5, g, i]),
                             speed_cmd[i], steer, _limits_row(limits, i), dt, max_accel)
        moved[0, g, i], moved[1, g, i], moved[2, g, i] = after.x, after.y, after.heading
        moved[3, g, i], moved[4, g, i], moved[5, g, i] = after.speed, after.accel, after.curvature


@jitable
def _idm_command(v, desired, gap, v_lead, free_gap, leader, p, is_ego, stop_gap, dt, ks, rss_ego, front_worst,
                 junction, held_gap):
    """The speed command [m/s] behind a leader at ``gap`` [m] (inf: none) and ``v_lead`` [m/s] (column
    ``leader``). The ego keeps at least the RSS distance behind a car (``gap`` is the car's ``free_gap``, not a lane
    end or the stop line; ``held_gap`` by leader column) and, behind its stop line, stays able to stop before the
    junction area beyond it."""
    free = np.isinf(gap)
    following = 0.0
    if is_ego and not free:
        if ks.rss_following and gap == free_gap:  # also while it speeds up evasively: T may fall to 0.6 s, not
            # into its leader's RSS distance
            following = following_distance(v, v_lead, rss_ego, front_worst, held_gap[leader])
        if ks.has_junction and gap == stop_gap:
            following = max(following, formulas.lon_reach(v, junction, junction.lon_brake_min) +
                            junction.min_lon_gap - ks.junction_beyond)
    return idm_speed_command(v, desired, v if free else v_lead, NO_LEADER_GAP + NO_LEADER_GAP * v if free else gap,
                             p, dt, following)


@jitable
def _reference_at(profile, s_front, v, ks):
    """[m/s] The ego's reference speed with its front bumper at ``s_front`` [m] at ``v`` [m/s]: ``profile`` [m]
    (one chain's, on the grid of ``ks``) read there and ``ks.reference_preview`` s ahead at ``v``, the lower."""
    ahead = s_front + ks.reference_preview * v
    return min(_profile_at(profile, (s_front - ks.reference_s0) / ks.reference_step),
               _profile_at(profile, (ahead - ks.reference_s0) / ks.reference_step))


@jitable
def _profile_at(values, at):
    """``values`` [m] at the fractional index ``at``: linear between the points, the end values beyond them
    (exactly a point's value where its neighbour is equal)."""
    at = min(max(at, 0.0), values.size - 1.000001)
    k = int(at)
    return values[k] + (values[k + 1] - values[k]) * (at - k)


@jitable
def _owes_braking(s, d, v, t_end, due, length, width, rss_ego, rss_table):
    """Whether the ego owes braking in the step ending at ``t_end`` [s]: its response time has ended (``due`` [n],
    see :func:`.forward_sim.simulate`) in an episode with a car that is still ahead of it and RSS-unsafe both ways
    (longitudinally, and laterally at zero lateral speeds: in its lane). One rollout's [n] states."""
    for j in range(s.size):
        if due[j] < t_end - 1e-9 and s[j] > s[0]:
            p = rss_row(rss_table, j)
            gap = s[j] - s[0] - 0.5 * (length[0] + length[j])
            lat_gap = np.abs(d[j] - d[0]) - 0.5 * (width[0] + width[j])
            if not formulas.is_safe_distance(gap, formulas.lon_safe_distance_same_dir(v[0], v[j], rss_ego, p)) and \
                    not formulas.is_safe_distance(lat_gap, formulas.lat_safe_distance(0.0, 0.0, rss_ego, p)):
                return True
    return False


@jitable
def _locate(x, s0, grid):
    """The grid cells [G, n] of frame positions ``x`` [G, n] (clamped to the ends of the ``grid`` points) and the
    fractions of the way to the next point (:meth:`RoadFrame.locate`)."""
    cell, frac = np.empty(x.shape, dtype=np.int64), np.empty(x.shape)
    for g in range(x.shape[0]):
        for i in range(x.shape[1]):
            at = min(max((x[g, i] - s0) / GRID_STEP, 0.0), grid - 1.000001)
            cell[g, i] = int(at)
            frac[g, i] = at - cell[g, i]
    return cell, frac


@jitable
def _chain_of_offsets(to_right, to_current, to_left, s, exists, extent):
    """The existing chain nearest to a point at ``s`` [m] at these offsets from the three chains' centre lines
    (:meth:`RoadFrame.chain_of_offsets`)."""
    right, current, left = np.inf, np.inf, np.inf
    if exists[RIGHT] and extent[RIGHT, 0] <= s <= extent[RIGHT, 1]:
        right = to_right
    if exists[CURRENT] and extent[CURRENT, 0] <= s <= extent[CURRENT, 1]:
        current = to_current
    if exists[LEFT] and extent[LEFT, 0] <= s <= extent[LEFT, 1]:
        left = to_left
    return LEFT if left < min(right, current) else (CURRENT if current < right else RIGHT)


@jitable
def _idm_row(idm, r, i):
    return IdmRow(idm[0, r, i], idm[1, r, i], idm[2, r, i], idm[3, r, i], idm[4, r, i], idm[5, r, i], idm[6, r, i],
                  idm[7, r, i])


@jitable
def _limits_row(limits, i):
    return LimitsRow(limits[0, i], limits[1, i], limits[2, i], limits[3, i], limits[4, i], limits[5, i],
                     limits[6, i], limits[7, i], limits[8, i])


@jitable
def _children(parent, state, valid, barrier_steps, cell, frac):
    """The state of each child prefix: a copy of its ``parent``'s (explicit loops: numba's fancy indexing costs
    seconds of compile time)."""
    G, n = parent.size, state.shape[2]
    state_out, cell_out, frac_out = np.empty((state.shape[0], G, n)), np.empty((G, n), dtype=np.int64), np.empty((G, n))
    valid_out, barrier_out = np.empty(G, dtype=np.bool_), np.empty(G, dtype=np.int64)
    for g in range(G):
        p = parent[g]
        valid_out[g], barrier_out[g] = valid[p], barrier_steps[p]
        for i in range(n):
            cell_out[g, i], frac_out[g, i] = cell[p, i], frac[p, i]
            for f in range(state.shape[0]):
                state_out[f, g, i] = state[f, p, i]
    return state_out, valid_out, barrier_out, cell_out, frac_out
