"""Scenario files (TOML) → validated :class:`ScenarioSpec` records.

Every key is documented in ``docs/scenarios.md``. The whole file is validated once, here: unknown keys, wrong
types, out-of-range values, missing files and unknown networks or presets raise :class:`ScenarioError` naming
the file, the dotted key path and the expected form.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from .errors import ScenarioError
from .planner.behavior.cost_weights import CostWeights
from .road.topology import NetTopology, read_topology
from .rss.occlusion import OcclusionParams
from .rss.params import PRESETS, EvasiveParams
from .scenario_routes import check_depart_speed, check_route_permits, read_depart_lane, read_route
from .scenario_rss import RssSpec, read_rss
from .scenario_sumo import SumoSpec, read_input_files, read_sumo
from .sumo_home import vtype_attribute_names
from .validation import TableReader, one_of, read_toml

CAR_FOLLOW_MODELS = ("Krauss", "KraussPS", "KraussOrig1", "IDM", "EIDM", "ACC", "CACC", "W99", "Wiedemann")
# SL2015 needs SUMO's sublane model, which this project does not use (see docs/scenarios.md).
LANE_CHANGE_MODELS = ("LC2013",)
VEHICLE_CLASSES = ("passenger", "truck", "trailer", "bus", "coach", "delivery", "motorcycle", "emergency")
DEPART_SPEEDS = ("max", "desired", "avg", "random", "speedLimit", "last")
CONTROLLERS = ("sumo", "sumo_restricted", "epsilon", "mpdm")
BACKGROUND_DISTRIBUTION, EGO_TYPE = "background", "ego_type"  # vType ids of the generated route file
MAX_SEED = 2**31 - 1  # SUMO's --seed is a 32-bit signed integer
_NOT_IN_IDS = " \t\n\r|\\'\";,<>&"  # characters SUMO refuses in vehicle and vType ids
_NOT_IN_NAMES = "/\\,;"  # a scenario's name is a folder of its runs, inside SUMO's file lists (split on , and ;)
MAX_DURATION_S = 7 * 86400.0  # [s] the longest run a scenario may ask for
MAX_VEH_PER_HOUR = 20000.0  # [veh/h] the densest flow a scenario (or a batch's demand_scale) may ask for


def networks_root() -> Path:
    """Folder holding ``<name>/<name>.net.xml``: ``$SUMO_RSS_NETWORKS`` or the repository's ``networks/``."""
    env = os.environ.get("SUMO_RSS_NETWORKS")
    return Path(env) if env else Path(__file__).resolve().parent.parent / "networks"


def available_networks() -> list[str]:
    root = networks_root()
    return sorted(p.name for p in root.iterdir() if (p / f"{p.name}.net.xml").is_file()) if root.is_dir() else []


@dataclass(frozen=True)
class VehicleTypeSpec:
    """A SUMO vType. Lengths in m, speeds in m/s, accelerations in m/s², times in s."""

    id: str
    probability: float = 1.0  # share within the background distribution (normalised by SUMO)
    vclass: str = "passenger"
    length: float = 5.0
    width: float = 1.8
    min_gap: float = 2.5
    accel: float = 2.6
    decel: float = 4.5
    emergency_decel: float = 9.0
    sigma: float = 0.5  # driver imperfection in [0, 1]
    tau: float = 1.0  # desired time headway / reaction time
    max_speed: float = 55.56
    speed_factor: float = 1.0  # mean of the normal distribution of the speed factor
    speed_dev: float = 0.1  # its standard deviation
    car_follow_model: str = "Krauss"
    lane_change_model: str = "LC2013"
    car_follow_params: dict[str, float] = field(default_factory=dict)
    lane_change_params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FlowSpec:
    """Background traffic on one route: ``veh_per_hour`` (evenly spaced) or ``probability`` per second."""

    id: str
    route: tuple[str, ...]
    veh_per_hour: float | None
    probability: float | None
    begin_s: float
    end_s: float | None  # [s] None: until the end of the run (duration_s, also when an override changes it)
    depart_lane: str  # a lane index as a string, or one of scenario_routes.DEPART_LANES
    depart_speed: str | float  # [m/s], or one of DEPART_SPEEDS
    vtype: str | None  # None: the background vType distribution


@dataclass(frozen=True)
class DemandSpec:
    vtypes: tuple[VehicleTypeSpec, ...]
    flows: tuple[FlowSpec, ...]
    route_files: tuple[Path, ...] = ()  # absolute: SUMO route files of the user's own, loaded before the flows


@dataclass(frozen=True)
class PlannerOverrides:
    """EPSILON settings a scenario may change (epsilon.md, 'Decisions for our port')."""

    replan_every: int = 1  # plan every N SUMO steps
    layers: int = 5  # DCP-tree depth
    layer_duration_s: float = 1.0
    sim_step_s: float = 0.2  # forward-simulation step
    scenarios_k: int = 4  # CFB: most likely intention combinations kept
    intention_net: bool = True  # CFB uses the shipped intention network where lanes branch
    motion_layer: bool = True  # SSC corridor + Bézier QP; False executes the behaviour trajectory (docs/motion.md)
    lane_changes: bool = True  # False: only lane-keeping policies (the planner without lateral actions)
    rss_preset: str | None = None  # None: the scenario's RSS parameters for the ego class
    costs: dict[str, float] = field(default_factory=dict)  # CostWeights fields that differ from epsilon.md §9


@dataclass(frozen=True)
class EgoSpec:
    id: str
    route: tuple[str, ...]
    depart_s: float
    depart_lane: str  # an index as a string, or one of scenario_routes.DEPART_LANES
    depart_pos_m: float
    depart_speed: float
    desired_speed: float
    controller: str
    vehicle: VehicleTypeSpec
    planner: PlannerOverrides


@dataclass(frozen=True)
class OutputsSpec:
    fcd: bool = False  # SUMO FCD file with accelerations and lateral position/speed
    collisions_xml: bool = True  # SUMO's collision-output file


@dataclass(frozen=True)
class ScenarioSpec:
    name: str
    source: Path
    network: str
    net_file: Path
    duration_s: float
    step_s: float
    seed: int
    sumo: SumoSpec
    demand: DemandSpec
    ego: EgoSpec | None
    rss: RssSpec
    outputs: OutputsSpec

    def with_overrides(self, *, seed: int | None = None, duration_s: float | None = None,
                       controller: str | None = None) -> ScenarioSpec:
        spec = self
        if controller is not None:
            if controller not in CONTROLLERS:
                raise ScenarioError(self.source, "ego.controller", f"expected one of {', '.join(CONTROLLERS)}",
                                    controller)
            if self.ego is None:
                raise ScenarioError(self.source, "ego", "expected an [ego] table: the scenario has no ego to drive",
                                    has_got=False)
            spec = replace(spec, ego=replace(spec.ego, controller=controller))
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
                raise ScenarioError(self.source, "seed", f"expected an integer in [0, {MAX_SEED}]", seed)
            spec = replace(spec, seed=seed)
        if duration_s is not None:  # the file's duration_s is replaced: errors name the override, not the file's
            key = "duration_s override (e.g. --duration)"
            if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)):
                raise ScenarioError(self.source, key, "expected a number [s]", duration_s)
            if not duration_s > 0 or (self.ego is not None and duration_s <= self.ego.depart_s):
                lower = f"ego.depart_s ({self.ego.depart_s:g})" if self.ego is not None else "0"
                raise ScenarioError(self.source, key, f"expected a number > {lower}", duration_s)
            if not duration_s <= MAX_DURATION_S:
                raise ScenarioError(self.source, key, f"expected a number <= {MAX_DURATION_S:.0f} (7 days)",
                                    duration_s)
            for flow in self.demand.flows:  # a flow that runs until the end must begin before it
                if flow.end_s is None and duration_s <= flow.begin_s:
                    raise ScenarioError(self.source, key, f"expected a number > the begin_s of flow "
                                                          f"{flow.id!r} ({flow.begin_s:g})", duration_s)
            if not _whole_steps(duration_s, self.step_s):
                raise ScenarioError(self.source, key, _steps_expected(duration_s, self.step_s), duration_s)
            spec = replace(spec, duration_s=float(duration_s))
        return spec

    def to_toml_data(self) -> dict[str, Any]:
        """The resolved scenario in the scenario-file schema, every default filled in; loading it again
        gives an equal spec (the network is written as an absolute path)."""
        def vtype(vt: VehicleTypeSpec, *, probability: bool) -> dict[str, Any]:
            d = _plain(asdict(vt))
            del d["id"]
            if not probability:
                del d["probability"]
            return d

        def lane(value: str) -> str | int:
            return int(value) if value.isdigit() else value

        data: dict[str, Any] = {
            "name": self.name, "network": str(self.net_file), "duration_s": self.duration_s,
            "step_s": self.step_s, "seed": self.seed, "sumo": _plain(asdict(self.sumo)),
            "demand": {"vtypes": {vt.id: vtype(vt, probability=True) for vt in self.demand.vtypes},
                       "flows": [{**_plain(asdict(f)), "depart_lane": lane(f.depart_lane)}
                                 for f in self.demand.flows]},
            "rss": {"preset": self.rss.preset, "signal_rule": self.rss.signal_rule,
                    "hold_standing": self.rss.hold_standing, "raw_episodes": self.rss.raw_episodes,
                    "junction_brake_min": self.rss.junction_brake_min, **self.rss.role_overrides,
                    "vtypes": dict(self.rss.vtype_overrides)},
            "outputs": _plain(asdict(self.outputs)),
        }
        if self.rss.evasive != EvasiveParams():  # left out at the defaults: the scenario's hash stays what it was
            data["rss"].update(evasive_effort=self.rss.evasive.enabled, evasive_horizon_s=self.rss.evasive.horizon_s,
                               evasive_lookback_s=self.rss.evasive.lookback_s)
        if self.rss.occlusion != OcclusionParams():  # the same: left out at the defaults
            o = self.rss.occlusion
            data["rss"].update(occlusion=o.enabled, occluders=_plain(o.occluders), occluder_min_height_m=o.min_height_m,
                               occluded_speed_factor=o.speed_factor, occluded_yield_speed_ms=o.yield_speed_ms,
                               occluded_yield_zone_m=o.yield_zone_m, occluded_lat_speed_ms=o.lat_speed_ms)
        # SUMO files of the user's own, as absolute paths (left out where there are none: the hash of a scenario
        # without them is what it was before they could be given)
        if self.demand.route_files:
            data["demand"]["route_files"] = _plain(self.demand.route_files)
        if not self.sumo.additional_files:
            del data["sumo"]["additional_files"]
        if self.ego is not None:
            ego = _plain(asdict(self.ego))
            ego.update(depart_lane=lane(self.ego.depart_lane), vehicle=vtype(self.ego.vehicle, probability=False))
            data["ego"] = ego
        return data


def _plain(value: Any) -> Any:
    """Dataclass data → TOML-ready data: tuples become lists, paths strings, None values are dropped."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


# ---------------------------------------------------------------------------------------------------------
def load_scenario(path: str | Path) -> ScenarioSpec:
    """Read and validate a scenario file."""
    path = Path(path)
    return parse_scenario(read_toml(path, "scenario"), path)


def _whole_steps(duration: float, step: float) -> bool:
    """Whether ``duration`` [s] is a whole number of steps of ``step`` [s] (up to float rounding)."""
    steps = duration / step
    return abs(steps - round(steps)) <= 1e-6 * max(1.0, steps)


def _steps_expected(duration: float, step: float) -> str:
    """The error text for a duration [s] that is not a whole number of steps [s]: the two nearest that are."""
    below = math.floor(duration / step) * step
    return (f"expected a whole number of steps of step_s = {step:g} s (the run stops at a step), e.g. "
            f"{below:.6g} or {below + step:.6g}")


def parse_scenario(data: dict[str, Any], path: Path) -> ScenarioSpec:
    if isinstance(data.get("batch"), dict):
        raise ScenarioError(path, "batch", "expected a scenario file, not a batch file ([batch] table): run it with "
                                           "'sumo-rss batch'", has_got=False)
    top = TableReader(data, path)
    name = top.string("name", path.stem)
    if name.startswith(".") or any(c in name for c in _NOT_IN_NAMES) or not name.isprintable():
        raise top.error("name", "expected a name for the run folders: printable, not starting with '.', without "
                                "'/', '\\', ',' or ';' (the default is the file's name)", name)
    network, net_file = _read_network(top, path)
    topology = _topology(top, net_file)
    duration = top.number("duration_s", min=0.0, max=MAX_DURATION_S, min_exclusive=True)
    step = top.number("step_s", 0.1, min=0.001, max=1.0)
    if abs(step * 1000.0 - round(step * 1000.0)) > 1e-6:
        raise top.error("step_s", "expected a whole number of milliseconds (SUMO rounds its step to 1 ms)", step)
    if not _whole_steps(duration, step):
        raise top.error("duration_s", _steps_expected(duration, step), duration)
    seed = top.integer("seed", 0, min=0, max=MAX_SEED)
    sumo = read_sumo(top.table("sumo"), path)
    demand = _read_demand(top.table("demand"), topology, duration, path)
    ego = _read_ego(top.table("ego"), topology, duration) if top.has("ego") else None
    if ego is not None:
        if ego.id in {f.id for f in demand.flows}:
            raise ScenarioError(path, "ego.id", "expected an id other than the flows' (each names its route "
                                                "route_<id> in the route file)", ego.id)
        clash = next((f.id for f in demand.flows if re.fullmatch(rf"{re.escape(f.id)}\.\d+", ego.id)), None)
        if clash is not None:
            raise ScenarioError(path, "ego.id", f"expected an id that is not a vehicle of flow {clash!r} "
                                                f"(named {clash}.0, {clash}.1, ...)", ego.id)
    rss = read_rss(top.table("rss"), demand, ego, path)
    outputs_t = top.table("outputs")
    outputs = OutputsSpec(fcd=outputs_t.boolean("fcd", False), collisions_xml=outputs_t.boolean("collisions_xml", True))
    outputs_t.finish()
    top.finish()
    return ScenarioSpec(name, path, network, net_file, duration, step, seed, sumo, demand, ego, rss, outputs)


def _read_network(top: TableReader, path: Path) -> tuple[str, Path]:
    value = top.string("network")
    suffix = next((end for end in (".net.xml", ".net.xml.gz") if value.endswith(end)), None)
    if suffix is not None:
        net_file = (path.parent / value).resolve()
        if not net_file.is_file():
            raise top.error("network", f"expected an existing {suffix} file (looked for {net_file})", value)
        return net_file.name[: -len(suffix)], net_file
    net_file = networks_root() / value / f"{value}.net.xml"
    if not net_file.is_file():
        names = ", ".join(available_networks()) or f"none found under {networks_root()}"
        raise top.error("network", f"expected a network name ({names}) or a path to a .net.xml", value)
    return value, net_file


def _topology(top: TableReader, net_file: Path) -> NetTopology:
    try:
        return read_topology(net_file)
    except ValueError as exc:
        raise top.error("network", str(exc)) from exc


def _sumo_id(t: TableReader, key: str, value: str) -> str:
    """``value`` (read at ``key``) if SUMO accepts it as a vehicle, flow or vType id."""
    if any(c in value for c in _NOT_IN_IDS) or not value.isprintable():
        raise t.error(key, "expected an id SUMO accepts: no spaces and none of | \\ ' \" ; , < > &", value)
    return value


def _read_vtype(t: TableReader, vtype_id: str, *, with_probability: bool) -> VehicleTypeSpec:
    d = VehicleTypeSpec(vtype_id)
    spec = VehicleTypeSpec(
        id=vtype_id,
        probability=t.number("probability", d.probability, min=0.0) if with_probability else 1.0,
        vclass=t.string("vclass", d.vclass, choices=VEHICLE_CLASSES),
        length=t.number("length", d.length, min=0.5, max=30.0),
        width=t.number("width", d.width, min=0.3, max=4.0),
        min_gap=t.number("min_gap", d.min_gap, min=0.0, max=20.0),
        accel=t.number("accel", d.accel, min=0.0, max=15.0, min_exclusive=True),
        decel=t.number("decel", d.decel, min=0.0, max=15.0, min_exclusive=True),
        emergency_decel=t.number("emergency_decel", d.emergency_decel, min=0.0, max=20.0, min_exclusive=True),
        sigma=t.number("sigma", d.sigma, min=0.0, max=1.0),
        tau=t.number("tau", d.tau, min=0.0, max=10.0, min_exclusive=True),
        max_speed=t.number("max_speed", d.max_speed, min=0.0, max=100.0, min_exclusive=True),
        speed_factor=t.number("speed_factor", d.speed_factor, min=0.0, max=3.0, min_exclusive=True),
        speed_dev=t.number("speed_dev", d.speed_dev, min=0.0, max=1.0),
        car_follow_model=t.string("car_follow_model", d.car_follow_model, choices=CAR_FOLLOW_MODELS),
        lane_change_model=t.string("lane_change_model", d.lane_change_model, choices=LANE_CHANGE_MODELS),
        car_follow_params=_model_params(t, "car_follow_params", lane_change=False),
        lane_change_params=_model_params(t, "lane_change_params", lane_change=True),
    )
    if spec.emergency_decel < spec.decel:
        raise t.error("emergency_decel", f"expected a number >= decel ({spec.decel:g})", spec.emergency_decel)
    t.finish()
    return spec


# vType attributes that have their own scenario keys (or are set by sumo_rss) and so are not model params.
_OWN_VTYPE_ATTRIBUTES = frozenset({
    "id", "refId", "probability", "vClass", "length", "width", "minGap", "accel", "decel", "emergencyDecel",
    "sigma", "tau", "maxSpeed", "speedFactor", "speedDev", "carFollowModel", "laneChangeModel"})


def _model_params(t: TableReader, key: str, *, lane_change: bool) -> dict[str, float]:
    """Extra car-following / lane-change attributes, checked against SUMO's own vType schema."""
    params = t.number_table(key)
    allowed = sorted(name for name in vtype_attribute_names() - _OWN_VTYPE_ATTRIBUTES
                     if name.startswith("lc") == lane_change)
    for name in params:
        if name not in allowed:
            kind = "lane-change (lc...)" if lane_change else "car-following"
            raise ScenarioError(t.file, f"{t.key_path(key)}.{name}",
                                f"expected a SUMO {kind} vType attribute such as {', '.join(allowed[:6])}, ...",
                                name)
    return params


def _read_demand(t: TableReader, topology: NetTopology, duration: float, path: Path) -> DemandSpec:
    vtypes = tuple(_read_vtype(r, _sumo_id(t, f"vtypes.{name}", name), with_probability=True)
                   for name, r in t.named_tables("vtypes").items())
    if not vtypes:
        vtypes = (VehicleTypeSpec("car"),)
    names = {v.id for v in vtypes}
    flows = []
    for i, f in enumerate(t.table_list("flows")):
        route = read_route(f, topology)
        kind = one_of(f, ("veh_per_hour", "probability"))
        begin = f.number("begin_s", 0.0, min=0.0)
        end = f.number("end_s", min=0.0, optional=True)
        last = duration if end is None else end  # [s] when the flow stops
        if last <= begin:
            raise f.error("end_s", f"expected a number > begin_s ({begin:g})", last)
        speed = f.raw("depart_speed", "desired")
        if not (speed in DEPART_SPEEDS or (isinstance(speed, (int, float)) and not isinstance(speed, bool)
                                           and 0 <= speed <= 100)):
            raise f.error("depart_speed", f"expected a speed in [0, 100] m/s or one of "
                                          f"{', '.join(repr(v) for v in DEPART_SPEEDS)}", speed)
        vtype = f.string("vtype", None, choices=sorted(names)) if f.has("vtype") else None
        drawn = [v for v in vtypes if (v.id == vtype if vtype else v.probability > 0)]  # the flow's vTypes
        if not isinstance(speed, str):
            slowest = min(drawn, key=lambda v: v.max_speed)
            check_depart_speed(f, float(speed), topology.edges[route[0]], slowest.max_speed,
                               f"the max_speed of vType {slowest.id!r}", min(v.speed_factor for v in drawn))
        depart_lane = read_depart_lane(f, route[0], topology)
        for v in drawn:
            check_route_permits(f, route, v.vclass, f"vType {v.id!r}", topology, depart_lane)
        flows.append(FlowSpec(
            id=_sumo_id(f, "id", f.string("id", f"flow{i}")), route=route,
            veh_per_hour=f.number("veh_per_hour", min=0.0, max=MAX_VEH_PER_HOUR, min_exclusive=True)
            if kind == "veh_per_hour" else None,
            probability=f.number("probability", min=0.0, max=1.0, min_exclusive=True)
            if kind == "probability" else None,
            begin_s=begin, end_s=end, depart_lane=depart_lane,
            depart_speed=speed if isinstance(speed, str) else float(speed), vtype=vtype))
        f.finish()
    ids = [fl.id for fl in flows]
    if len(set(ids)) != len(ids):
        raise t.error("flows", "expected unique flow ids", ids)
    reserved = sorted(names & {BACKGROUND_DISTRIBUTION, EGO_TYPE})
    if reserved:
        raise t.error(f"vtypes.{reserved[0]}", f"expected another name: {BACKGROUND_DISTRIBUTION!r} and {EGO_TYPE!r} "
                                               "are the route file's own vType names", reserved[0])
    drawing = [fl.id for fl in flows if fl.vtype is None]
    if drawing and not any(v.probability > 0 for v in vtypes):  # 0: only for flows that name the vType
        raise t.error("vtypes", f"expected a vType with probability > 0 for the flows that draw from the mix "
                                f"({', '.join(drawing)})", {v.id: v.probability for v in vtypes})
    route_files = read_input_files(t, "route_files", path)
    t.finish()
    return DemandSpec(vtypes, tuple(flows), route_files)


def _read_planner(t: TableReader) -> PlannerOverrides:
    d = PlannerOverrides()
    spec = PlannerOverrides(
        replan_every=t.integer("replan_every", d.replan_every, min=1, max=100),
        layers=t.integer("layers", d.layers, min=1, max=10),
        layer_duration_s=t.number("layer_duration_s", d.layer_duration_s, min=0.1, max=5.0),
        sim_step_s=t.number("sim_step_s", d.sim_step_s, min=0.01, max=1.0),
        scenarios_k=t.integer("scenarios_k", d.scenarios_k, min=1, max=64),
        intention_net=t.boolean("intention_net", d.intention_net),
        motion_layer=t.boolean("motion_layer", d.motion_layer),
        lane_changes=t.boolean("lane_changes", d.lane_changes),
        rss_preset=t.string("rss_preset", None, choices=PRESETS) if t.has("rss_preset") else None,
        costs=_read_cost_weights(t.table("costs")) if t.has("costs") else {},
    )
    t.finish()
    return spec


def _read_cost_weights(t: TableReader) -> dict[str, float]:
    """EUDM's cost weights (``CostWeights`` fields): numbers >= 0; the discount in (0, 1]."""
    defaults, out = CostWeights(), {}
    for name in CostWeights.__dataclass_fields__:
        given = t.has(name)
        value = t.number(name, getattr(defaults, name), min=0.0, min_exclusive=name == "discount",
                         max=1.0 if name == "discount" else None)
        if given:
            out[name] = value
    t.finish()
    return out


def _read_ego(t: TableReader, topology: NetTopology, duration: float) -> EgoSpec:
    route = read_route(t, topology)
    first = topology.edges[route[0]]
    depart_s = t.number("depart_s", 0.0, min=0.0)
    if depart_s >= duration:
        raise t.error("depart_s", f"expected a time before the end of the run (duration_s = {duration:g})",
                      depart_s)
    spec = EgoSpec(
        id=_sumo_id(t, "id", t.string("id", "ego")), route=route, depart_s=depart_s,
        depart_lane=read_depart_lane(t, route[0], topology),
        depart_pos_m=t.number("depart_pos_m", 0.0, min=0.0, max=first.length),
        depart_speed=t.number("depart_speed", 0.0, min=0.0, max=100.0),
        desired_speed=t.number("desired_speed", min=0.0, max=100.0, min_exclusive=True),
        controller=t.string("controller", "sumo", choices=CONTROLLERS),
        vehicle=_read_vtype(t.table("vehicle"), "ego", with_probability=False),
        planner=_read_planner(t.table("planner")),
    )
    check_depart_speed(t, spec.depart_speed, first, min(spec.vehicle.max_speed, spec.desired_speed),
                       "the ego's top speed under SUMO, min(vehicle.max_speed, desired_speed)",
                       spec.vehicle.speed_factor)
    check_route_permits(t, route, spec.vehicle.vclass, "the ego", topology, spec.depart_lane)
    t.finish()
    return spec
