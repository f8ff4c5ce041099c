"""DCP-tree: the domain-specific closed-loop policy tree of EUDM (epsilon.md §2.3).

A policy is a sequence of ``layers`` semantic actions. The longitudinal action (maintain, accelerate, decelerate)
is constant along a sequence; the lateral action (keep, lane change left/right) starts as the ongoing one and may
change once. The first layer lasts what remains of the ongoing action, so decision points stay on a fixed grid.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from enum import Enum


class Lon(str, Enum):
    MAINTAIN = "M"
    ACCELERATE = "A"
    DECELERATE = "D"


class Lat(str, Enum):
    KEEP = "K"
    LEFT = "L"
    RIGHT = "R"


@dataclass(frozen=True)
class Action:
    lon: Lon
    lat: Lat
    duration: float  # [s]


@dataclass(frozen=True)
class Policy:
    """One sequence of actions (a path through the tree). Its derived properties are computed once per policy: the
    planner gets the same policy objects every cycle from :func:`valid_policies`."""

    lon: Lon
    lats: tuple[Lat, ...]
    durations: tuple[float, ...]  # [s] per layer

    @functools.cached_property
    def name(self) -> str:
        """E.g. 'M:KKLLL'."""
        return f"{self.lon.value}:{''.join(lat.value for lat in self.lats)}"

    @functools.cached_property
    def lateral(self) -> Lat:
        """The sequence-level lateral behaviour: its first lane change, else keep."""
        return next((lat for lat in self.lats if lat is not Lat.KEEP), Lat.KEEP)

    @functools.cached_property
    def is_cancel(self) -> bool:
        """A lane change that returns to keep (e.g. 'LKKKK' started during an ongoing left change)."""
        return self.lats[0] is not Lat.KEEP and Lat.KEEP in self.lats[1:]

    @functools.cached_property
    def is_valid(self) -> bool:
        """No direct switch between opposite lane changes (L→R or R→L): pre-deleted, never simulated."""
        return not any({a, b} == {Lat.LEFT, Lat.RIGHT} for a, b in zip(self.lats, self.lats[1:]))

    @property
    def horizon(self) -> float:
        return sum(self.durations)


def ongoing_action(previous: Policy | None, elapsed: float, layer_duration: float = 1.0,
                   lane_change_active: bool = False) -> Action:
    """The action of ``previous`` (started ``elapsed`` s ago) active now, with its remaining duration.

    Without a previous plan: maintain and keep until the next whole ``layer_duration`` boundary. Without an
    active lane-change context the ongoing lateral action is forced to keep (epsilon.md §2.7).
    """
    remaining_to_grid = layer_duration - (elapsed % layer_duration)
    if previous is None:
        return Action(Lon.MAINTAIN, Lat.KEEP, remaining_to_grid)
    start = 0.0
    for lat, duration in zip(previous.lats, previous.durations):
        if elapsed < start + duration - 1e-9:
            return Action(previous.lon, lat if lane_change_active else Lat.KEEP, start + duration - elapsed)
        start += duration
    return Action(Lon.MAINTAIN, Lat.KEEP, remaining_to_grid)


def build_tree(ongoing: Action, layers: int = 5, layer_duration: float = 1.0) -> list[Policy]:
    """Every policy of the tree, valid or not (27 with 5 layers: 3 longitudinal x 9 lateral sequences)."""
    durations = (ongoing.duration,) + (layer_duration,) * (layers - 1)
    sequences = [(ongoing.lat,) * layers]
    for h in range(1, layers):
        for lat in Lat:
            if lat is not ongoing.lat:
                sequences.append((ongoing.lat,) * h + (lat,) * (layers - h))
    return [Policy(lon, seq, durations) for lon in Lon for seq in sequences]


@functools.lru_cache(maxsize=256)
def valid_policies(ongoing: Action, layers: int = 5, layer_duration: float = 1.0) -> tuple[Policy, ...]:
    """The policies that are simulated (27 with an ongoing keep, 15 during a lane change); the same tuple for the
    same arguments (built once: the tree's Python objects cost ~0.2 ms a cycle)."""
    return tuple(p for p in build_tree(ongoing, layers, layer_duration) if p.is_valid)
