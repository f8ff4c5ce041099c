"""What a view page holds: a run's or audit's folder read into one JSON header and two binary blobs.

The scene blob (:mod:`.blob`) carries what is drawn per step: positions quantised to 1 cm (int32, relative to ``origin``,
as differences along each vehicle's rows), headings to 2π/65534 rad (int16, likewise), speeds to 1 cm/s (uint16),
the network's shapes as float32; the state blob, which the page reads after its first frame, the episodes'
step-by-step states quantised to 0.01 (m: int32; m/s, m/s²: int16, per car one column after the other). The header (JSON) carries the tables: episodes, violations, collisions,
signal changes, vehicle ids.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SumoRssError
from ..files import read_csv_table, read_json_object
from ..rss.episode_states import STATE_FILE, EpisodeStates
from .blob import Blob
from .network import LANE_KINDS, NetGeometry
from .trajectories import Trajectories

HEADING_SCALE = 32767.0 / math.pi  # int16 units per rad
STATE_UNIT = 0.01  # [m, m/s, m/s²] of the episodes' step-by-step states
_EPISODE_COLUMNS = ("episode_key", "vehicle_a", "vehicle_b", "class_a", "class_b", "situation", "conflict_area",
                    "t_b_s", "t_end_s", "duration_s", "trigger", "owed_a", "owed_b", "responsible",
                    "min_lon_margin_m", "min_lat_margin_m", "collision", "ended_by")
_VIOLATION_COLUMNS = ("episode_key", "vehicle_id", "role", "constraint", "bound", "worst_actual", "t_start_s",
                      "t_end_s")
_COLLISION_COLUMNS = ("time_s", "collider", "victim", "blamed")
_STATE_GAPS = ("lon_gap", "lon_d_min", "lat_gap", "lat_d_min")  # [m], int32
_STATE_PER_CAR = ("accel", "accel_max", "accel_min", "lat_speed", "lat_speed_max")  # [m/s², m/s], int16


def read_table(path: Path, columns: tuple[str, ...]) -> pd.DataFrame:
    """A CSV of the audit as text cells; SumoRssError naming the file and the missing columns."""
    if not path.is_file():
        raise SumoRssError(f"{path}: not found (a folder of 'sumo-rss run', 'batch' or 'audit' has it)")
    table = read_csv_table(path, "sumo-rss", dtype=str, keep_default_na=False)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise SumoRssError(f"{path}: expected the columns {', '.join(columns)}, missing {', '.join(missing)}")
    return table


def _numbers(table: pd.DataFrame, column: str, path: Path) -> list[float | None]:
    """A column of numbers (empty cells: None); SumoRssError naming the file and column where a cell is text."""
    values = pd.to_numeric(table[column].where(table[column] != ""), errors="coerce")
    if (values.isna() & (table[column] != "")).any():
        bad = table[column][values.isna() & (table[column] != "")].iloc[0]
        raise SumoRssError(f"{path}: {column}: expected numbers, got {bad!r}")
    return [None if math.isnan(v) else round(float(v), 6) for v in values]


def build_payload(run_dir: Path, trajectories: Trajectories, net: NetGeometry, every: int = 1
                  ) -> tuple[dict, Blob, Blob]:
    """The page's header, scene blob and state blob for ``run_dir``, keeping every ``every``-th recorded step."""
    header: dict = {"title": _title(run_dir), "scope": trajectories.scope, "every": every,
                    "lane_kinds": list(LANE_KINDS)}
    blob = Blob()
    x0, y0, x1, y1 = net.bounds()
    origin = (math.floor(x0), math.floor(y0))
    header["origin"], header["bounds"] = origin, [x0, y0, x1, y1]
    _add_network(blob, net, origin)
    _add_trajectories(header, blob, trajectories, origin, every)
    vehicle_index = {vid: k for k, vid in enumerate(trajectories.ids.tolist())}
    episodes = read_table(run_dir / "episodes.csv", _EPISODE_COLUMNS)
    header["episodes"] = _episodes(episodes, run_dir / "episodes.csv", vehicle_index)
    violations = read_table(run_dir / "violations.csv", _VIOLATION_COLUMNS)
    header["violations"] = _violations(violations, run_dir / "violations.csv", episodes, vehicle_index)
    collisions = read_table(run_dir / "collisions.csv", _COLLISION_COLUMNS)
    header["collisions"] = {"time": _numbers(collisions, "time_s", run_dir / "collisions.csv"),
                            "collider": [vehicle_index.get(v, -1) for v in collisions.collider],
                            "victim": [vehicle_index.get(v, -1) for v in collisions.victim],
                            "ids": [f"{c} / {v}" for c, v in zip(collisions.collider, collisions.victim)],
                            "blamed": collisions.blamed.tolist()}
    states = Blob()
    header["episodes"].update(_add_states(states, run_dir / STATE_FILE, episodes.episode_key.tolist()))
    header["states_cut_at"] = header["episodes"].pop("states_cut_at")
    header["scene_blob"], header["state_blob"] = blob.index, states.index
    return header, blob, states


def _title(run_dir: Path) -> str:
    summary = read_json_object(run_dir / "summary.json") or {}
    return str(summary.get("run_id") or f"{run_dir.parent.name}/{run_dir.name}")


def _add_network(blob: Blob, net: NetGeometry, origin: tuple[int, int]) -> None:
    shift = np.array(origin, dtype=float)
    for name, lines in (("lane", net.lanes), ("junction", net.junctions), ("marking", net.markings)):
        blob.add(f"{name}_xy", (lines.points - shift).astype(np.float32).ravel())
        blob.add(f"{name}_start", lines.start.astype(np.uint32))
    blob.add("lane_width", net.lane_width.astype(np.float32))
    blob.add("lane_kind", net.lane_kind.astype(np.uint8))
    blob.add("bar_xy", (net.bars - shift).astype(np.float32).ravel())
    blob.add("bar_signal", net.bar_signal.astype(np.int32))
    blob.add("bar_link", net.bar_link.astype(np.int32))


def _add_trajectories(header: dict, blob: Blob, t: Trajectories, origin: tuple[int, int], every: int) -> None:
    steps = np.arange(0, len(t.time), every)
    start, end = t.step_start[steps], t.step_start[steps + 1]
    rows = np.concatenate([np.arange(s, e) for s, e in zip(start, end)]) if len(steps) else np.zeros(0, dtype=int)
    blob.add("time", t.time[steps].astype(np.float64))
    blob.add("step_start", np.concatenate([[0], np.cumsum(end - start)]).astype(np.uint32))
    blob.add("vehicle", t.vehicle[rows].astype(np.uint32))
    blob.add("x", np.round((t.x[rows].astype(np.float64) - origin[0]) * 100.0).astype(np.int32), delta_by="vehicle")
    blob.add("y", np.round((t.y[rows].astype(np.float64) - origin[1]) * 100.0).astype(np.int32), delta_by="vehicle")
    blob.add("heading", np.round(t.heading[rows].astype(np.float64) * HEADING_SCALE).astype(np.int16),
             delta_by="vehicle")
    blob.add("speed", np.clip(np.round(t.speed[rows].astype(np.float64) * 100.0), 0, 65535).astype(np.uint16))
    blob.add("length", t.length.astype(np.float32))
    blob.add("width", t.width.astype(np.float32))
    classes = sorted(set(t.vclass.tolist()))
    header["vehicles"] = {"ids": t.ids.tolist(), "classes": classes,
                          "vclass": [classes.index(c) for c in t.vclass.tolist()], "vtype": t.vtype.tolist()}
    header["signals"] = {"ids": t.signal_ids.tolist(), "time": t.signal_time.tolist(),
                         "signal": t.signal.tolist(), "state": t.signal_state.tolist()}


def _episodes(episodes: pd.DataFrame, path: Path, vehicle_index: dict[str, int]) -> dict:
    table: dict = {c: episodes[c].tolist() for c in ("episode_key", "vehicle_a", "vehicle_b", "class_a", "class_b",
                                                     "situation", "conflict_area", "trigger", "owed_a", "owed_b",
                                                     "responsible", "ended_by")}
    for column in ("t_b_s", "t_end_s", "duration_s", "min_lon_margin_m", "min_lat_margin_m"):
        table[column] = _numbers(episodes, column, path)
    table["collision"] = [v == "True" for v in episodes.collision]
    table["a"] = [vehicle_index.get(v, -1) for v in episodes.vehicle_a]
    table["b"] = [vehicle_index.get(v, -1) for v in episodes.vehicle_b]
    return table


def _violations(violations: pd.DataFrame, path: Path, episodes: pd.DataFrame, vehicle_index: dict[str, int]
                ) -> dict:
    """Violations with the index of their episode (-1: a signal violation) and the car's side in it (0: vehicle_a,
    1: vehicle_b)."""
    number = {key: k for k, key in enumerate(episodes.episode_key)}
    episode = [number.get(key, -1) for key in violations.episode_key]
    a_of = episodes.vehicle_a.tolist()
    side = [(0 if a_of[e] == v else 1) if e >= 0 else -1 for e, v in zip(episode, violations.vehicle_id)]
    table: dict = {"episode": episode, "side": side, "vehicle": [vehicle_index.get(v, -1) for v in
                                                                 violations.vehicle_id]}
    table.update({c: violations[c].tolist() for c in ("vehicle_id", "role", "constraint")})
    for column in ("bound", "worst_actual", "t_start_s", "t_end_s"):
        table[column] = _numbers(violations, column, path)
    return table


def _add_states(blob: Blob, path: Path, episode_keys: list[str]) -> dict:
    """The episodes' step-by-step states in the order of episodes.csv: per episode ``state_start`` / ``state_count``
    (0 rows where the folder has no episode_states.npz: charts left empty)."""
    states = EpisodeStates.read(path) if path.is_file() else None
    rows_of = states.rows() if states is not None else {}
    spans = [rows_of.get(key, (0, 0)) for key in episode_keys]
    count = np.array([e - s for s, e in spans], dtype=np.int64)
    take = np.concatenate([np.arange(s, e) for s, e in spans] + [np.zeros(0, dtype=np.int64)])
    blob.add_quantised("state_time", states.time[take] if states is not None else np.zeros(0), 0.001)  # [s]: 1 ms
    for name in _STATE_GAPS:
        blob.add_quantised(f"state_{name}", getattr(states, name)[take] if states is not None else np.zeros(0),
                           STATE_UNIT)
    for name in _STATE_PER_CAR:  # car a's column, then car b's
        values = getattr(states, name)[take].T if states is not None else np.zeros((2, 0))
        blob.add_quantised(f"state_{name}", values.ravel(), STATE_UNIT, np.int16)
    cut_at = states.cut_at if states is not None and not np.isnan(states.cut_at) else None
    return {"state_start": (np.cumsum(count) - count).tolist(), "state_count": count.tolist(), "states_cut_at": cut_at}
