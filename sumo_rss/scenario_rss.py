"""The ``[rss]`` table of a scenario file: preset, per-role and per-vType parameter overrides, signal rule,
hold_standing and the episode and junction-response rules, validated so that every vehicle class resolves to consistent RSS parameters (docs/scenarios.md)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .rss.occlusion import OcclusionParams
from .rss.params import PARAM_NAMES, PRESETS, ROLES, EvasiveParams, evasive_params, resolve_params
from .validation import TableReader

if TYPE_CHECKING:
    from .scenario import DemandSpec, EgoSpec


@dataclass(frozen=True)
class RssSpec:
    preset: str = "ad_rss"
    signal_rule: bool = True  # red-light and avoidable yellow-light entries are violations
    role_overrides: dict[str, dict[str, float]] = field(default_factory=dict)
    vtype_overrides: dict[str, dict[str, float]] = field(default_factory=dict)
    hold_standing: bool = False  # CARLA's convention: a car standing still does not accelerate during ρ
    raw_episodes: bool = False  # an episode re-opening within ρ of its end is a new one (default: it continues)
    junction_brake_min: bool = False  # ad_rss's reading: a yielding car brakes at b_min even if it stops before
    evasive: EvasiveParams = field(default_factory=EvasiveParams)  # rule 5: evasive_effort, _horizon_s, _lookback_s
    occlusion: OcclusionParams = field(default_factory=OcclusionParams)  # rule 4: occlusion, occluders, occlu*_


def read_rss(t: TableReader, demand: DemandSpec, ego: EgoSpec | None, scenario_file: Path) -> RssSpec:
    preset = t.string("preset", "ad_rss", choices=PRESETS)
    signal_rule = t.boolean("signal_rule", True)
    hold_standing = t.boolean("hold_standing", False)
    raw_episodes, junction_brake_min = t.boolean("raw_episodes", False), t.boolean("junction_brake_min", False)
    evasive = evasive_params(preset, t.number("evasive_horizon_s", EvasiveParams.horizon_s, min=0.0, max=10.0,
                                              min_exclusive=True),
                             t.number("evasive_lookback_s", EvasiveParams.lookback_s, min=0.0, max=60.0,
                                      min_exclusive=True),
                             t.boolean("evasive_effort", False))
    occlusion = _read_occlusion(t, scenario_file)
    roles = {role: _read_param_overrides(t.table(role)) for role in ROLES if t.has(role)}
    vtype_ids = {v.id for v in demand.vtypes}
    by_vtype = {}
    for name, r in t.named_tables("vtypes").items():
        if name not in vtype_ids:
            raise t.error(f"vtypes.{name}", f"expected a vType of demand.vtypes ({', '.join(sorted(vtype_ids))})",
                          name)
        by_vtype[name] = _read_param_overrides(r)
    t.finish()
    spec = RssSpec(preset, signal_rule, roles, by_vtype, hold_standing, raw_episodes, junction_brake_min, evasive,
                   occlusion)
    problem = rss_inconsistency(spec, demand, ego)  # inconsistent overrides fail here, at load time
    if problem is not None:
        raise t.error(*problem)
    return spec


def rss_inconsistency(rss: RssSpec, demand: DemandSpec, ego: EgoSpec | None) -> tuple[str, str] | None:
    """(key below [rss], message) of the first vehicle class whose RSS parameters the preset and overrides of
    ``rss`` make inconsistent (each class is resolved once), or None."""
    checks = [("background", v.id, v) for v in demand.vtypes] + ([("ego", None, ego.vehicle)] if ego else [])
    for role, vtype_id, vt in checks:
        try:
            resolve_params(rss.preset, role, vtype_id, role_overrides=rss.role_overrides,
                           vtype_overrides=rss.vtype_overrides, tau=vt.tau, decel=vt.decel)
        except ValueError as exc:
            key = f"vtypes.{vtype_id}" if vtype_id in rss.vtype_overrides else role
            who = f"{role} vType {vtype_id!r}" if vtype_id else role
            return key, f"inconsistent RSS parameters for {who} (preset {rss.preset!r}): {exc}"
    return None


def _read_param_overrides(t: TableReader) -> dict[str, float]:
    out = {name: t.number(name) for name in PARAM_NAMES if t.has(name)}
    t.finish()
    return out


def _read_occlusion(t: TableReader, scenario_file: Path) -> OcclusionParams:
    """Rule 4's keys (docs/rss.md "Rule 4"): ``occlusion`` (on; also implied by ``occluders``), ``occluders`` (SUMO
    additional files with <poly> occluders, relative to the scenario file) and the parameters of rss.md §9."""
    from .scenario_sumo import read_input_files

    defaults = OcclusionParams()
    occluders = read_input_files(t, "occluders", scenario_file)
    return OcclusionParams(
        enabled=t.boolean("occlusion", bool(occluders)) or bool(occluders),
        min_height_m=t.number("occluder_min_height_m", defaults.min_height_m, min=0.0, max=20.0),
        speed_factor=t.number("occluded_speed_factor", defaults.speed_factor, min=1.0, max=10.0),
        yield_speed_ms=t.number("occluded_yield_speed_ms", defaults.yield_speed_ms, min=0.0, max=100.0),
        yield_zone_m=t.number("occluded_yield_zone_m", defaults.yield_zone_m, min=0.0, max=1000.0),
        lat_speed_ms=t.number("occluded_lat_speed_ms", defaults.lat_speed_ms, min=0.0, max=10.0),
        occluders=occluders)
