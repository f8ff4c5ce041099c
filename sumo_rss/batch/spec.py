"""Batch files: scenarios x seeds x variants (a grid of parameter sweeps), expanded into run tasks.

```toml
[batch]
scenarios = ["highway_dense.toml", "merge_onramp.toml"]   # relative to this file
seeds = [0, 1]                                            # or "0:20" (20 excluded)

[batch.grid]                                              # optional: every combination is a variant
rss_preset = ["ad_rss", "krauss"]
demand_scale = [0.5, 1.0]                                 # multiplies every flow's rate
controller = ["sumo"]                                     # the ego's controller
```
"""
from __future__ import annotations

import functools
import hashlib
import itertools
import json
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import ScenarioError, shown
from ..road.build import without_generator_header
from ..rss.params import PRESETS
from ..scenario import CONTROLLERS, MAX_SEED, MAX_VEH_PER_HOUR, ScenarioSpec, load_scenario
from ..scenario_rss import rss_inconsistency
from ..validation import TableReader, read_toml

GRID_KEYS = ("rss_preset", "demand_scale", "controller")
MAX_SEEDS = 100_000  # seeds of one batch (a range is checked before it is expanded)


@dataclass(frozen=True)
class Task:
    """One run: a scenario (with the variant applied) and a seed."""

    spec: ScenarioSpec
    variant: str  # '' for the scenario as written, else e.g. 'rss_preset=krauss+demand_scale=0.5'

    @property
    def run_id(self) -> str:
        """``<scenario>[__<variant>]/<seed>``: the run's folder below the batch folder, and its key in CSVs."""
        return f"{self.spec.name}{'__' + self.variant if self.variant else ''}/{self.spec.seed}"

    def parameter_hash(self, custom_controller: str | None = None) -> str:
        """SHA-256 of the resolved scenario: two runs with the same hash simulate the same thing. The network
        counts by its content, not its path or netconvert's build-date comment: a moved or re-cloned checkout, or
        `sumo-rss nets build` of the same sources, resumes its batches; so do the scenario's route and additional
        files. A run whose ego a Python controller drove
        (``custom_controller``: its class) hashes differently from the scenario's own."""
        data = self.spec.to_toml_data()
        data["network"] = _file_digest(self.spec.net_file)
        for table, key, files in (("demand", "route_files", self.spec.demand.route_files),
                                  ("sumo", "additional_files", self.spec.sumo.additional_files)):
            if files:
                data[table][key] = [_file_digest(p) for p in files]
        if custom_controller is not None:
            data["custom_controller"] = custom_controller
        text = json.dumps(data, sort_keys=True, default=str)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()


@functools.lru_cache(maxsize=64)
def _cached_digest(path: Path, size: int, modified_ns: int) -> str:
    content = without_generator_header(path.read_bytes().decode("utf-8", errors="surrogateescape"))
    return hashlib.sha256(content.encode("utf-8", errors="surrogateescape")).hexdigest()


def _file_digest(path: Path) -> str:
    """SHA-256 of a network file's content without netconvert's leading comment (read again only when its size or
    modification time changed)."""
    status = path.stat()
    return _cached_digest(path.resolve(), status.st_size, status.st_mtime_ns)


@dataclass(frozen=True)
class BatchSpec:
    source: Path
    scenarios: tuple[ScenarioSpec, ...]
    seeds: tuple[int, ...]
    grid: dict[str, tuple]  # key of GRID_KEYS → values; empty for no sweep

    def tasks(self) -> list[Task]:
        """Every (scenario, variant, seed), in that nesting order."""
        variants = [dict(zip(self.grid, values)) for values in itertools.product(*self.grid.values())] \
            if self.grid else [{}]
        return [Task(apply_variant(spec, v).with_overrides(seed=seed), variant_name(v))
                for spec in self.scenarios for v in _distinct_variants(spec, variants) for seed in self.seeds]


def _distinct_variants(spec: ScenarioSpec, variants: list[dict]) -> list[dict]:
    """The variants that change this scenario: without an ego, a controller sweep has nothing to sweep, so its
    variants lose the controller and collapse into one run each (not one identical run per controller)."""
    if spec.ego is not None:
        return variants
    kept = [{k: v for k, v in values.items() if k != "controller"} for values in variants]
    return [dict(items) for items in dict.fromkeys(tuple(values.items()) for values in kept)]


def variant_name(values: dict) -> str:
    """E.g. 'rss_preset=krauss+demand_scale=0.5' (no commas: SUMO splits file lists on them)."""
    return "+".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())


def apply_variant(spec: ScenarioSpec, values: dict) -> ScenarioSpec:
    """The scenario with the variant's overrides; raises ScenarioError for an impossible combination."""
    if "rss_preset" in values:
        spec = replace(spec, rss=replace(spec.rss, preset=values["rss_preset"]))
        problem = rss_inconsistency(spec.rss, spec.demand, spec.ego)  # the overrides under the new preset
        if problem is not None:
            raise ScenarioError(spec.source, f"rss.{problem[0]}", problem[1], has_got=False)
    if "demand_scale" in values:
        scale = values["demand_scale"]
        for i, flow in enumerate(spec.demand.flows):
            if flow.probability is not None and flow.probability * scale > 1.0:
                # SUMO draws at most one vehicle per second from a probability flow
                raise ScenarioError(spec.source, f"demand.flows[{i}].probability",
                                    f"demand_scale {scale:g} makes it {flow.probability * scale:g} per second, above "
                                    "the at most 1 of a probability flow (give the flow as veh_per_hour to scale it "
                                    "further)", has_got=False)
            if flow.veh_per_hour is not None and flow.veh_per_hour * scale > MAX_VEH_PER_HOUR:
                raise ScenarioError(spec.source, f"demand.flows[{i}].veh_per_hour",
                                    f"demand_scale {scale:g} makes it {flow.veh_per_hour * scale:g} veh/h, above the "
                                    f"at most {MAX_VEH_PER_HOUR:g} veh/h of a flow", has_got=False)
        flows = tuple(replace(f, veh_per_hour=f.veh_per_hour * scale if f.veh_per_hour is not None else None,
                              probability=f.probability * scale if f.probability is not None else None)
                      for f in spec.demand.flows)
        spec = replace(spec, demand=replace(spec.demand, flows=flows))
    if "controller" in values and spec.ego is not None:  # a scenario without an ego runs as it is
        spec = spec.with_overrides(controller=values["controller"])
    return spec


def parse_seeds(value: object, reader: TableReader | None = None) -> tuple[int, ...]:
    """``[0, 1, 5]``, ``"0:20"`` (20 excluded) or ``"1,7,42"`` → seeds; ValueError (or the reader's
    ScenarioError) otherwise."""
    def fail() -> Exception:
        expected = f"expected a list of integers in [0, {MAX_SEED}], 'A:B' or 'a,b,c' (at most {MAX_SEEDS} seeds)"
        return reader.error("seeds", expected, value) if reader else ValueError(f"{expected}, got {shown(value)}")

    try:
        if isinstance(value, str) and ":" in value:
            lo, hi = (int(x) for x in value.split(":", 1))
            if hi - lo > MAX_SEEDS:
                raise fail()
            seeds = list(range(lo, hi))
        elif isinstance(value, str):
            seeds = [int(x) for x in value.split(",")]
        elif isinstance(value, list) and all(isinstance(s, int) and not isinstance(s, bool) for s in value):
            seeds = list(value)
        else:
            raise fail()
    except ValueError:
        raise fail() from None
    if not seeds or len(seeds) > MAX_SEEDS or min(seeds) < 0 or max(seeds) > MAX_SEED:
        raise fail()
    return tuple(dict.fromkeys(seeds))


def load_batch(path: str | Path) -> BatchSpec:
    """Read and validate a batch file; scenario paths are relative to it."""
    path = Path(path)
    top = TableReader(read_toml(path, "batch"), path)
    batch = top.table("batch", required=True)
    files = batch.string_list("scenarios")
    seeds = parse_seeds(batch.raw("seeds", [0]), batch)
    grid_t = batch.table("grid")
    grid = {}
    for key, kind in (("rss_preset", PRESETS), ("controller", CONTROLLERS)):
        if grid_t.has(key):
            grid[key] = grid_t.string_list(key)
            bad = [v for v in grid[key] if v not in kind]
            if bad:
                raise grid_t.error(key, f"expected values among {', '.join(kind)}", bad)
    if grid_t.has("demand_scale"):
        scales = grid_t.raw("demand_scale")
        if not isinstance(scales, list) or not scales or not all(
                isinstance(s, (int, float)) and not isinstance(s, bool) and 0 < s <= 10 for s in scales):
            raise grid_t.error("demand_scale", "expected a list of numbers in (0, 10]", scales)
        grid["demand_scale"] = tuple(float(s) for s in scales)
    grid_t.finish()
    batch.finish()
    top.finish()
    specs = []
    for i, name in enumerate(files):
        scenario_file = path.parent / name
        if not scenario_file.is_file():
            raise batch.error(f"scenarios[{i}]", f"expected an existing scenario file (looked for {scenario_file})",
                              name)
        specs.append(load_scenario(scenario_file))
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise batch.error("scenarios", "expected scenarios with distinct names (their results folders)", names)
    return BatchSpec(path, tuple(specs), seeds, {k: tuple(v) for k, v in grid.items()})
