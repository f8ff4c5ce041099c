"""EpsilonPlanner: one EUDM planning cycle per call (epsilon.md §2-§4, port decisions 1-6), and the MPDM
baseline (§8) as a configuration of the same machinery.

``plan(snapshot, ego_id)`` builds the planning frame along the ego's route, selects key vehicles, estimates
their intentions (rule-based belief; the intention network where lanes branch), branches the uncertain ones that
matter (CFB), forward-simulates every (policy x scenario) rollout in one vectorised batch, evaluates, reselects by
the lane-change context and hands the winner to the motion layer (:mod:`.motion.ssc`), which returns the ego
trajectory (front-bumper states at absolute times, as SUMO places vehicles). When no policy is valid or allowed,
the emergency backup (lane keep, braking at the ego's RSS b_min) is executed.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from ..heap import keep_freed_memory
from ..rss import formulas
from ..rss.auditor import ParamResolver
from ..rss.params import RssParamArrays
from ..rss.owed_responses import OwedResponses
from ..road.junctions import JunctionModel
from ..road.network import RoadNetwork
from ..road.routes import RouteTable
from ..sim.snapshot import WorldSnapshot
from ..trajectory import Trajectory
from .behavior.cfb import branch_scenarios, uncertain_agents
from .behavior.controllers import IdmParams, VehicleLimits
from .behavior.dcp_tree import Lat, Lon, Policy, valid_policies
from .behavior.cost_weights import CostWeights
from .behavior.evaluation import TARGET_CHAIN, Navigation, evaluate
from .behavior.forward_sim import JunctionArea, ReferenceProfile, Rollouts, SimResult, SimSettings, Vehicles, \
    simulate
from .behavior.intention import rule_belief
from .behavior.key_vehicles import SEARCH_RADIUS, KeyVehicles, key_vehicles
from .behavior.manager import Manager, ManagerSettings
from .behavior.precheck import intention_matters
from .intention.features import network_branches
from .junction_rules import Crossing, stop_line
from . import gap_seek, navigation
from .frames import PlanningFrames
from .lanes import CURRENT, LEFT, RIGHT, lanes_consistent_with
from .motion.frenet_plan import FrenetPlan, from_samples
from .motion.ssc import MotionInput, MotionLayer, MotionSettings
from .road_frame import RoadFrame

if TYPE_CHECKING:
    from .intention.belief import LearnedBelief

MODES = ("epsilon", "mpdm")
BACKUP = "backup"
SPEED_STEP_A, SPEED_STEP_D = 10.0, 10.0  # [m/s] acc/dec command gaps of the longitudinal actions
SPACING_SCALE_ACCELERATE = 0.75  # s0 and T factor of the 'accelerate' action
MPDM_IDM = IdmParams(s0=2.5, headway=1.5, accel=2.0, comfort_brake=3.0)  # aggressiveness level 3 (epsilon.md §2.4)
MPDM_PURSUIT_GAIN = 2.0  # [s] pure-pursuit look-ahead per m/s of every aggressiveness level
MPDM_SPEED_STEP = 5.0  # [m/s] MPDM's speed command is within this of the ego's speed
# [m/s²] the ego's acceleration: epsilon.md §3.1's ego has 1.0 (the release's highway demo), half of what its agents,
# its evasive mode and the MPDM baseline use; with it the ego took ~12 s from 10 to 13 m/s (docs/planner.md)
EGO_ACCEL = 2.0
# [s] the reference speed is also read this far ahead of the ego's front bumper at its speed (the lower reading
# holds): a rollout holds its desired speed for the whole horizon and the IDM slows to a lower one with a lag, so read
# at the centre the ego reached intersection_tls's 9.26 m/s junction lane at 12.3 m/s with the 1.67 m/s² envelope
# (docs/planner.md "Junctions")
REFERENCE_PREVIEW = 1.0
# [s] the ego's rollouts reach their desired speed at EGO_ACCEL, then close the last (v0 − v) with this time constant
# (IDM's a·(1 − (v/v0)^4) takes v0/(4a), 4.1 s at 33 m/s: docs/planner.md, "A speed target reached at the limit")
EGO_APPROACH_TIME = 1.0
EGO_SIM = SimSettings(ego_idm=IdmParams(accel=EGO_ACCEL, approach_time=EGO_APPROACH_TIME),
                      ego_limits=VehicleLimits(max_accel=EGO_ACCEL))


@dataclass(frozen=True)
class PlannerConfig:
    """Planner settings; scenario files may override ``layers``, ``layer_duration``, ``sim_step``,
    ``scenarios_k`` and ``replan_every`` (docs/scenarios.md)."""

    mode: str = "epsilon"
    desired_speed: float = 20.0  # [m/s] user desired speed
    layers: int = 5
    layer_duration: float = 1.0  # [s]
    sim_step: float = 0.2  # [s]
    scenarios_k: int = 4
    replan_every: int = 1
    output_step: float = 0.1  # [s] sampling of the returned trajectory (the co-simulation step)
    intention_net: bool = True  # CFB uses the shipped intention network where lanes branch (epsilon mode)
    lane_changes: bool = True  # False: lane-keeping policies only (no lateral actions)
    sim: SimSettings = EGO_SIM
    costs: CostWeights = CostWeights()
    manager: ManagerSettings = ManagerSettings()
    motion: MotionSettings = MotionSettings()

    @classmethod
    def mpdm(cls, desired_speed: float) -> PlannerConfig:
        """The MPDM baseline: 3 lateral policies at constant speed command, one scenario, 4 s at 0.4 s (ten 0.4 s
        layers, so that each is one step: the layers are cut into equal steps of at most ``sim_step``); ego and
        agents drive by IDM at aggressiveness level 3 and pure pursuit with gain 2 (epsilon.md §2.4, §8)."""
        sim = SimSettings(ego_idm=MPDM_IDM, agent_idm=replace(MPDM_IDM, hard_brake=SimSettings.agent_idm.hard_brake),
                          ego_pursuit=(MPDM_PURSUIT_GAIN, *SimSettings.ego_pursuit[1:]),
                          agent_pursuit=(MPDM_PURSUIT_GAIN, *SimSettings.agent_pursuit[1:]),
                          rss_following=False, gap_informed_changes=False)
        return cls(mode="mpdm", desired_speed=desired_speed, layers=10, layer_duration=0.4, sim_step=0.4,
                   scenarios_k=1, manager=ManagerSettings(consistency_frames=2, min_operation_delay=0.0),
                   motion=MotionSettings(enabled=False), sim=sim)


@dataclass(frozen=True, eq=False)
class PlanResult:
    """One planning cycle: the ego trajectory (and the same in the planning frame) and what led to it."""

    trajectory: Trajectory
    frenet: FrenetPlan
    policy: str  # winning policy name, or 'backup'
    costs: dict[str, float]  # policy name → cost (inf: invalid)
    timings: dict[str, float]  # [s] per stage
    agents: int
    scenarios: int
    backup: bool


@dataclass
class PlannerStats:
    backups: int = 0
    learned_beliefs: int = 0  # agent intentions given by the intention network (summed over cycles)
    stop_lines: dict[str, int] = field(default_factory=dict)  # cycles per stop-line reason ('' = none)
    gap_seek_cycles: int = 0  # cycles in which a held mandatory change sought its gap (navigation.seek_speed)
    overtake_seek_cycles: int = 0  # cycles in which a held discretionary change sought its gap (gap_seek)
    cycle_times: list[float] = field(default_factory=list)


class EpsilonPlanner:
    """Plans the ego every call; keeps the manager state between calls (one instance per ego and run)."""

    def __init__(self, network: RoadNetwork, params: ParamResolver, config: PlannerConfig = PlannerConfig()):
        if config.mode not in MODES:
            raise ValueError(f"unknown planner mode {config.mode!r}; expected one of {', '.join(MODES)}")
        keep_freed_memory()  # the rollouts' large temporaries are reused instead of faulted in anew (heap.py)
        self.network = network
        self.params = params
        self.config = config
        self.manager = Manager(config.manager, config.layer_duration, config.desired_speed)
        self.stats = PlannerStats()
        self.frames = PlanningFrames(network)
        self._curvature = 0.0
        self._seeking: Lat | None = None  # the held mandatory change of the cycle before (navigation.change_held)
        self._overtaking: Lat | None = None  # the held discretionary change of the cycle before, kept (gap_seek)
        self.junctions = JunctionModel.from_file(network.path, network)
        self.routes = RouteTable(network)
        self.belief = _learned_belief(network, config.output_step * config.replan_every) \
            if config.mode == "epsilon" and config.intention_net else None
        self.motion = MotionLayer(config.motion, config.output_step) if config.motion.enabled else None

    # -----------------------------------------------------------------------------------------------------
    def plan(self, snapshot: WorldSnapshot, ego_id: str, owed: OwedResponses | None = None) -> PlanResult:
        """One planning cycle. ``owed``: the ego's open RSS episodes (the auditor's ``owed_by``); a car ahead that
        the ego owes no longitudinal braking (it cut in) is followed at the gap it left (:meth:`_cut_in_gaps`)."""
        cfg = self.config
        clock = time.perf_counter()
        ego = snapshot.index_of(ego_id)
        if self.belief is not None:
            self.belief.observe(snapshot)
        lane, frame = self.planning_lane(snapshot, ego)
        now = snapshot.time
        self.manager.update_context(now, lane)
        all_params = self.params.arrays(snapshot)
        key = key_vehicles(snapshot, ego, frame, self._rear_reach(snapshot, ego, all_params))
        vehicles, params = self._vehicles(snapshot, ego, frame, key, all_params)
        v_ego = float(snapshot.speed[ego])
        mandatory = navigation.mandatory_change(frame, float(vehicles.s[0]), v_ego)
        # A mandatory change that the barrier held in the cycle before seeks its gap: slower than the target lane.
        seek = navigation.seek_speed(vehicles, mandatory) if mandatory is not None and mandatory is self._seeking \
            else np.inf
        self.stats.gap_seek_cycles += int(np.isfinite(seek))
        # A discretionary change held in the cycle before is kept while a gap lines up in time (gap_seek), the ego
        # slowing where only that makes one line up.
        line_up = self._line_up(snapshot, ego, frame, all_params, now, self._overtaking)
        self.stats.overtake_seek_cycles += int(line_up is not None)
        overtake_cap = line_up if line_up is not None and line_up < v_ego else np.inf
        speed_cap = min(seek, overtake_cap)  # the rollouts' desired speeds are capped by it and the reference
        v_ref = min(_reference_speed(frame, vehicles, v_ego, cfg.desired_speed), speed_cap)
        t_scene = time.perf_counter()

        policies = self._policies(now, frame, lane, navigation.held_sides(owed))
        probs = self._intentions(frame, key, snapshot)
        horizon = float(sum(policies[0].durations))
        branched = uncertain_agents(probs) & intention_matters(frame, vehicles, key.chain, probs, horizon)
        scenarios = branch_scenarios(probs, branched, cfg.scenarios_k) if cfg.scenarios_k > 1 else \
            branch_scenarios(probs, np.zeros(len(probs), dtype=bool), 1)
        rollouts, policy_of, weight_of = self._rollouts(policies, scenarios, key, vehicles, frame, v_ego, v_ref,
                                                        speed_cap, snapshot, ego, horizon)
        # The ego is planned as moving: with hold_standing a standing ego has a_acc = 0 now, which makes 0 m the
        # RSS distance to a stopped car ahead, but every rollout that moves it must keep the moving distance
        # (else it creeps up in pulses, each a new danger episode).
        ego_moving = RssParamArrays.stack([self.params.get(str(snapshot.vclass[ego]), str(snapshot.vtype[ego]))])
        params = replace(params, lon_accel_max=np.concatenate([ego_moving.lon_accel_max, params.lon_accel_max[1:]]))
        ego_params = _row(params, 0)
        s_front = float(vehicles.s[0]) + 0.5 * float(vehicles.length[0])
        limits = cfg.sim.ego_limits  # as the rollouts drive it through the junction, and brake it
        crossing = Crossing(limits.max_accel, lambda start, length: frame.chains.speed_cap(
            CURRENT, s_front + start, length, cfg.desired_speed), limits.hard_brake, limits.brake_jerk)
        stop = stop_line(snapshot, ego, self.network, self.junctions, self.routes, all_params, ego_moving, crossing)
        self.stats.stop_lines[stop.reason] = self.stats.stop_lines.get(stop.reason, 0) + 1
        t_setup = time.perf_counter()
        cut_in_gap = navigation.cut_in_gaps(snapshot, key, vehicles, owed, frame, v_ref)
        owed_due = self._owed_braking(snapshot, key, owed, float(ego_params.response_time))
        area = JunctionArea(stop.area_beyond, ego_moving) if np.isfinite(stop.distance + stop.area_beyond) else None
        # Where the ego's lane ends (an acceleration lane, not one that leaves the route) a held change waits ready;
        # a seeking change has no evasive speed-up.
        own_lanes = frame.chains.lanes[frame.chains.chain_of[CURRENT]]
        ready = mandatory is not None and bool(self.network.lane_ends[own_lanes[-1]])
        settings = replace(cfg.sim, evasive_speed_up=cfg.sim.evasive_speed_up and bool(np.isinf(seek) and
                                                                                np.isinf(overtake_cap)),
                           ready_wait=ready)
        sim = simulate(frame, vehicles, rollouts, policies[0].durations, settings, ego_params, params, cfg.sim_step,
                       s_front + stop.distance, cut_in_gap, area, owed_due)
        self._seeking = mandatory if mandatory is not None and navigation.change_held(
            mandatory, policies, policy_of, sim, float(vehicles.d[0]),
            np.inf if ready else navigation.STILL_IN_LANE_M) else None
        t_sim = time.perf_counter()
        nav = self.manager.navigation(now)
        if mandatory is not None and nav.recommended is None:
            nav = Navigation(recommended=mandatory)
        everything = policies + [Policy(Lon.DECELERATE, (Lat.KEEP,) * cfg.layers, policies[0].durations)]
        agents_params = params.take(np.arange(1, len(vehicles)))
        if cfg.mode == "mpdm":
            from .mpdm import mpdm_costs
            ev = mpdm_costs(sim, everything, policy_of, weight_of, v_ref, vehicles)
        else:
            ev = evaluate(sim, frame, everything, policy_of, weight_of, v_ref, nav, ego_params, agents_params,
                          vehicles.length, vehicles.width, cfg.costs,
                          cfg.sim.ego_idm.headway if cfg.sim.rss_following else None,
                          None if cut_in_gap is None else np.isfinite(cut_in_gap[1:]))
        n_real = len(policies)
        ctx = self.manager.context
        self._overtaking = None
        if navigation.change_stuck(ctx, now, policies, policy_of, sim, float(vehicles.d[0])):
            if line_up is None:
                line_up = self._line_up(snapshot, ego, frame, all_params, now, ctx.direction)
            if line_up is None:
                self.manager.call_off()
            else:
                self._overtaking = ctx.direction
        cost = np.where(ev.valid, ev.cost, np.inf)
        original = int(np.argmin(cost[:n_real])) if np.any(ev.valid[:n_real]) else None
        chosen = self.manager.select(policies, ev.cost[:n_real], ev.valid[:n_real], now)
        self.manager.propose(policies[original] if original is not None else None, now, v_ego, lane,
                             lanes_consistent_with(self.network, frame.chains.lanes[frame.chains.chain_of[CURRENT]]),
                             mandatory)
        backup = chosen is None
        winner = n_real if backup else chosen
        self.manager.commit(everything[winner], now)
        r = self._likely(policy_of, weight_of, winner)
        self._curvature = float(sim.ego_curvature[r, 1])
        if self.motion is None:
            frenet, trajectory = self._rollout_plan(frame, sim, r, vehicles, now)
        t_behaviour = time.perf_counter()
        if self.motion is not None:
            def emergency() -> tuple[FrenetPlan, Trajectory]:  # only built when the motion layer falls back
                return self._rollout_plan(frame, sim, self._likely(policy_of, weight_of, n_real), vehicles, now)
            frenet, trajectory = self.motion.plan(self._motion_input(frame, sim, r, vehicles, now, stop.distance,
                                                                     float(snapshot.accel[ego])),
                                                  emergency)
        done = time.perf_counter()
        self.stats.backups += int(backup)
        self.stats.cycle_times.append(done - clock)
        names = [p.name for p in policies] + [BACKUP]
        return PlanResult(trajectory, frenet, BACKUP if backup else names[winner],
                          {n: float(c) for n, c in zip(names, cost)},
                          {"scene": t_scene - clock, "setup": t_setup - t_scene, "simulate": t_sim - t_setup,
                           "evaluate": t_behaviour - t_sim, "motion": done - t_behaviour, "total": done - clock},
                          len(vehicles) - 1, len(scenarios.weights), backup)

    def _line_up(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame, all_params: RssParamArrays, now: float,
                 direction: Lat | None) -> float | None:
        """[m/s] :func:`.gap_seek.line_up_speed` for the discretionary lane-change context towards ``direction``
        before it expires (None: no such context, or no gap lines up in time), over every car seen within the key
        vehicles' search radius behind the ego (the gap the ego waits for may be beyond the rear reach that makes a
        car key)."""
        ctx = self.manager.context
        if direction is None or ctx is None or ctx.mandatory or ctx.direction is not direction:
            return None
        seen = key_vehicles(snapshot, ego, frame, np.full(len(snapshot.ids), SEARCH_RADIUS))
        vehicles, params = self._vehicles(snapshot, ego, frame, seen, all_params)
        within = ctx.operation_time + self.manager.settings.outdated_after - now
        return gap_seek.line_up_speed(vehicles, params, direction, within, navigation.SEEK_SLOWER,
                                      self.config.sim.commit_time, SEARCH_RADIUS)

    # -----------------------------------------------------------------------------------------------------
    def frame_for(self, snapshot: WorldSnapshot, ego: int) -> RoadFrame:
        """The planning frame along the ego's remaining route, around its :meth:`planning_lane`."""
        return self.planning_lane(snapshot, ego)[1]

    def planning_lane(self, snapshot: WorldSnapshot, ego: int) -> tuple[int, RoadFrame]:
        """The ego's lane for planning and its frame (:meth:`PlanningFrames.planning_lane`)."""
        return self.frames.planning_lane(snapshot, ego)

    @staticmethod
    def _rear_reach(snapshot: WorldSnapshot, ego: int, params: RssParamArrays) -> np.ndarray:
        """[m] per snapshot row: the RSS distance that car needs behind the ego (bumper gap) plus both half
        lengths, i.e. how far behind the ego's centre it still matters."""
        gap = formulas.lon_safe_distance_same_dir(snapshot.speed, snapshot.speed[ego], params,
                                                  params.take(np.array([ego])))
        return gap + 0.5 * (snapshot.length + snapshot.length[ego])

    def _vehicles(self, snapshot: WorldSnapshot, ego: int, frame: RoadFrame, key: KeyVehicles,
                  all_params: RssParamArrays) -> tuple[Vehicles, RssParamArrays]:
        rows = np.concatenate([[ego], key.rows]).astype(int)
        s_e, d_e, h_e = self.frames.ego_centre(snapshot, ego, frame)
        chain_e = frame.nearest_chain(s_e, d_e)
        n = rows.size
        ego_column, limits = np.arange(n) == 0, self.config.sim
        curvature = np.zeros(n)
        curvature[0] = self._curvature
        vehicles = Vehicles(
            s=np.concatenate([s_e, key.frame_s]), d=np.concatenate([d_e, key.frame_d]),
            heading=np.concatenate([h_e, key.heading]), speed=snapshot.speed[rows].astype(float),
            accel=np.clip(snapshot.accel[rows].astype(float), -np.where(ego_column, limits.ego_limits.hard_brake,
                                                                        limits.agent_limits.hard_brake),
                          np.where(ego_column, limits.ego_limits.max_accel, limits.agent_limits.max_accel)),
            curvature=curvature, length=snapshot.length[rows].astype(float), width=snapshot.width[rows].astype(float),
            chain=np.concatenate([chain_e, key.chain]).astype(int))
        params = all_params.take(rows)
        return vehicles, params

    @staticmethod
    def _owed_braking(snapshot: WorldSnapshot, key: KeyVehicles, owed: OwedResponses | None,
                      response_time: float) -> np.ndarray | None:
        """[s from now] per vehicle column: when the ego's response time ends in an open episode in which it owes
        that car (a car it follows) longitudinal braking (inf elsewhere; None: no such car among the key
        vehicles). The forward simulation brakes from then on while the pair is unsafe, as the guard will."""
        rows = owed.must_brake & owed.same_direction if owed is not None else np.zeros(0, dtype=bool)
        if not rows.any():
            return None
        match = snapshot.ids[key.rows][:, None] == owed.other_id[rows][None, :]
        due = np.where(match, (owed.t_b[rows] + response_time - snapshot.time)[None, :], np.inf).min(axis=1,
                                                                                                   initial=np.inf)
        return np.concatenate([[np.inf], due]) if np.isfinite(due).any() else None

    def _policies(self, now: float, frame: RoadFrame, lane: int, held: frozenset[Lat] = frozenset()) -> list[Policy]:
        """The DCP-tree's policies whose lanes exist. A change starts only towards a neighbour of the ego's lane
        on its edge (SUMO changes lanes within an edge; a ramp beside the motorway before they join is not one),
        and not towards a side ``held`` by a lateral response the ego owes in an open episode (the guard would hold
        it in its lane: planned, such a change only looked worth its navigation reward); an ongoing change goes
        on."""
        cfg = self.config
        ongoing = self.manager.ongoing(now)
        if cfg.mode == "mpdm":
            durations = (cfg.layer_duration,) * cfg.layers
            lats = [ongoing.lat] if ongoing.lat is not Lat.KEEP else list(Lat)
            out = [Policy(Lon.MAINTAIN, (lat,) * cfg.layers, durations) for lat in lats]
        else:
            out = valid_policies(ongoing, cfg.layers, cfg.layer_duration)
        startable = {Lat.KEEP: True,
                     Lat.LEFT: cfg.lane_changes and self.network.lane_left[lane] >= 0 and Lat.LEFT not in held,
                     Lat.RIGHT: cfg.lane_changes and self.network.lane_right[lane] >= 0 and Lat.RIGHT not in held}
        allowed = {lat for lat in Lat if frame.exists[_target(lat)] and (startable[lat] or lat is ongoing.lat)}
        return [p for p in out if allowed.issuperset(p.lats)]

    def _intentions(self, frame: RoadFrame, key: KeyVehicles, snapshot: WorldSnapshot) -> np.ndarray:
        chain = key.chain
        # Nobody changes into a lane that ends ahead of them (an acceleration lane seen from the motorway).
        enterable = frame.exists & ~np.isfinite(frame.end_s)
        has_left = (chain < LEFT) & enterable[np.minimum(chain + 1, LEFT)]
        has_right = (chain > RIGHT) & enterable[np.maximum(chain - 1, RIGHT)]
        probs = rule_belief(key.d, snapshot.lat_speed[key.rows], has_left, has_right, frame.end_s[chain] - key.frame_s)
        if self.belief is not None and key.rows.size:
            lanes = self.network.lane_indices(snapshot.lane_id[key.rows])
            learned, used = self.belief.lateral_probabilities(snapshot, key.rows, lanes)
            learned *= np.column_stack([np.ones(chain.size, dtype=bool), has_left, has_right])
            total = learned.sum(axis=1)
            used &= total > 0.0
            probs[used] = learned[used] / total[used, None]
            self.stats.learned_beliefs += int(used.sum())
        return probs

    def _rollouts(self, policies: list[Policy], scenarios, key: KeyVehicles, vehicles: Vehicles,
                  frame: RoadFrame, v_ego: float, v_ref: float, speed_cap: float, snapshot: WorldSnapshot, ego: int,
                  horizon: float) -> tuple[Rollouts, np.ndarray, np.ndarray]:
        """The rollouts of every (policy x scenario). EPSILON's ego holds its policy's speed within ``speed_cap``
        [m/s] (a gap seek's) and the reference speed along its own path (:meth:`ReferenceProfile.along`); MPDM's
        holds one speed command near ``v_ref`` [m/s], the reference speed now."""
        cfg = self.config
        P, K = len(policies) + 1, len(scenarios.weights)
        policy_of = np.repeat(np.arange(P), K)
        scenario_of = np.tile(np.arange(K), P)
        base = float(np.floor(v_ego))
        lon_v0 = {Lon.ACCELERATE: min(base + SPEED_STEP_A, speed_cap), Lon.MAINTAIN: min(base, speed_cap),
                  Lon.DECELERATE: min(max(base - SPEED_STEP_D, 0.0), speed_cap)}
        ego_chain = np.array([[_target(lat) for lat in p.lats] for p in policies] +
                             [[CURRENT] * cfg.layers], dtype=int)[policy_of]
        mpdm_v0 = float(np.clip(v_ref, v_ego - MPDM_SPEED_STEP, v_ego + MPDM_SPEED_STEP))
        v0 = np.array([lon_v0[p.lon] if cfg.mode == "epsilon" else mpdm_v0 for p in policies] + [0.0])[policy_of]
        scale = np.array([SPACING_SCALE_ACCELERATE if p.lon is Lon.ACCELERATE else 1.0 for p in policies] +
                         [1.0])[policy_of]
        intention = scenarios.intentions[scenario_of]  # [R, agents]
        step = np.array([0, 1, -1])[intention]  # keep, left, right
        agent_chain = np.clip(key.chain[None, :] + step, RIGHT, LEFT)
        agent_chain = np.where(frame.exists[agent_chain], agent_chain, key.chain[None, :])
        n = len(vehicles)
        chains = np.zeros((P * K, n), dtype=int)
        chains[:, 1:] = agent_chain
        a = snapshot.accel[key.rows]
        v = snapshot.speed[key.rows]
        agent_v0 = np.concatenate([[0.0], np.where(a >= 0.0, v, np.maximum(0.0, v + a * horizon))])
        ego_params = self.params.get(str(snapshot.vclass[ego]), str(snapshot.vtype[ego]))
        backup_brake = min(ego_params.lon_brake_min + 0.2, cfg.sim.ego_limits.hard_brake)
        limit = frame.chains.speed_limit(CURRENT, float(vehicles.s[0]), _speed_reach(v_ego))
        front = float(vehicles.s[0]) + 0.5 * float(vehicles.length[0])
        reach = max(v_ego, cfg.desired_speed) * (horizon + REFERENCE_PREVIEW)  # [m] the bumper's, and the preview's
        reference = ReferenceProfile.along(frame.chains, front, reach, cfg.desired_speed, REFERENCE_PREVIEW) \
            if cfg.mode == "epsilon" else None
        rollouts = Rollouts(ego_chain, v0, scale, policy_of == P - 1, backup_brake, chains, agent_v0, limit, reference)
        return rollouts, policy_of, scenarios.weights[scenario_of]

    @staticmethod
    def _likely(policy_of: np.ndarray, weight_of: np.ndarray, policy: int) -> int:
        """The rollout of ``policy`` in its most likely scenario."""
        candidates = np.flatnonzero(policy_of == policy)
        return int(candidates[np.argmax(weight_of[candidates])])

    def _rollout_plan(self, frame: RoadFrame, sim: SimResult, r: int, vehicles: Vehicles, now: float
                      ) -> tuple[FrenetPlan, Trajectory]:
        """Rollout ``r``'s ego states at absolute times every ``output_step``, interpolated in the frame
        (interpolating world points would cut across the vertices of a curved lane's polyline): in the frame and
        as front-bumper states."""
        step = self.config.output_step
        t = np.arange(0.0, float(sim.t[-1]) + 0.5 * step, step)
        accel = np.concatenate([sim.ego_accel[r, 1:], sim.ego_accel[r, -1:]])
        v_k, h_k = sim.speed[r, :, 0], sim.heading[r, :, 0]
        h, speed, accel = (np.interp(t, sim.t, a) for a in (h_k, v_k, accel))
        # Positions between the samples by their rates (v cos h, v sin h): linear ones disagreed with the speeds
        # by ½·a·t·(Δt − t) (−0.035 m per 0.1 s braking at 2.3 m/s² between MPDM's 0.4 s samples).
        s = _hermite(t, sim.t, sim.s[r, :, 0], v_k * np.cos(h_k))
        d = _hermite(t, sim.t, sim.d[r, :, 0], v_k * np.sin(h_k))
        x, y, heading = frame.bumper_at(s, d, h, 0.5 * float(vehicles.length[0]))
        return from_samples(frame, now + t, s, d, h, speed), Trajectory(now + t, x, y, heading, speed, accel)

    @staticmethod
    def _motion_input(frame: RoadFrame, sim: SimResult, r: int, vehicles: Vehicles, now: float,
                      stop_distance: float, measured_accel: float) -> MotionInput:
        """The motion layer's view of rollout ``r`` (the winner in its most likely scenario): the ego's and the
        agents' simulated trajectories, the ego's starting with its ``measured_accel`` [m/s²] (the forward
        simulation starts from it clipped to its own limits); the stop line as a bound on the ego's centre."""
        accel = sim.ego_accel[r].copy()
        accel[0] = measured_accel
        ego = (*(a[r, :, 0] for a in (sim.s, sim.d, sim.heading, sim.speed)), accel)
        agents = (sim.s[r, :, 1:], sim.d[r, :, 1:], sim.heading[r, :, 1:], vehicles.length[1:], vehicles.width[1:])
        return MotionInput(frame, now, sim.t, ego, float(vehicles.length[0]), float(vehicles.width[0]), agents,
                           float(vehicles.s[0]) + stop_distance)


def _learned_belief(network: RoadNetwork, period: float) -> LearnedBelief | None:
    """The intention network's belief (None if its weights are unusable), or None on a network where no lane
    branches or ends, which never asks it: torch is then not even imported (~2 s saved per run). ``period`` [s]:
    between two planning calls."""
    if not network_branches(network):
        return None
    from .intention.belief import LearnedBelief
    from .intention.estimator import load_estimator

    estimator = load_estimator()
    return LearnedBelief(network, estimator, period) if estimator is not None else None


def _reference_speed(frame: RoadFrame, vehicles: Vehicles, v_ego: float, desired: float) -> float:
    """[m/s] The ego's reference speed (:meth:`.lanes.LaneChains.reference_speed`): read at its front bumper (SUMO
    holds a car to the limit of the lane its front bumper is on) and REFERENCE_PREVIEW s at ``v_ego`` [m/s] ahead of
    it, the lower of the two (the preview brings lower speeds ahead nearer, never a higher limit: the ramp's 22.22 m/s
    holds until the bumper is on the acceleration lane)."""
    front = float(vehicles.s[0]) + 0.5 * float(vehicles.length[0])
    return min(frame.chains.reference_speed(CURRENT, front, desired),
               frame.chains.reference_speed(CURRENT, front + REFERENCE_PREVIEW * v_ego, desired))


def _speed_reach(v: float) -> float:
    """[m] How far ahead the ego's speed is planned from (epsilon.md §2.7): max(20, v²/1.67) at ``v`` [m/s]."""
    return max(20.0, v * v / 1.67)


def _target(lat: Lat) -> int:
    return TARGET_CHAIN[lat]


def _row(params: RssParamArrays, i: int):
    """One vehicle's parameters as scalars (an RssParamArrays of 0-d arrays)."""
    return RssParamArrays(**{k: np.asarray(v[i]) for k, v in vars(params).items()})


def _hermite(t: np.ndarray, knots: np.ndarray, values: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation at ``t`` of ``values`` with time derivatives ``rates`` at increasing ``knots``
    (exact for motion at a constant acceleration between them)."""
    k = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    span = knots[k + 1] - knots[k]
    u = (t - knots[k]) / span
    u2, u3 = u * u, u * u * u
    return (2 * u3 - 3 * u2 + 1) * values[k] + (u3 - 2 * u2 + u) * span * rates[k] + \
        (-2 * u3 + 3 * u2) * values[k + 1] + (u3 - u2) * span * rates[k + 1]

