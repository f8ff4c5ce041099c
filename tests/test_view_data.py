"""What runs and audits record for the viewer (trajectories.npz, episode_states.npz), the net geometry it draws, the
page `sumo-rss view` writes, and the report's links to it. The page in a browser: test_view_browser.py."""
from __future__ import annotations

import base64
import gzip
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from conftest import NETWORKS, run_cli
from sumo_rss.rss.episode_states import EpisodeStates
from sumo_rss.view import Trajectories, TrajectoryRecorder
from sumo_rss.view.network import offset_polyline, read_geometry
from sumo_rss.view.payload import HEADING_SCALE

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
TLS = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"


@pytest.fixture(scope="module")
def audit_dir(dense_run, tmp_path_factory):
    """The offline audit of dense_run's FCD."""
    out = tmp_path_factory.mktemp("audit")
    proc = run_cli("audit", str(dense_run / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes",
                   str(dense_run / "routes.rou.xml"), "--collisions", str(dense_run / "collisions.xml"), "--out",
                   str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    return out


def _fcd_rows(path):
    """(time, id, x, y, angle) of every vehicle entry of an FCD file."""
    rows = []
    for step in ET.parse(path).getroot().iter("timestep"):
        for v in step.iter("vehicle"):
            rows.append((float(step.get("time")), v.get("id"), float(v.get("x")), float(v.get("y")),
                         float(v.get("angle"))))
    return pd.DataFrame(rows, columns=["time", "id", "x", "y", "angle"])


def _table(t: Trajectories) -> pd.DataFrame:
    step = np.repeat(np.arange(len(t.time)), np.diff(t.step_start))
    return pd.DataFrame({"time": t.time[step], "id": t.ids[t.vehicle], "x": t.x, "y": t.y, "heading": t.heading,
                         "vclass": t.vclass[t.vehicle]})


def test_a_run_with_fcd_records_every_vehicle_of_its_fcd_and_the_audit_the_same(dense_run, audit_dir):
    fcd = _fcd_rows(dense_run / "fcd.xml")
    run, audit = Trajectories.read(dense_run / "trajectories.npz"), Trajectories.read(audit_dir / "trajectories.npz")
    assert run.scope == audit.scope == "all" and run.net_file == audit.net_file == str(HIGHWAY.resolve())
    for t in (run, audit):
        rows = _table(t)
        assert len(rows) == len(fcd) > 10000
        merged = fcd.merge(rows, on=["time", "id"], validate="one_to_one")
        assert len(merged) == len(fcd)
        assert np.abs(merged.x_x - merged.x_y).max() < 1e-3 and np.abs(merged.y_x - merged.y_y).max() < 1e-3
        heading = np.radians(90.0 - merged.angle)  # SUMO's compass angle
        assert np.abs(np.angle(np.exp(1j * (heading - merged.heading)))).max() < 1e-4
    # What the ego was: the run's ego trace, to the millimetre.
    trace = pd.read_csv(dense_run / "ego_trace.csv")
    ego = _table(run).query("vclass == 'ego'")
    assert len(ego) == len(trace) > 100
    assert np.abs(ego.x.to_numpy() - trace.x_m.to_numpy()).max() < 1e-3
    assert np.abs(ego.time.to_numpy() - trace.time_s.to_numpy()).max() < 1e-9


def test_a_run_without_fcd_records_the_vehicles_near_its_ego(dense_run):
    """The recorder on dense_run's own snapshots (read back from its FCD): near the ego only, every one of them."""
    from sumo_rss.road.network import RoadNetwork
    from sumo_rss.rss.fcd import FcdReader, read_vehicle_info

    network = RoadNetwork.from_file(HIGHWAY)
    near, every = TrajectoryRecorder(HIGHWAY, near_ego_m=50.0), TrajectoryRecorder(HIGHWAY)
    for snapshot in FcdReader(dense_run / "fcd.xml", network, read_vehicle_info(dense_run / "routes.rou.xml",
                                                                                  HIGHWAY)):
        near.add(snapshot)
        every.add(snapshot)
    for recorder, name in ((near, "near.npz"), (every, "all.npz")):
        recorder.write(dense_run.parent / name)
    near_rows, all_rows = (_table(Trajectories.read(dense_run.parent / n)) for n in ("near.npz", "all.npz"))
    ego = all_rows[all_rows.vclass == "ego"].set_index("time")
    distance = np.hypot(all_rows.x - ego.x.reindex(all_rows.time).to_numpy(),
                        all_rows.y - ego.y.reindex(all_rows.time).to_numpy())
    expected = all_rows[distance.to_numpy() <= 50.0]  # NaN (no ego on the road): none
    assert 0 < len(near_rows) == len(expected) < len(all_rows) / 2
    assert set(zip(near_rows.time, near_rows.id)) == set(zip(expected.time, expected.id))
    assert Trajectories.read(dense_run.parent / "near.npz").scope == "near-ego:50"
    # Deterministic bytes: the same snapshots give the same file.
    again = TrajectoryRecorder(HIGHWAY, near_ego_m=50.0)
    for snapshot in FcdReader(dense_run / "fcd.xml", network, read_vehicle_info(dense_run / "routes.rou.xml",
                                                                                  HIGHWAY)):
        again.add(snapshot)
    again.write(dense_run.parent / "again.npz")
    assert (dense_run.parent / "again.npz").read_bytes() == (dense_run.parent / "near.npz").read_bytes()


def test_every_episode_is_recorded_step_by_step_and_the_egos_are_pair_states_csv(dense_run, audit_dir):
    states = EpisodeStates.read(dense_run / "episode_states.npz")
    episodes = pd.read_csv(dense_run / "episodes.csv", keep_default_na=False)
    assert sorted(states.episode_keys.tolist()) == sorted(episodes.episode_key) and len(episodes) > 50
    rows = states.rows()
    joined = 0
    for e in episodes.itertuples():
        first, end = rows[e.episode_key]
        times = states.time[first:end]
        # From t_b to the last dangerous step: to t_end (one step before it where the pair was safe again).
        last = e.t_end_s if e.ended_by == "end-of-data" else e.t_end_s - 0.1
        assert times[0] == pytest.approx(e.t_b_s) and times[-1] == pytest.approx(last, abs=1e-6)
        # Every dangerous step: 0.1 s apart, but for the safe steps of an episode that re-opened within ρ (1 s here)
        # and was joined (docs/rss.md, issue 46 item 7).
        steps = np.diff(times)
        assert np.all(np.isclose(steps, np.round(steps / 0.1) * 0.1, atol=1e-6)) and np.all(steps < 1.2)
        joined += int((steps > 0.1 + 1e-6).any())
        gap_margin = states.lon_gap[first:end] - states.lon_d_min[first:end]
        assert gap_margin.min() == pytest.approx(e.min_lon_margin_m, abs=1e-3)
    assert joined > 0  # the run has joined episodes, so the rule above is exercised
    pair = pd.read_csv(dense_run / "pair_states.csv")
    assert len(pair) > 50
    for key, group in pair.groupby("episode_key"):
        first, end = rows[key]
        assert np.allclose(states.time[first:end], group.time_s)
        for name in ("lon_gap", "lon_d_min", "lat_gap", "lat_d_min"):
            assert np.allclose(getattr(states, name)[first:end], group[f"{name}_m"], atol=1e-4), name
    # The offline audit of the run's FCD records the same states.
    offline = EpisodeStates.read(audit_dir / "episode_states.npz")
    assert offline.episode_keys.tolist() == states.episode_keys.tolist()
    for name in ("time", "lon_gap", "lon_d_min", "accel_max", "accel_min", "lat_speed_max"):
        assert np.allclose(getattr(offline, name), getattr(states, name), atol=1e-3, equal_nan=True), name


def test_the_states_of_episodes_without_the_ego_are_bounded(dense_run, monkeypatch):
    """Past MAX_OTHER_ROWS episode-steps the auditor keeps only the ego's episodes (with a warning); theirs stay
    whole, as pair_states.csv has them."""
    from sumo_rss import load_scenario
    from sumo_rss.batch.runner import param_resolver
    from sumo_rss.road.network import RoadNetwork
    from sumo_rss.rss import episode_states
    from sumo_rss.rss.auditor import Auditor
    from sumo_rss.rss.fcd import FcdReader, read_vehicle_info

    monkeypatch.setattr(episode_states, "MAX_OTHER_ROWS", 3000)
    network = RoadNetwork.from_file(HIGHWAY)
    spec = load_scenario(dense_run / "scenario.toml")
    auditor = Auditor(network, param_resolver(spec), "highway_dense/0", trace_class="ego", record_states=True)
    with pytest.warns(UserWarning, match="more than 3,000 episode-steps: from .* only those of the ego class"):
        for snapshot in FcdReader(dense_run / "fcd.xml", network, read_vehicle_info(dense_run / "routes.rou.xml",
                                                                                      HIGHWAY)):
            auditor.observe(snapshot)
    states = auditor.finish().episode_states
    full = EpisodeStates.read(dense_run / "episode_states.npz")
    assert 0 < states.cut_at < 60.0 and np.isnan(full.cut_at)
    ego = [k for k in full.episode_keys.tolist() if "ego" in k.split("|")[:2]]
    rows, full_rows = states.rows(), full.rows()
    assert ego and all(np.diff(rows[k]) == np.diff(full_rows[k]) for k in ego)
    others = sum(int(np.diff(span)[0]) for k, span in rows.items() if k not in ego)
    assert 2500 < others <= 3000 < sum(int(np.diff(span)[0]) for k, span in full_rows.items() if k not in ego)
    assert all(states.time[rows[k][1] - 1] < states.cut_at for k in rows if k not in ego)


def test_the_recorded_bounds_are_the_owed_responses(dense_run):
    """a ≤ a_acc during ρ, a ≤ −b_min after it, a ≥ −b_max for the front car (ad_rss: 3.5, 4, 8 m/s², ρ = 1 s), and
    each violation's bound and worst value are a recorded step's."""
    states = EpisodeStates.read(dense_run / "episode_states.npz")
    episodes = pd.read_csv(dense_run / "episodes.csv", keep_default_na=False).set_index("episode_key")
    params = json.loads((dense_run / "rss_params.json").read_text())
    assert {p["response_time"] for p in params.values()} == {1.0}
    a_acc, b_min, b_max = (params["background/car"][k] for k in ("lon_accel_max", "lon_brake_min", "lon_brake_max"))
    checked = {"during": 0, "after": 0, "front": 0}
    for key, (first, whole_end) in states.rows().items():
        # A joined episode (docs/rss.md, issue 46 item 7) is judged afresh from each danger threshold: each part's
        # first step is not judged; its first part owes the responses episodes.csv names.
        parts = np.flatnonzero(np.diff(states.time[first:whole_end]) > 0.1 + 1e-6) + first + 1
        assert np.all(np.isnan(states.accel_max[parts])) and np.all(np.isnan(states.accel_min[parts]))
        end = int(parts[0]) if len(parts) else whole_end
        tau = states.time[first:end] - states.time[first]
        for side, owed in enumerate(episodes.loc[key, ["owed_a", "owed_b"]]):
            bound, lower = states.accel_max[first:end, side], states.accel_min[first:end, side]
            assert np.isnan(bound[0]) and np.isnan(lower[0])  # t_b is not judged
            if "lon:brake-min" in owed.split("+"):
                during = (tau > 0) & (tau <= 1.0 + 1e-6)
                assert np.allclose(bound[during], a_acc, atol=1e-5)
                after = bound[tau > 1.0 + 1e-6]
                assert np.all(np.isnan(after) | np.isclose(after, -b_min, atol=1e-5))  # NaN: stopped
                checked["during"] += int(during.sum())
                checked["after"] += int(np.isfinite(after).sum())
            elif "lon:brake-at-most-max" in owed.split("+"):
                assert np.allclose(lower[1:], -b_max, atol=1e-5) and np.all(np.isnan(bound))
                checked["front"] += len(lower) - 1
            else:
                assert np.all(np.isnan(bound)) and np.all(np.isnan(lower))
    assert min(checked.values()) > 100
    violations = pd.read_csv(dense_run / "violations.csv", keep_default_na=False)
    judged = violations[violations.constraint == "lon-brake-after-response-time"]
    found = 0
    for v in judged.itertuples():
        first, end = states.rows()[v.episode_key]
        side = 0 if episodes.loc[v.episode_key, "vehicle_a"] == v.vehicle_id else 1
        at = (states.time[first:end] >= v.t_start_s - 1e-6) & (states.time[first:end] <= v.t_end_s + 1e-6)
        worst = np.isclose(states.accel[first:end, side], v.worst_actual, atol=1e-4) & at
        if worst.any():  # else the worst step was the one that ended the episode (judged, not recorded)
            assert np.isclose(states.accel_max[first:end, side][worst], v.bound, atol=1e-4).any()
            found += 1
    assert found > 20


def test_the_net_geometry_is_the_nets_lanes_markings_and_signal_bars():
    net = read_geometry(HIGHWAY)
    root = ET.parse(HIGHWAY).getroot()
    lanes = root.findall("edge/lane")
    assert len(net.lanes) == len(lanes) and np.allclose(net.lane_width, [float(l.get("width", 3.2)) for l in lanes])
    normal = [e for e in root.findall("edge") if e.get("function") != "internal"]
    assert len(net.markings) == sum(len(e.findall("lane")) - 1 for e in normal) > 0
    first = lanes[0].get("shape").split()[0].split(",")
    assert net.lanes.points[0] == pytest.approx([float(first[0]), float(first[1])])
    tls = read_geometry(TLS)
    connections = [c for c in ET.parse(TLS).getroot().iter("connection") if c.get("tl")]
    assert len(tls.bars) == len(connections) > 0 and tls.signal_ids == ("C",)
    assert sorted(tls.bar_link.tolist()) == sorted(int(c.get("linkIndex")) for c in connections)
    shapes = {l.get("id"): l for l in ET.parse(TLS).getroot().iter("lane")}
    for bar, c in zip(tls.bars, connections):  # each bar lies across its lane, 0.5 m before the lane's end
        end = np.array([float(v) for v in shapes[f"{c.get('from')}_{c.get('fromLane')}"].get("shape").split()[-1]
                        .split(",")])
        assert 0.49 < np.hypot(*(bar.mean(axis=0) - end)) < 0.5 + 3.2 / 2


def test_an_offset_polyline_moves_each_point_along_its_normal():
    square = offset_polyline(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]), 1.0)
    assert square[0] == pytest.approx([0.0, 1.0]) and square[2] == pytest.approx([9.0, 10.0])
    assert square[1] == pytest.approx([10.0 - np.sqrt(0.5), np.sqrt(0.5)])  # along the corner's bisector


def _page_data(page: str) -> tuple[dict, dict[str, np.ndarray]]:
    header = json.loads(re.search(r'<script id="header" type="application/json">(.*?)</script>', page, re.S)
                        .group(1).replace("<\\/", "</"))
    arrays: dict[str, np.ndarray] = {}
    for kind in ("scene", "state"):
        blob = gzip.decompress(base64.b64decode(re.search(f'<script id="{kind}-blob" type="application/octet-stream">'
                                                          r'(.*?)</script>', page, re.S).group(1)))
        arrays.update(_arrays(blob, header[f"{kind}_blob"], arrays))
    return header, arrays


def _arrays(blob: bytes, index: dict, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    arrays = dict(arrays)
    for name, (t, off, n, options) in index.items():  # viewer.js's arrays(), written again
        dtype = np.dtype("<" + t)
        planes = np.frombuffer(blob, dtype=np.uint8, count=n * dtype.itemsize, offset=off)
        values = planes.reshape(dtype.itemsize, n).T.copy().view(dtype).ravel()
        if "delta_by" in options:
            values = _undelta(values, arrays[options["delta_by"]])
        if "unit" in options:
            values = np.where(values == np.iinfo(dtype).min, np.nan, values * options["unit"])
        arrays[name] = values
    return arrays


def _undelta(values: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Differences along each key summed up, in plain Python (not the writer's numpy)."""
    out, last = values.astype(np.int64), {}
    for i, key in enumerate(keys.tolist()):
        if key in last:
            out[i] += out[last[key]]
        last[key] = i
    return out.astype(values.dtype)


def test_the_blob_stores_planes_differences_and_quantised_values_that_read_back():
    """Hand-made arrays: a heading crossing ±π (int16 differences wrap around), two interleaved keys, NaN."""
    from sumo_rss.view.blob import Blob, previous_of

    keys = np.array([3, 1, 3, 1, 3], dtype=np.uint32)
    assert previous_of(keys).tolist() == [-1, -1, 0, 1, 2]
    heading = np.array([32000, -5, -32000, -4, 100], dtype=np.int16)
    blob = Blob()
    blob.add("vehicle", keys)
    blob.add("heading", heading, delta_by="vehicle")
    blob.add_quantised("gap", np.array([1.234, np.nan, -0.005, 1e9]), 0.01, np.int16)
    raw = gzip.decompress(blob.compressed())
    kind, offset, n, options = blob.index["heading"]
    assert (kind, n, options) == ("i2", 5, {"delta_by": "vehicle"}) and offset % 8 == 0
    low, high = raw[offset:offset + n], raw[offset + n:offset + 2 * n]  # all low bytes, then all high bytes
    stored = (np.frombuffer(low, np.uint8).astype(np.uint16) | (np.frombuffer(high, np.uint8).astype(np.uint16) << 8))
    assert stored.view(np.int16).tolist() == [32000, -5, 1536, 1, 32100]  # -32000 - 32000 wraps to 1536
    arrays = _arrays(raw, blob.index, {})
    assert arrays["heading"].tolist() == heading.tolist()
    gap = arrays["gap"]
    assert gap[0] == pytest.approx(1.23) and np.isnan(gap[1]) and gap[2] in (-0.0, -0.01) and gap[3] == 327.67


def test_the_view_page_is_self_contained_and_holds_the_run_quantised(dense_run, tmp_path):
    proc = run_cli("view", str(dense_run), "--out", str(tmp_path / "v.html"))
    assert proc.returncode == 0 and "v.html" in proc.stdout, proc.stderr
    page = (tmp_path / "v.html").read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", page) and "import " not in page.split(
        '<script type="module">')[1].split("</script>")[0].split("\n", 3)[2]
    header, arrays = _page_data(page)
    t = Trajectories.read(dense_run / "trajectories.npz")
    assert np.array_equal(arrays["time"], t.time) and np.array_equal(arrays["vehicle"], t.vehicle)
    ox, oy = header["origin"]
    assert np.abs(arrays["x"] / 100.0 + ox - t.x).max() <= 0.0051 and np.abs(arrays["y"] / 100.0 + oy - t.y).max() \
        <= 0.0051
    assert np.abs(arrays["heading"] / HEADING_SCALE - t.heading).max() < 1e-4
    episodes = pd.read_csv(dense_run / "episodes.csv", keep_default_na=False)
    assert header["episodes"]["episode_key"] == episodes.episode_key.tolist()
    assert sum(header["episodes"]["state_count"]) == len(arrays["state_time"]) > 0
    states = EpisodeStates.read(dense_run / "episode_states.npz")
    first, end = states.rows()[episodes.episode_key[0]]
    shown = header["episodes"]["state_start"][0]
    n = len(arrays["state_time"])
    assert np.allclose(arrays["state_lon_gap"][shown:shown + end - first], states.lon_gap[first:end], atol=5e-3)
    for side in (0, 1):  # per car: all of car a's values, then car b's
        assert np.allclose(arrays["state_accel_max"][side * n + shown:side * n + shown + end - first],
                           states.accel_max[first:end, side], atol=5e-3, equal_nan=True)
    # --every 5: every fifth step, a smaller page.
    assert run_cli("view", str(dense_run), "--out", str(tmp_path / "v5.html"), "--every", "5").returncode == 0
    header5, arrays5 = _page_data((tmp_path / "v5.html").read_text())
    assert np.array_equal(arrays5["time"], t.time[::5]) and header5["every"] == 5
    kept = np.concatenate([np.arange(t.step_start[k], t.step_start[k + 1]) for k in range(0, len(t.time), 5)])
    assert np.array_equal(arrays5["vehicle"], t.vehicle[kept])


def test_view_of_an_audit_folder_finds_its_net_or_takes_net(audit_dir, tmp_path):
    assert run_cli("view", str(audit_dir)).returncode == 0 and (audit_dir / "view.html").is_file()
    moved = tmp_path / "audit"
    moved.mkdir()
    for f in audit_dir.iterdir():
        (moved / f.name).write_bytes(f.read_bytes())
    t = Trajectories.read(moved / "trajectories.npz")
    data = dict(np.load(moved / "trajectories.npz"))
    data["net_file"] = np.str_(str(tmp_path / "gone.net.xml"))
    np.savez(moved / "trajectories.npz", **data)
    proc = run_cli("view", str(moved))
    assert proc.returncode == 2 and proc.stderr.strip().count("\n") == 0
    assert "gone.net.xml: network file not found" in proc.stderr and "--net" in proc.stderr
    assert run_cli("view", str(moved), "--net", t.net_file).returncode == 0


@pytest.mark.parametrize("case, message", [
    ("missing", "not a folder"), ("empty", "trajectories.npz: not found"), ("damaged", "not a trajectory file"),
    ("no-episodes", "episodes.csv: not found")])
def test_bad_view_input_is_one_line_naming_the_file(dense_run, tmp_path, case, message):
    folder = tmp_path / "run"
    if case != "missing":
        folder.mkdir()
    if case == "damaged":
        (folder / "trajectories.npz").write_bytes(b"PK\x03\x04 not really")
    if case == "no-episodes":
        (folder / "trajectories.npz").write_bytes((dense_run / "trajectories.npz").read_bytes())
    proc = run_cli("view", str(folder))
    assert proc.returncode == 2 and message in proc.stderr and proc.stderr.strip().count("\n") == 0, proc.stderr


def test_the_report_links_every_run_to_its_view(dense_run, tmp_path):
    """A batch folder of one run (dense_run's files), its report: each table row links the run's view.html."""
    batch = tmp_path / "b"
    run = batch / "highway_dense" / "0"
    run.mkdir(parents=True)
    for f in dense_run.iterdir():
        if f.is_file() and f.name != "fcd.xml":
            (run / f.name).write_bytes(f.read_bytes())
    summary = pd.DataFrame([{**json.loads((run / "summary.json").read_text()), "status": "ok"}])
    summary[["run_id", "scenario", "variant", "seed", "status"]].to_csv(batch / "batch_summary.csv", index=False)
    for name in ("episodes", "violations", "pair_states"):
        pd.read_csv(run / f"{name}.csv").assign(scenario="highway_dense", variant="", seed=0).to_csv(
            batch / f"{name}.csv", index=False)
    proc = run_cli("report", str(batch), "--quiet")
    assert proc.returncode == 0, proc.stderr
    page = (batch / "report.html").read_text()
    link = "<a href='highway_dense/0/view.html'>"
    assert (run / "view.html").is_file() and page.count(link) == 5  # ego, responsibility, rule 5 / rule 4, violations, runs tables
    stamp = (run / "view.html").stat().st_mtime_ns
    assert run_cli("report", str(batch), "--quiet").returncode == 0 and (run / "view.html").stat().st_mtime_ns == stamp
    assert run_cli("report", str(batch), "--no-views").returncode == 0 and link not in (batch / "report.html").read_text()
