"""Collisions as events: SUMO reports a contact on every step it lasts; we record it once per contact."""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class CollisionEvent:
    """A collision as SUMO reports it, once per contact (not every step it lasts)."""

    time: float  # [s]
    collider: str
    victim: str
    collider_type: str
    victim_type: str
    collider_speed: float  # [m/s]
    victim_speed: float  # [m/s]
    kind: str  # SUMO's collision type: 'collision', 'frontal', 'junction', ...
    lane: str
    pos: float  # [m] along ``lane``


class ContactTracker:
    """Turns SUMO's per-step collision reports into events: a pair in contact at consecutive steps is one
    contact; it is new again only after a step without contact."""

    def __init__(self) -> None:
        self._touching: set[tuple[str, str]] = set()

    def step(self, reports: Iterable[CollisionEvent]) -> list[CollisionEvent]:
        """The reports of one step → the new contacts among them (call once per step, also with none)."""
        touching: set[tuple[str, str]] = set()
        new = []
        for c in reports:
            pair = (c.collider, c.victim) if c.collider < c.victim else (c.victim, c.collider)
            if pair not in self._touching and pair not in touching:
                new.append(c)
            touching.add(pair)
        self._touching = touching
        return new
