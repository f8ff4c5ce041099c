"""Closed-loop multi-agent forward simulation of EUDM (epsilon.md §3): its inputs, its outputs and the DCP tree's
shared prefixes; the steps run in the compiled kernel (:mod:`.kernel`, numba).

Every (policy x scenario) rollout of a planning cycle is one row of [rollouts, vehicles] arrays (column 0 is the
ego), the rollouts advanced together in synchronous (Jacobi) steps: each step computes every vehicle's command from the
states at the start of the step, then commits them all. Vehicles live in the planning frame (:class:`RoadFrame`):
s along the ego's lane chain, d across it, heading relative to it; lanes are offset profiles, so nothing is
projected inside the loop. The reference point is the geometric centre (SUMO gives no axle geometry).

Per step and vehicle: pure pursuit on the tracked lane (its target lane; the ego's lane per layer of its policy),
a leader search on the tracked lane and on the lane the vehicle is in now, ACC/IIDM on the nearer leader (a lane
that ends is a stopped leader at its end), the kinematic bicycle with its limits. The ego's lane-change layers
use the gap-informed controller of §3.5 with the port's fix (the current-lane IDM still applies), the RSS
evasive speed-up and an RSS virtual barrier (RSS's cut-in rule, :func:`.lane_change.lane_change_command`). A rollout whose
ego box (inflated) meets another vehicle's box is invalid from that step on.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...rss.params import PARAM_NAMES
from ..lanes import CURRENT, LEFT, RIGHT, LaneChains
from ..road_frame import GRID_STEP, RoadFrame
from ..route_lanes import UNREACHABLE
from .controllers import IdmParams, VehicleLimits
from .kernel import KernelSettings, run
from .lane_change import GapSettings
from .leaders import hardest_braking

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
    track_speed_gain: float = 0.8  # K_v' [1/s], tracking acceleration clipped to [-1, ego_limits.max_accel] m/s²
    preferred_blend: float = 0.1
    evasive_accel: float = 2.0  # [m/s²] speed-up into the gap when the gap-rear car is RSS-unsafe (IDM a, limit)
    evasive_headway: float = 0.6  # [s] the ego's IDM T while it speeds up
    evasive_extra_speed: float = 10.0  # [m/s] its desired speed: the rear car's RSS-safe minimum plus this
    evasive_speed_up: bool = True  # False: no evasive speed-up (a mandatory change seeking a gap behind)
    inflation: float = 0.1  # [m] added to length and width in the strict collision check
    lane_end_margin: float = 20.0  # [m] a lane that ends is a stopped leader this far before its end (room to merge)
    commit_time: float = 1.0  # [s] the gap must stay RSS-safe this long at constant speeds before the ego enters it
    rss_following: bool = True  # the ego's IDM headway distance is at least the RSS safe distance to a car ahead
    gap_informed_changes: bool = True  # the ego's lane changes by EPSILON's controller (False: IDM + pure pursuit)
    # a held change of an ego whose lane ends waits beside its gap ready to go (lane_change.ready_offset)
    ready_wait: bool = False


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
class ReferenceProfile:
    """The ego's reference speed along its path: ``speed[c, g]`` [m/s] with its front bumper on chain c
    (RIGHT/CURRENT/LEFT) at frame position ``s0 + g·step`` [m] (linear between the points, the end values beyond
    them; finite everywhere, a missing chain a copy of another), read at the front bumper and ``preview`` [s] at the
    ego's speed ahead of it, the lower of the two: the ego's desired speed; ``limit[c, g]`` the same from the lanes'
    speed limits alone (no bends), read at the front bumper: a cap on its speed (docs/planner.md, "The desired
    speed along the rollout's path")."""

    s0: float
    step: float
    speed: np.ndarray  # [3, m]
    limit: np.ndarray  # [3, m]
    preview: float

    def __post_init__(self) -> None:
        for values in (self.speed, self.limit):
            if values.ndim != 2 or values.shape[0] != 3 or values.shape[1] < 2 or not np.isfinite(values).all():
                raise ValueError("a reference profile needs finite speeds [3, m >= 2]")
        if self.limit.shape != self.speed.shape or self.step <= 0.0:
            raise ValueError("a reference profile's two speeds share one grid of positive step")

    @classmethod
    def along(cls, chains: LaneChains, front: float, reach: float, desired: float, preview: float
              ) -> ReferenceProfile:
        """The profile of ``chains`` (:meth:`.lanes.LaneChains.reference_profile`, at most ``desired`` [m/s]) for
        the ego's front bumper from ``front`` [m] over ``reach`` [m] (the horizon's and the preview's), on a
        GRID_STEP grid, read ``preview`` [s] ahead too. A rise of a limit (a faster lane's start) counts one grid
        step late, so that no point between two grid points reads above the slower lane's limit. A chain that does
        not exist gets the current chain's profile (never read)."""
        grid = front + GRID_STEP * np.arange(-1, int(np.ceil((reach + 2.0 * GRID_STEP) / GRID_STEP)) + 1)
        speed, limit = np.empty((3, grid.size - 1)), np.empty((3, grid.size - 1))
        for which in (CURRENT, RIGHT, LEFT):
            if not chains.exists(which):
                speed[which], limit[which] = speed[CURRENT], limit[CURRENT]
                continue
            for out, bends in ((speed, True), (limit, False)):
                profile = chains.reference_profile(which, grid, desired, bends=bends)
                out[which] = np.minimum(profile[1:], profile[:-1])
        return cls(front, GRID_STEP, speed, limit, preview)


@dataclass(frozen=True, eq=False)
class Rollouts:
    """What differs between rollouts. ``ego_chain[r, layer]``: the lane the ego tracks in each layer;
    ``ego_v0[r]`` its desired speed, ``ego_spacing_scale[r]`` the factor on its s0 and T (0.75 when
    accelerating); ``ego_backup[r]``: the emergency backup (lane keep, braking at ``backup_brake``);
    ``agent_chain[r, i]`` each agent's target lane, ``agent_v0[i]`` its desired speed; ``ego_speed_limit`` the
    road's speed limit [m/s], which the evasive speed-up does not exceed; ``ego_reference``: the reference speed
    along the ego's path, which caps its desired speed at every step (None: ``ego_v0`` throughout)."""

    ego_chain: np.ndarray  # [R, layers] int
    ego_v0: np.ndarray  # [R]
    ego_spacing_scale: np.ndarray  # [R]
    ego_backup: np.ndarray  # [R] bool
    backup_brake: float
    agent_chain: np.ndarray  # [R, n] int (column 0 unused)
    agent_v0: np.ndarray  # [n]
    ego_speed_limit: float = np.inf
    ego_reference: ReferenceProfile | None = None


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


@functools.lru_cache(maxsize=16)
def _vehicle_tables(settings: SimSettings, n: int) -> tuple[IdmParams, np.ndarray, np.ndarray, np.ndarray]:
    """The per-vehicle parameters of ``n`` vehicles (column 0 the ego) in the kernel's form, built once per settings
    and vehicle count (read, never written): the IDM's (IdmParams of [n] arrays), the limits [fields, n] in
    VehicleLimits' order, pure pursuit's [3, n] (gain, min, max look-ahead) and the evasive speed-up's largest
    acceleration [n] [m/s²]."""
    cols = np.arange(n)
    idm = _per_vehicle(settings.ego_idm, settings.agent_idm, n)
    limits = _per_vehicle(settings.ego_limits, settings.agent_limits, n)
    evasive_max_accel = np.where(cols == 0, np.maximum(settings.evasive_accel, limits.max_accel), limits.max_accel)
    pursuit = np.array([np.where(cols == 0, e, a) for e, a in zip(settings.ego_pursuit, settings.agent_pursuit)])
    table = [getattr(limits, name) for name in VehicleLimits.__dataclass_fields__]
    return idm, _c(table, np.float64), _c(pursuit, np.float64), _c(evasive_max_accel, np.float64)


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


def ego_end_room(frame: RoadFrame, margin: float) -> float:
    """[m] What the ego keeps before its own lane's end (where it ends or leaves the route) beyond the waiting
    ``margin``, also while a change is going: ``margin`` per lane change still to make after the next one. A
    slow ego uses some of the lane in every change; with one waiting margin for three changes it crept to 2 m before
    the end of highway_exit's ex_decel and had no room for the last (docs/planner.md, "Room for every change")."""
    total = frame.chains.changes[1]
    if not np.isfinite(frame.end_s[CURRENT]) or total >= UNREACHABLE:
        return 0.0
    return margin * max(total - 1, 0)


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
    that share a prefix of the tree are simulated once until they branch (:func:`prefix_tree`); the steps run in
    the compiled kernel (:func:`.kernel.run`)."""
    t, layer_end = step_times(durations, sim_step)
    n, R = len(vehicles), len(rollouts.ego_v0)
    tree = prefix_tree(rollouts)
    firsts, parents, inverses = (np.zeros((len(tree), R), dtype=np.int64) for _ in range(3))
    for layer, (first, parent, inverse) in enumerate(tree):
        firsts[layer, :first.size], parents[layer, :first.size], inverses[layer] = first, parent, inverse
    counts = np.array([first.size for first, _, _ in tree], dtype=np.int64)
    agent_idm, limits, pursuit, evasive_max_accel = _vehicle_tables(settings, n)
    rss_following = settings.rss_following and n > 1
    front_worst = hardest_braking(rss_agents.take(np.arange(1, n))) if rss_following else rss_agents
    held_gap = np.full(n + 1, np.inf)  # by leader column; n: no car ahead
    if cut_in_gap is not None:
        held_gap[:n] = cut_in_gap
    # Per rollout: desired speeds [R, n] and IDM parameters [fields, R, n] (the ego's s0 and T scaled per policy).
    v0_of_rollout = np.tile(np.asarray(rollouts.agent_v0, dtype=float), (R, 1))
    v0_of_rollout[:, 0] = rollouts.ego_v0
    idm_of_rollout = _idm_per_rollout(agent_idm, rollouts.ego_spacing_scale, n)
    state = np.array([vehicles.s, vehicles.d, vehicles.heading, vehicles.speed, vehicles.accel, vehicles.curvature],
                     dtype=float)
    reference = rollouts.ego_reference
    ks = KernelSettings(
        settings.ego_radius, settings.agent_radius, settings.inflation, settings.lane_end_margin,
        ego_end_room(frame, settings.lane_end_margin), settings.ego_idm.s0,
        settings.evasive_headway, settings.evasive_accel, settings.ego_limits.wheelbase, float(rollouts.backup_brake),
        float(rollouts.ego_speed_limit), float(ego_stop_s), float(vehicles.width[1:].max()) if n > 1 else 0.0,
        junction_area.beyond if junction_area is not None else 0.0, rss_following, settings.gap_informed_changes,
        junction_area is not None, owed_brake_due is not None, settings.ready_wait, reference is not None,
        reference.s0 if reference is not None else 0.0, reference.step if reference is not None else 1.0,
        reference.preview if reference is not None else 0.0)
    gs = GapSettings(settings.gap_speed_gain, settings.preferred_blend, settings.track_speed_gain,
                     settings.track_pos_gain, settings.ego_limits.max_accel, settings.evasive_accel,
                     settings.evasive_extra_speed, settings.commit_time, settings.evasive_speed_up)
    f64, i64 = np.float64, np.int64
    vehicle_samples, ego_samples, valid, barrier_steps = run(
        _c(t, f64), _c(layer_end, i64), firsts, parents, inverses, counts, _c(state, f64), _c(vehicles.length, f64),
        _c(vehicles.width, f64), _c(idm_of_rollout, f64), _c(v0_of_rollout, f64),
        limits, pursuit, evasive_max_accel, rss_table(rss_agents, n), rss_table(rss_ego, 1), rss_table(front_worst, 1),
        rss_table(junction_area.params if junction_area is not None else rss_ego, 1), _c(rollouts.ego_chain, i64),
        _c(rollouts.agent_chain, i64), _c(rollouts.ego_backup, np.bool_), _c(frame.centre, f64),
        _c(frame.slope_grid, f64), _c(frame.extent, f64), _c(frame.end_s, f64), _c(frame.exists, np.bool_),
        float(frame.s0), held_gap, _c(np.full(n, np.inf) if owed_brake_due is None else owed_brake_due, f64),
        _c(reference.speed if reference is not None else np.zeros((3, 2)), f64),
        _c(reference.limit if reference is not None else np.zeros((3, 2)), f64), ks, gs)
    s, d, heading, speed, chain = vehicle_samples.transpose(1, 2, 0, 3)
    ego_accel, ego_curvature, lead_gap, lead_speed, lead_held_gap, lead_is_car = ego_samples.transpose(1, 2, 0)
    return SimResult(t, layer_end, s, d, heading, speed, ego_accel, ego_curvature, valid, lead_gap, lead_speed,
                     lead_held_gap, lead_is_car == 1.0, barrier_steps, chain.astype(np.intp))


def rss_table(params: Any, rows: int) -> np.ndarray:
    """[rows, fields] RSS parameters (RssParams, or RssParamArrays of ``rows`` or 1 rows) in PARAM_NAMES' order:
    the kernel's form (:func:`~sumo_rss.jit.rss_row`)."""
    table = np.array([getattr(params, name) for name in PARAM_NAMES], dtype=float).reshape(len(PARAM_NAMES), -1)
    return np.ascontiguousarray(np.broadcast_to(table[:, :rows].T, (rows, len(PARAM_NAMES))))


def _c(values: Any, dtype: type) -> np.ndarray:
    """A writeable C-contiguous array of ``dtype`` (the kernel is compiled for exactly these array types)."""
    return np.require(values, dtype, ["C", "W"])


def _idm_per_rollout(idm: IdmParams, ego_spacing_scale: np.ndarray, n: int) -> np.ndarray:
    """Per-vehicle IDM parameters ``idm`` ([n] fields) for every rollout as one [fields, R, n] array (fields in
    IdmParams' order), the ego's s0 and T times its rollout's ``ego_spacing_scale`` [R]."""
    out = np.empty((len(_IDM_FIELDS), ego_spacing_scale.shape[0], n))
    out[:] = np.array([getattr(idm, name) for name in _IDM_FIELDS], dtype=float)[:, None, :]
    for name in ("s0", "headway"):
        out[_IDM_FIELDS.index(name), :, 0] *= ego_spacing_scale
    return out
