"""Invariants of an audit of a SUMO run on a real network that hold on any network (issue 46), shared by the
real-network regression (``make test``) and the MoST-size check (``make acceptance``).

Each check returns the episodes or collisions that break it (empty: it holds), so a test can name them.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd

from sumo_rss.boxes import boxes_overlap
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import AuditResult
from sumo_rss.rss.fcd import VehicleInfo
from sumo_rss.sim.snapshot import compass_deg_to_heading

STOPPED = 0.05  # [m/s]
DEFAULT_SIZE = (5.0, 1.8)  # [m] SUMO's passenger car


class FcdTable:
    """The FCD's rows (time, x, y, angle [SUMO degrees], speed, lane, length, width) by vehicle id."""

    def __init__(self, path: Path, vehicles: VehicleInfo):
        rows = []
        for _, elem in ET.iterparse(path):
            if elem.tag == "timestep":
                t = float(elem.get("time"))
                rows += [(t, v.get("id"), float(v.get("x")), float(v.get("y")), float(v.get("angle")),
                          float(v.get("speed")), v.get("lane"), v.get("type") or vehicles.type_of(v.get("id")))
                         for v in elem.iter("vehicle")]
                elem.clear()
        table = pd.DataFrame(rows, columns=["time", "id", "x", "y", "angle", "speed", "lane", "type"])
        sizes = table.type.map(lambda t: vehicles.sizes.get(t, DEFAULT_SIZE))
        table["length"], table["width"] = [s[0] for s in sizes], [s[1] for s in sizes]
        table["step"] = np.round(table.time * 100).astype(np.int64)  # [10 ms]
        self.ids = set(table.id)
        self._by_id = {vid: rows.set_index("step") for vid, rows in table.groupby("id", sort=False)}

    def car(self, vid: str, t0: float, t1: float) -> pd.DataFrame:
        """Rows of car ``vid`` at the steps in [t0, t1] [s]."""
        rows = self._by_id[vid]
        return rows.loc[int(round(t0 * 100)):int(round(t1 * 100))]

    def pair(self, a: str, b: str, t0: float, t1: float) -> pd.DataFrame:
        """Rows of cars a and b at the steps in [t0, t1] where both are present, joined per step (_a, _b)."""
        return self.car(a, t0, t1).join(self.car(b, t0, t1), how="inner", lsuffix="_a", rsuffix="_b")


def opposite_pairs_beyond_a_lane(result: AuditResult, fcd: FcdTable, net: RoadNetwork) -> list[str]:
    """Opposite-direction episodes at whose t_b the other car's front bumper lies more than one lane width (plus the
    two lanes' half widths, + 0.5 m) across the first car's lane from the first car's own front bumper: two streets,
    not one road (measured from the car, not its lane's centre line: a car changing lanes towards the oncoming ones
    is already off it; MoST 115|136 at 116.8 s, 1.49 m)."""
    bad = []
    for e in result.episodes[result.episodes.situation == "opposite-direction"].itertuples():
        steps = fcd.pair(e.vehicle_a, e.vehicle_b, e.t_b_s, e.t_b_s)
        if not len(steps):
            continue
        step = steps.iloc[0]
        lanes = net.lane_indices([step.lane_a, step.lane_b])
        _, d, _ = net.frenet(lanes[[0, 0]], np.array([step.x_a, step.x_b]), np.array([step.y_a, step.y_b]))
        widths = net.lane_width[lanes]
        if abs(d[1] - d[0]) > 0.5 * widths.sum() + widths.max() + 0.5:
            bad.append(e.episode_key)
    return bad


def deep_lateral_overlaps_apart(result: AuditResult, fcd: FcdTable, net: RoadNetwork) -> list[str]:
    """Road episodes with a step whose lateral gap is below −(sum of the bodies' half widths across their lanes at
    SUMO's angles + 1 m) while the two bodies do not overlap in the FCD (the phantom geometry of a projection onto
    the wrong road: −139.6 m for cars 20 m apart). Steps below −2.8 m (two passenger cars' widths + 1 m) are checked
    against the bodies' own extents. Needs ``result.pair_states`` (audit with a ``trace_class``)."""
    states = result.pair_states
    road = result.episodes[~result.episodes.situation.str.startswith("intersection")].set_index("episode_key")
    deep = states[states.episode_key.isin(road.index) & (states.lat_gap_m < -(2 * DEFAULT_SIZE[1] + 1.0))]
    bad = []
    for key, at in deep.groupby("episode_key"):
        e = road.loc[key]
        steps = fcd.pair(e.vehicle_a, e.vehicle_b, at.time_s.min(), at.time_s.max())
        gap = pd.Series(at.lat_gap_m.to_numpy(), index=np.round(at.time_s.to_numpy() * 100).astype(np.int64))
        steps = steps[steps.index.isin(gap.index)]
        boxes, across = [], 1.0
        for car in ("a", "b"):
            length, width = steps[f"length_{car}"].to_numpy(), steps[f"width_{car}"].to_numpy()
            heading = compass_deg_to_heading(steps[f"angle_{car}"].to_numpy())
            centre_x = steps[f"x_{car}"].to_numpy() - 0.5 * length * np.cos(heading)
            centre_y = steps[f"y_{car}"].to_numpy() - 0.5 * length * np.sin(heading)
            boxes += [centre_x, centre_y, heading, length, width]
            _, _, lane_heading = net.frenet(net.lane_indices(steps[f"lane_{car}"].to_numpy()), centre_x, centre_y)
            turned = heading - lane_heading
            across = across + 0.5 * (length * np.abs(np.sin(turned)) + width * np.abs(np.cos(turned)))
        if not (boxes_overlap(*boxes) | (gap.loc[steps.index].to_numpy() >= -across)).all():
            bad.append(key)
    return bad


def collisions_without_an_episode(result: AuditResult, fcd: FcdTable) -> list[tuple[float, str, str]]:
    """SUMO collisions between two audited vehicles without an episode of theirs open within the second before."""
    bad = []
    for c in result.collisions.itertuples():
        if not {c.collider, c.victim} <= fcd.ids:
            continue  # a vehicle outside the FCD (not audited)
        keys = c.episode_key.split(";") if c.episode_key else []
        closing = result.episodes[result.episodes.episode_key.isin(keys)]
        if not keys or not ((closing.t_end_s >= c.time_s - 1.0 - 1e-6).all() and closing.collision.all()):
            bad.append((c.time_s, c.collider, c.victim))
    return bad


def blamed_cars_that_stopped_short(result: AuditResult, fcd: FcdTable) -> list[tuple[str, str]]:
    """(episode, car) of junction episodes whose responsible car stood still during it without ever being on a
    junction's internal lane (it stopped before the conflict area: it gave the response the rule asks for). A
    responsible person (not in the table's vehicles) is not a car: persons wait at the kerb, not on a lane."""
    junction = result.episodes[result.episodes.situation.str.startswith("intersection") &
                               (result.episodes.responsible != "none")]
    bad = []
    for e in junction.itertuples():
        for car, side in ((e.vehicle_a, "a"), (e.vehicle_b, "b")):
            if e.responsible not in (side, "both") or car not in fcd.ids:
                continue
            rows = fcd.car(car, e.t_b_s, e.t_end_s)
            if not rows.lane.str.startswith(":").any() and (rows.speed < STOPPED).any():
                bad.append((e.episode_key, car))
    return bad


def counts(result: AuditResult) -> tuple[int, int, int]:
    """(episodes, violations, episodes with a responsible car)."""
    return len(result.episodes), len(result.violations), int((result.episodes.responsible != "none").sum())
