"""Batches: parallel runs equal single runs, failures are recorded, a killed batch resumes cleanly, Ray gives
the same results, and the report plots exactly what the CSVs say."""
from __future__ import annotations

import fcntl
import json
import multiprocessing
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace

import pandas as pd
import pytest

from conftest import REPO, SCENARIOS, run_cli, two_scenario_batch, write_scenario
from sumo_rss import load_scenario
from sumo_rss.batch.executors import LocalExecutor, RayExecutor
from sumo_rss.batch.orchestrator import _BatchLock, run_batch
from sumo_rss.batch.runner import WRITER_LOCK, _work_folder, partial_run_is_live, run_one
from sumo_rss.batch.spec import BatchSpec, Task, load_batch, parse_seeds
from sumo_rss.errors import ScenarioError, SumoRssError
from sumo_rss.report.html import _numbers_as_numbers, ego_traces, write_report
from sumo_rss.report.summary import ego_table, read_batch_csv, responsibility_category, responsibility_table

AUDIT_FILES = ("episodes.csv", "violations.csv", "collisions.csv", "pair_states.csv", "ego_trace.csv")


@pytest.fixture
def two_scenarios(tmp_path, valid_scenario):
    """Two 20 s highway scenarios (different demand) and a batch file over seeds 0 and 1."""
    return two_scenario_batch(tmp_path, valid_scenario, 20.0, "[0, 1]")


def test_two_worker_batch_equals_running_each_alone(two_scenarios, tmp_path):
    batch = load_batch(two_scenarios / "batch.toml")
    rows = run_batch(batch.tasks(), tmp_path / "batch", LocalExecutor(workers=2), progress=False)
    assert list(rows.status) == ["ok"] * 4
    for task in batch.tasks():
        run_one(task.spec, tmp_path / "alone")
        for name in AUDIT_FILES:
            together = (tmp_path / "batch" / task.run_id / name).read_bytes()
            assert together == (tmp_path / "alone" / task.run_id / name).read_bytes(), (task.run_id, name)
    # The batch CSVs are the runs' CSVs with their keys, cell for cell as the runs wrote them.
    combined = pd.read_csv(tmp_path / "batch" / "episodes.csv", dtype=str, keep_default_na=False)
    for task in batch.tasks():
        rows = combined[combined.run_id == task.run_id].drop(columns=["scenario", "variant", "seed"])
        assert rows.to_csv(index=False, lineterminator="\n") == \
            (tmp_path / "batch" / task.run_id / "episodes.csv").read_text()
    episodes = read_batch_csv(tmp_path / "batch", "episodes")
    per_run = sum(len(pd.read_csv(tmp_path / "batch" / t.run_id / "episodes.csv")) for t in batch.tasks())
    assert len(episodes) == per_run > 0
    assert list(episodes.columns[:4]) == ["run_id", "scenario", "variant", "seed"]
    summary = read_batch_csv(tmp_path / "batch", "batch_summary")
    assert summary.episodes.sum() == per_run and (summary.ego_mean_speed_ms > 5).all()


def test_a_failing_run_is_recorded_and_the_batch_goes_on(two_scenarios, valid_scenario, tmp_path):
    valid_scenario["duration_s"] = 10.0
    valid_scenario["sumo"] = {"extra_args": ["--max-depart-delay", "soon"]}  # SUMO refuses to start
    write_scenario(two_scenarios, valid_scenario, "bad.toml")
    (two_scenarios / "mixed.toml").write_text('[batch]\nscenarios = ["light.toml", "bad.toml"]\nseeds = [0, 1]\n')
    out = tmp_path / "out"
    proc = run_cli("batch", str(two_scenarios / "mixed.toml"), "--out", str(out), "--workers", "2", "--quiet")
    assert proc.returncode == 1 and "2 runs ok, 2 failed" in proc.stdout
    summary = read_batch_csv(out, "batch_summary")
    assert list(summary.status) == ["ok", "ok", "failed", "failed"]
    failure = json.loads((out / "bad" / "0.failed" / "failed.json").read_text())
    assert "SessionError" in failure["error"] and "Traceback" in failure["traceback"]
    assert "Invalid Number Format (double) soon" in failure["error"]  # SUMO's own reason...
    assert "sumo.extra_args: --max-depart-delay soon" in failure["error"]  # ...and where it comes from
    assert (out / "batch_summary.csv").read_text().splitlines()[1].split(",")[8] == "200"  # counts stay integers
    assert not (out / "bad" / "0").exists()
    finished = (out / "light" / "0" / "summary.json").stat().st_mtime_ns
    again = run_cli("batch", str(two_scenarios / "mixed.toml"), "--out", str(out), "--quiet", "--seeds", "0:3")
    assert "3 runs ok, 3 failed" in again.stdout
    assert (out / "light" / "0" / "summary.json").stat().st_mtime_ns == finished  # skipped, not rerun


def test_a_batch_removes_only_its_own_half_written_runs(two_scenarios, tmp_path):
    """A batch cleans up what a killed batch left of its own runs; other ``.partial`` folders below its output
    folder may be runs in progress of another batch, and a partial folder of its own run may be that of a 'sumo-rss
    run' in progress (it holds the folder's writer lock), which it must not delete. A run's folder is ``.starting``
    until its lock is held: a ``.partial`` one without a lock file is a dead run's, however new."""
    out = tmp_path / "out"
    light = out / "light"
    own, foreign, sibling, live = light / ".0.k1ll3d.partial", out / "other" / ".0.busy.partial", \
        light / ".10.busy.partial", light / ".0.running.partial"
    lockless, young, stale = light / ".0.n0l0ck.partial", light / ".0.new.starting", light / ".0.old.starting"
    for folder in (own, foreign, sibling, live, lockless, young, stale):
        folder.mkdir(parents=True)
    (own / WRITER_LOCK).touch()  # its process died: the lock is free
    an_hour_ago = time.time() - 3600
    os.utime(stale, (an_hour_ago, an_hour_ago))  # young: a run that has not taken its lock yet; stale: died so
    task = Task(load_scenario(two_scenarios / "light.toml").with_overrides(seed=0), "")
    with (live / WRITER_LOCK).open("w") as writer:  # a 'sumo-rss run' of the same run, writing its folder
        fcntl.flock(writer, fcntl.LOCK_EX)
        rows = run_batch([task], out, LocalExecutor(workers=1), progress=False)
    assert list(rows.status) == ["ok"]
    assert not own.exists() and foreign.is_dir() and sibling.is_dir() and live.is_dir() and young.is_dir()
    assert not lockless.exists() and not stale.exists()
    assert not list(out.glob("light/0/.*"))  # the finished run's folder keeps no writer lock


def test_a_run_folder_appears_as_partial_only_with_its_lock_held(tmp_path):
    """A batch killed right after a run's folder appeared leaves a folder its resume can tell from a live run's."""
    final = tmp_path / "out" / "light" / "0"
    work, writer = _work_folder(final, 0)
    try:
        assert work.name.startswith(".0.") and work.name.endswith(".partial") and partial_run_is_live(work)
        assert [p.name for p in work.parent.iterdir()] == [work.name]  # the .starting folder was renamed
    finally:
        writer.close()
    assert not partial_run_is_live(work)


def test_a_run_whose_folder_is_removed_meanwhile_fails_instead_of_reporting_ok(two_scenarios, tmp_path):
    """What is written after the folder went would be an incomplete run (no manifest, routes or SUMO log)."""
    spec = load_scenario(two_scenarios / "light.toml")

    def remove_the_work_folder(simulated: float) -> None:
        if abs(simulated - 5.0) < 1e-6:
            for partial in (tmp_path / "out" / "light").glob(f".{spec.seed}.*.partial"):
                shutil.rmtree(partial)

    with pytest.raises(SumoRssError, match="the run's folder was removed while the run was writing it"):
        run_one(spec, tmp_path / "out", on_step=remove_the_work_folder)
    assert not (tmp_path / "out").exists()  # nor the folders the run made for itself


def test_a_moved_checkout_resumes_its_batches_but_a_changed_network_reruns(two_scenarios, tmp_path):
    """The parameter hash counts the network by its content: a re-cloned or moved repository (another absolute
    path, the same file) must not rerun and delete finished runs."""
    spec = load_scenario(two_scenarios / "light.toml")
    moved = tmp_path / "elsewhere" / spec.net_file.name
    moved.parent.mkdir()
    moved.write_bytes(spec.net_file.read_bytes())
    assert Task(replace(spec, net_file=moved), "").parameter_hash() == Task(spec, "").parameter_hash()
    # A rebuild of the same sources (`sumo-rss nets build`) differs only in netconvert's build-date comment.
    original = spec.net_file.read_bytes()
    assert b"<!-- generated on " in original
    moved.write_bytes(original.replace(b"<!-- generated on ", b"<!-- generated on 2099-01-01 (rebuilt) ", 1))
    assert Task(replace(spec, net_file=moved), "").parameter_hash() == Task(spec, "").parameter_hash()
    moved.write_bytes(original.replace(b'speed="33.33"', b'speed="30.00"', 1))
    assert Task(replace(spec, net_file=moved), "").parameter_hash() != Task(spec, "").parameter_hash()


def test_a_preset_sweep_rechecks_the_egos_overrides_at_load(two_scenarios, valid_scenario):
    """Under krauss (b_min = b_max = the vType's decel) an ego override lon_brake_min = 6 is inconsistent: said
    when the batch is built, naming the file and key, not by every run failing once the ego departs."""
    valid_scenario["rss"] = {"ego": {"lon_brake_min": 6.0}}
    write_scenario(two_scenarios, valid_scenario, "braking.toml")
    (two_scenarios / "sweep.toml").write_text('[batch]\nscenarios = ["braking.toml"]\n[batch.grid]\n'
                                              'rss_preset = ["ad_rss", "krauss"]\n')
    with pytest.raises(ScenarioError, match=r"braking\.toml: rss\.ego: inconsistent RSS parameters for ego \(preset "
                                            r"'krauss'\): expected lon_brake_min_correct <= lon_brake_min"):
        load_batch(two_scenarios / "sweep.toml").tasks()


def _scaled_tasks(folder, scenario: str, scale: float) -> list[Task]:
    (folder / "scaled.toml").write_text(f'[batch]\nscenarios = ["{scenario}"]\n[batch.grid]\n'
                                        f'demand_scale = [{scale}]\n')
    return load_batch(folder / "scaled.toml").tasks()


def test_a_demand_scale_beyond_what_a_probability_flow_can_insert_is_refused(two_scenarios, valid_scenario):
    """SUMO draws at most one vehicle per second from a probability flow: 0.6 x 2 was silently capped at 1."""
    valid_scenario["demand"]["flows"][0] = {"id": "drawn", "route": ["hw0", "hw1", "hw2"], "probability": 0.6}
    write_scenario(two_scenarios, valid_scenario, "drawn.toml")
    assert _scaled_tasks(two_scenarios, "drawn.toml", 1.5)[0].spec.demand.flows[0].probability == pytest.approx(0.9)
    with pytest.raises(ScenarioError, match=r"drawn\.toml: demand\.flows\[0\]\.probability: demand_scale 2 makes "
                                            r"it 1\.2 per second, above the at most 1 of a probability flow"):
        _scaled_tasks(two_scenarios, "drawn.toml", 2.0)


def test_a_demand_scale_beyond_the_densest_flow_a_scenario_may_ask_for_is_refused(two_scenarios):
    """The same 20000 veh/h bound as in a scenario file: 3000 x 10 was let through."""
    assert _scaled_tasks(two_scenarios, "busy.toml", 6.0)[0].spec.demand.flows[0].veh_per_hour == 18000
    with pytest.raises(ScenarioError, match=r"busy\.toml: demand\.flows\[0\]\.veh_per_hour: demand_scale 10 makes it "
                                            r"30000 veh/h, above the at most 20000 veh/h of a flow"):
        _scaled_tasks(two_scenarios, "busy.toml", 10.0)


def test_a_controller_sweep_runs_a_scenario_without_an_ego_once_per_other_variant(two_scenarios, valid_scenario):
    """It made one identical run per controller (same traffic, same seed) under different names."""
    del valid_scenario["ego"]
    write_scenario(two_scenarios, valid_scenario, "traffic.toml")
    (two_scenarios / "sweep.toml").write_text('[batch]\nscenarios = ["traffic.toml", "light.toml"]\n'
                                              '[batch.grid]\nrss_preset = ["ad_rss", "krauss"]\n'
                                              'controller = ["sumo", "epsilon"]\n')
    assert [t.run_id for t in load_batch(two_scenarios / "sweep.toml").tasks()] == [
        "traffic__rss_preset=ad_rss/0", "traffic__rss_preset=krauss/0",
        "light__rss_preset=ad_rss+controller=sumo/0", "light__rss_preset=ad_rss+controller=epsilon/0",
        "light__rss_preset=krauss+controller=sumo/0", "light__rss_preset=krauss+controller=epsilon/0"]
    (two_scenarios / "only.toml").write_text('[batch]\nscenarios = ["traffic.toml"]\n[batch.grid]\n'
                                             'controller = ["sumo", "epsilon", "mpdm"]\n')
    assert [t.run_id for t in load_batch(two_scenarios / "only.toml").tasks()] == ["traffic/0"]


def test_a_huge_seed_range_is_refused_before_it_is_built():
    with pytest.raises(ValueError, match=r"\(at most 100000 seeds\), got '0:99999999999'"):
        parse_seeds("0:99999999999")
    assert parse_seeds("5:8") == (5, 6, 7)


def test_a_killed_batch_resumes_without_duplicates_or_partial_files(two_scenarios, tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "sumo_rss", "batch", str(two_scenarios / "batch.toml"), "--out", str(out),
           "--quiet"]
    parent = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while not list(out.glob("*/*/summary.json")) and time.time() < deadline:
        time.sleep(0.05)
    while not list(out.glob("*/.*.partial")) and time.time() < deadline:  # the next run is under way
        time.sleep(0.01)
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    finished_before = len(list(out.glob("*/*/summary.json")))
    assert 1 <= finished_before < 4
    time.sleep(0.5)  # the orphaned child is killed with its parent (PR_SET_PDEATHSIG)
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and "4 runs ok, 0 failed" in proc.stdout
    assert len(list(out.glob("*/*/summary.json"))) == 4
    assert not list(out.glob("**/.*.partial")) and not list(out.glob("**/*.tmp")) and not (out / ".batch.lock").exists()
    summary = read_batch_csv(out, "batch_summary")
    assert summary.run_id.is_unique and len(summary) == 4


def test_ray_runs_the_same_tasks_with_the_same_results(two_scenarios, tmp_path):
    ray = pytest.importorskip("ray")
    spec = load_scenario(two_scenarios / "light.toml")
    tasks = [Task(spec.with_overrides(seed=s), "") for s in (0, 1)]
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        rows = run_batch(tasks, tmp_path / "ray", RayExecutor("local"), progress=False)
    finally:
        ray.shutdown()
    run_batch(tasks, tmp_path / "local", LocalExecutor(workers=2), progress=False)
    assert list(rows.status) == ["ok", "ok"]
    for task in tasks:
        for name in AUDIT_FILES:
            assert (tmp_path / "ray" / task.run_id / name).read_bytes() == \
                (tmp_path / "local" / task.run_id / name).read_bytes()


def test_a_stopped_ray_batch_disconnects_the_ray_it_connected(two_scenarios, tmp_path):
    """On a stop the executor that connected to Ray disconnects rather than cancelling the runs (cancelling a task
    whose result is arriving can crash Ray's core worker); Ray then ends the runs."""
    ray = pytest.importorskip("ray")
    assert not ray.is_initialized()
    spec = load_scenario(two_scenarios / "light.toml")
    tasks = [Task(spec.with_overrides(seed=s), "") for s in (0, 1, 2)]
    executor = RayExecutor("local")
    results = []

    def stop_after_the_first(outcome):
        results.append(outcome)
        raise KeyboardInterrupt

    try:
        with pytest.raises(KeyboardInterrupt):
            executor.run(tasks, tmp_path, stop_after_the_first)
        assert len(results) == 1 and results[0].status == "ok" and not ray.is_initialized()
    finally:
        ray.shutdown()


def test_a_ray_address_where_nothing_listens_fails_at_once(tmp_path):
    """Ray retries an address without a cluster for ever; the batch says so in one line and exits 2 instead."""
    pytest.importorskip("ray")
    with socket.socket() as probe:  # a port that was free a moment ago: nothing listens there
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    proc = run_cli("batch", str(SCENARIOS / "highway_sparse.toml"), "--seeds", "0", "--ray-address",
                   f"127.0.0.1:{port}", "--out", str(tmp_path / "out"), timeout=120)
    assert proc.returncode == 2
    assert f"--ray-address 127.0.0.1:{port}: no Ray cluster listens there" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_grid_variants_sweep_presets_and_demand(two_scenarios, tmp_path):
    (two_scenarios / "grid.toml").write_text('[batch]\nscenarios = ["busy.toml"]\nseeds = [3]\n'
                                             '[batch.grid]\nrss_preset = ["ad_rss", "krauss"]\n'
                                             'demand_scale = [0.5, 1.0]\n')
    tasks = load_batch(two_scenarios / "grid.toml").tasks()
    assert [t.run_id for t in tasks] == [
        "busy__rss_preset=ad_rss+demand_scale=0.5/3", "busy__rss_preset=ad_rss+demand_scale=1/3",
        "busy__rss_preset=krauss+demand_scale=0.5/3", "busy__rss_preset=krauss+demand_scale=1/3"]
    assert tasks[0].spec.demand.flows[0].veh_per_hour == 1500.0 and tasks[2].spec.rss.preset == "krauss"
    rows = run_batch(tasks, tmp_path / "grid", LocalExecutor(workers=2), progress=False).set_index("variant")
    assert rows.loc["rss_preset=ad_rss+demand_scale=0.5", "vehicles_inserted"] < \
        rows.loc["rss_preset=ad_rss+demand_scale=1", "vehicles_inserted"]
    # Krauss parameters describe what SUMO's drivers do: far fewer danger episodes than under ad_rss.
    assert rows.loc["rss_preset=krauss+demand_scale=1", "episodes"] < rows.loc["rss_preset=ad_rss+demand_scale=1",
                                                                               "episodes"]


def test_report_plots_what_the_csvs_say(two_scenarios, tmp_path):
    batch = load_batch(two_scenarios / "batch.toml")
    out = tmp_path / "b"
    run_batch(batch.tasks(), out, LocalExecutor(workers=2), progress=False)
    html = write_report(out)
    page = html.read_text()
    for name in ("ego_responsibility", "responsibility", "violations", "pair_timeline", "ego_speed"):
        assert (out / "report" / f"{name}.png").stat().st_size > 5000
        assert f"alt='{name}' src='data:image/png;base64," in page  # self-contained
    # Bar lengths of the responsibility plot = counts recomputed here from the episodes CSV.
    from sumo_rss.report.plots import responsibility_bars

    episodes = pd.read_csv(out / "episodes.csv", keep_default_na=False)
    fig, table = responsibility_bars(responsibility_table(episodes))
    expected = pd.crosstab(episodes.scenario, responsibility_category(episodes))
    widths = [round(p.get_width()) for p in fig.axes[0].patches]
    n = len(table.index)
    for k, category in enumerate(table.columns):
        for r, label in enumerate(table.index):
            assert widths[k * n + r] == expected.get(category, pd.Series(dtype=int)).get(label, 0)
    assert sum(widths) == len(episodes)
    # The ego's table: its episodes by who broke a proper response, counted here from the episodes CSV.
    summary = read_batch_csv(out, "batch_summary")
    ego = ego_table(episodes, summary)
    for scenario, rows in episodes.groupby("scenario"):
        as_a, as_b = rows.class_a == "ego", rows.class_b == "ego"
        mine = rows[as_a | as_b]
        ego_broke = (as_a & rows.responsible.isin(["a", "both"])) | (as_b & rows.responsible.isin(["b", "both"]))
        other_broke = (as_a & rows.responsible.isin(["b", "both"])) | (as_b & rows.responsible.isin(["a", "both"]))
        row = ego.loc[scenario]
        assert row["seeds"] == "0, 1" and row["episodes"] == len(mine) > 0
        assert row["responsible: ego"] == (ego_broke & ~other_broke).sum()
        assert row["responsible: the other car only"] == (other_broke & ~ego_broke).sum()
        assert row["responsible: nobody"] == (mine.responsible == "none").sum()
        assert row["ego mean speed [m/s]"] == pytest.approx(summary[summary.scenario == scenario].ego_mean_speed_ms
                                                              .mean())
    # Every run's row is in the HTML summary.
    for run_id in read_batch_csv(out, "batch_summary").run_id:
        assert run_id in page


def test_a_changed_scenario_is_run_again_and_old_batch_files_do_not_linger(two_scenarios, valid_scenario,
                                                                           tmp_path):
    out = tmp_path / "b"
    assert run_cli("batch", str(two_scenarios / "light.toml"), "--out", str(out), "--quiet").returncode == 0
    assert write_report(out) and (out / "episodes.csv").is_file() and (out / "report" / "ego_speed.png").is_file()
    valid_scenario["duration_s"] = 15.0
    write_scenario(two_scenarios, valid_scenario, "light.toml")  # same name, other parameters
    again = run_cli("batch", str(two_scenarios / "light.toml"), "--out", str(out), "--quiet")
    assert again.returncode == 0 and "1 run folder(s) are not a finished run" in again.stderr and \
        "light/1: made from other scenario parameters" in again.stderr
    assert read_batch_csv(out, "batch_summary").sim_time_s.tolist() == [15.0]
    valid_scenario["sumo"] = {"extra_args": ["--max-depart-delay", "soon"]}
    write_scenario(two_scenarios, valid_scenario, "light.toml")
    assert run_cli("batch", str(two_scenarios / "light.toml"), "--out", str(out), "--quiet").returncode == 1
    page = write_report(out).read_text()
    assert not (out / "episodes.csv").exists() and not (out / "report" / "ego_speed.png").exists()
    assert "0 of 1 runs ok" in page and "alt='pair_timeline'" not in page


def test_the_timeline_plots_numbers_and_tables_show_runs_without_any(tmp_path):
    from sumo_rss.report.plots import pair_timeline
    from sumo_rss.report.summary import violation_table

    states = pd.DataFrame({"run_id": "r/0", "episode_key": "a|b|1", "time_s": [1.0, 1.1, 1.2],
                           "lon_gap_m": [5.0, 4.0, 3.0], "lon_d_min_m": [9.0, 9.0, 9.0],
                           "lat_gap_m": ["-1.5", "", "-1.25"], "lat_d_min_m": ["0.35", "", "0.35"]})
    episode = pd.Series({"run_id": "r/0", "episode_key": "a|b|1", "t_b_s": 1.0, "t_end_s": 1.2, "owed_a": "",
                         "owed_b": "lon:brake-min", "responsible": "b"})
    fig, _ = pair_timeline(states, episode)  # text cells, as a batch CSV with junction rows reads
    gap = fig.axes[1].get_lines()[0].get_ydata()
    assert gap[0] == -1.5 and gap[2] == -1.25 and str(gap[1]) == "nan"
    violations = pd.DataFrame({"constraint": ["lat-speed-envelope"], "scenario": ["s"], "variant": ["a"]})
    table = violation_table(violations, ["s [a]", "s [b]"])
    assert table.loc["lat-speed-envelope"].to_dict() == {"s [a]": 1, "s [b]": 0}
    assert table.loc["signal-red-light"].to_dict() == {"s [a]": 0, "s [b]": 0}  # every rule: 0 is not "unchecked"
    assert violation_table(pd.DataFrame(), ["s [a]"]).loc["lon-brake-beyond-max", "s [a]"] == 0
    assert responsibility_table(pd.DataFrame(), ["s [b]"]).loc["s [b]"].sum() == 0


def test_batch_spec_errors_name_the_file_and_key(tmp_path):
    bad = tmp_path / "b.toml"
    bad.write_text('[batch]\nscenarios = ["x.toml"]\nseeds = "9:3"\n')
    with pytest.raises(Exception, match=r"b\.toml: batch\.seeds: expected a list of integers"):
        load_batch(bad)
    bad.write_text('[batch]\nscenarios = ["x.toml"]\n[batch.grid]\nrss_preset = ["strict"]\n')
    with pytest.raises(Exception, match=r"b\.toml: batch\.grid\.rss_preset: expected values among"):
        load_batch(bad)
    bad.write_text('[batch]\nscenarios = ["x.toml"]\nseeds = [1, 3000000000]\n')  # SUMO's seed is 32-bit
    with pytest.raises(Exception, match=r"b\.toml: batch\.seeds: expected a list of integers in \[0, 2147483647\]"):
        load_batch(bad)
    proc = run_cli("run", "scenarios/highway_dense.toml", "--seed", "3000000000")
    assert proc.returncode == 2 and "--seed: expected an integer in [0, 2147483647]" in proc.stderr
    assert isinstance(BatchSpec, type)


def _default_sigint() -> None:
    """A shell ignores SIGINT in the commands it starts in the background, and Python then keeps ignoring it: the
    batch gets the default SIGINT, as an interactive user's has, however the tests were launched."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("stop, ray", [(signal.SIGINT, False), (signal.SIGTERM, False), (signal.SIGTERM, True)],
                         ids=["ctrl-c", "sigterm", "sigterm-ray"])
def test_ctrl_c_stops_cleanly_and_keeps_what_finished(two_scenarios, tmp_path, stop, ray):
    """Ctrl-C (a terminal sends SIGINT to the batch and its workers: the whole process group), or SIGTERM as a job
    scheduler or timeout sends it (to the batch). The workers stop quietly: each printed its traceback. On Ray too:
    ray.init installs a SIGTERM handler of its own (exit code 15, no summary message)."""
    if ray:
        pytest.importorskip("ray")
    out = tmp_path / "out"
    parent = subprocess.Popen([sys.executable, "-m", "sumo_rss", "batch", str(two_scenarios / "batch.toml"),
                               "--out", str(out), "--quiet", *(["--ray-address", "local"] if ray else [])], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint,
                              start_new_session=True)
    deadline = time.time() + 120
    # A finished run: its summary in its own folder, not in the '.partial' folder it is written in before the rename
    # (pathlib's '*' matches dot-folders too).
    while not [s for s in out.glob("*/*/summary.json") if not s.parent.name.endswith(".partial")] and \
            time.time() < deadline:
        time.sleep(0.05)
    if stop == signal.SIGINT:
        os.killpg(parent.pid, stop)
    else:
        parent.send_signal(stop)
    _, err = parent.communicate(timeout=60)
    assert parent.returncode == 130 and "interrupted" in err and "Traceback" not in err, \
        (parent.returncode, err[-4000:])
    assert ray or not list(out.glob("**/.*.partial"))  # on Ray the runs stop a moment later (docs/batches.md)
    assert not (out / ".batch.lock").exists()
    assert not [lock for lock in out.glob("**/.writer.lock") if not lock.parent.name.endswith(".partial")]
    summary = read_batch_csv(out, "batch_summary")
    assert (summary.status == "ok").sum() >= 1 and set(summary.status) <= {"ok", "missing"}


def _start_run(scenario, out) -> subprocess.Popen:
    """'sumo-rss run' of ``scenario`` for 600 s, once it has started stepping (its route file is written)."""
    proc = subprocess.Popen([sys.executable, "-m", "sumo_rss", "run", str(scenario), "--duration", "600", "--out",
                             str(out), "--quiet"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    deadline = time.time() + 120
    while not list(out.glob("*/.*.partial/routes.rou.xml")) and time.time() < deadline:
        time.sleep(0.05)
    return proc


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_or_sigterm_ends_a_single_run_early_with_its_results(two_scenarios, tmp_path, stop):
    """'sumo-rss run' stopped by Ctrl-C, or by SIGTERM as a scheduler or timeout sends it: the run ends after the
    current step and is written up to there, as the run of that duration is (an hour's run is not lost)."""
    out = tmp_path / "out"
    proc = _start_run(two_scenarios / "light.toml", out)
    time.sleep(5.0)  # a few simulated seconds
    proc.send_signal(stop)
    printed, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "stopping after this step" in err and "Traceback" not in err, (printed, err)
    (run,) = out.glob("*/*")
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "interrupted" and 1.0 < summary["sim_time_s"] < 600.0
    assert f"interrupted at {summary['sim_time_s']:g} s" in printed and not list(out.glob("**/.*.partial"))
    short = load_scenario(two_scenarios / "light.toml").with_overrides(duration_s=summary["sim_time_s"])
    assert run_one(short, tmp_path / "short").steps == summary["steps"]
    for name in AUDIT_FILES:
        assert (run / name).read_bytes() == (tmp_path / "short" / run.relative_to(out) / name).read_bytes(), name


def test_a_second_signal_aborts_a_single_run_without_results(two_scenarios, tmp_path):
    """The second signal is sent once the first is acknowledged: two sent at once were seen to count as one under
    load (1 in 16), while SUMO stepped too."""
    out = tmp_path / "out"
    proc = _start_run(two_scenarios / "light.toml", out)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    first = proc.stderr.readline()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "stopping after this step" in first and "sumo-rss: interrupted" in err
    assert list(out.glob("**/.*.partial")) == [] and list(out.glob("*/*")) == []


def test_a_batch_script_without_a_main_guard_fails_with_a_message_that_says_so(two_scenarios, tmp_path):
    """Workers are spawned and import the script again: without the guard each one dies before its run starts,
    and the failure says why instead of blaming SUMO."""
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from pathlib import Path\n"
        "from sumo_rss.batch.executors import LocalExecutor\n"
        "from sumo_rss.batch.orchestrator import run_batch\n"
        "from sumo_rss.batch.spec import load_batch\n"
        f"tasks = load_batch(Path({str(two_scenarios / 'batch.toml')!r})).tasks()[:1]\n"
        f"rows = run_batch(tasks, Path({str(tmp_path / 'out')!r}), LocalExecutor(workers=1), progress=False)\n"
        "print('STATUS', rows.status.iloc[0], rows.error.iloc[0])\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    status = [line for line in done.stdout.splitlines() if line.startswith("STATUS")]
    assert status and status[0].startswith("STATUS failed"), done.stdout + done.stderr
    assert 'if __name__ == "__main__":' in status[0] and "SUMO crashed" not in status[0]


def test_the_batch_lock_is_exclusive_and_a_left_over_lock_file_is_taken_over(tmp_path):
    """The lock is an flock: held, a second batch in the folder is refused with the holder's process id; a lock
    file left by a killed batch (any content: its process is gone, and the kernel dropped its lock) is no
    obstacle, and the lock file is gone after the batch."""
    (tmp_path / ".batch.lock").write_text("garbage\n")
    with _BatchLock(tmp_path, []):
        assert (tmp_path / ".batch.lock").read_text() == f"{os.getpid()}\n"
        with pytest.raises(SumoRssError, match=rf"another batch \(process {os.getpid()}\) is running"):
            _BatchLock(tmp_path, []).__enter__()
    assert not (tmp_path / ".batch.lock").exists()
    with _BatchLock(tmp_path, []):
        pass


@pytest.mark.parametrize("damaged, content", [("summary.json", '{"run_id": '), ("summary.json", "[]"),
                                              ("summary.json", "{}"), ("manifest.json", "[]")])
def test_a_finished_run_with_a_damaged_summary_is_run_again(two_scenarios, tmp_path, damaged, content):
    """Cut short, or valid JSON that is not what a finished run writes: run again (a JSON list was a traceback, an
    empty object a finished run with an empty status, reported as failed at every rerun)."""
    tasks = load_batch(two_scenarios / "batch.toml").tasks()[:1]
    out = tmp_path / "out"
    run_batch(tasks, out, LocalExecutor(workers=1), progress=False)
    (out / tasks[0].run_id / damaged).write_text(content)
    with pytest.warns(UserWarning, match=rf"1 run folder\(s\) are not a finished run .*{damaged} is missing or damaged"):
        rows = run_batch(tasks, out, LocalExecutor(workers=1), progress=False)
    assert rows.status.tolist() == ["ok"]
    assert json.loads((out / tasks[0].run_id / "summary.json").read_text())["status"] == "ok"


def _kill_itself() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def test_a_worker_killed_while_starting_is_not_blamed_on_a_missing_main_guard(two_scenarios, tmp_path):
    task = load_batch(two_scenarios / "batch.toml").tasks()[0]
    proc = multiprocessing.get_context("spawn").Process(target=_kill_itself)
    proc.start()
    proc.join()
    outcome = LocalExecutor._outcome(proc, task, tmp_path, started=False)
    assert outcome.status == "failed"
    assert outcome.error.startswith("worker process died (killed by signal 9) while starting") and \
        "__main__" not in outcome.error


@pytest.mark.parametrize("content, message", [
    (None, r"no batch_summary\.csv; run 'sumo-rss batch' first"),
    ("", r"batch_summary\.csv: not a CSV file as 'sumo-rss batch' writes it"),
    ("run_id,scenario,variant,seed\nhw/0,hw,,0\n", r"batch_summary\.csv: column 'status' is missing \(expected the "
                                                 r"columns run_id, scenario, variant, seed, status"),
    ("run_id,scenario,variant,seed,status\n", r"batch_summary\.csv: lists no runs"),
])
def test_report_on_a_damaged_batch_folder_names_the_file_and_what_is_wrong(tmp_path, content, message):
    if content is not None:
        (tmp_path / "batch_summary.csv").write_text(content)
    with pytest.raises(SumoRssError, match=message):
        write_report(tmp_path)


def test_the_ego_speed_plot_takes_the_lowest_seed_whose_ego_was_on_the_road(tmp_path):
    """Seed 0's ego never got on the road (its trace has a header only); seed 1's did: the report plots seed 1,
    not nothing. A failed seed 2 is not looked at."""
    header = "time_s,x_m,y_m,speed_ms,accel_ms2,lane_id,lane_pos_m,lat_pos_m\n"
    for seed, rows in ((0, ""), (1, "30.000000,1.0,2.0,20.000000,0.0,hw0_1,20.0,0.0\n")):
        (tmp_path / "hw" / str(seed)).mkdir(parents=True)
        (tmp_path / "hw" / str(seed) / "ego_trace.csv").write_text(header + rows)
    summary = pd.DataFrame({"run_id": ["hw/0", "hw/1", "hw/2"], "scenario": "hw", "variant": "", "seed": [0, 1, 2],
                            "status": ["ok", "ok", "failed"]})
    traces = ego_traces(tmp_path, summary)
    assert list(traces) == ["hw seed 1"] and traces["hw seed 1"].speed_ms.tolist() == [20.0]


def test_the_runs_table_prints_three_decimals_also_next_to_a_failed_run(tmp_path):
    """A failed run's empty cells made the number columns text, printed with all their decimals."""
    summary = pd.DataFrame({"run_id": ["hw/0", "hw/1"], "variant": ["", ""], "status": ["ok", "failed"],
                            "real_time_factor": ["13.456789", ""], "episodes": ["400", ""],
                            "steps": pd.array([3000, None], dtype="Int64"), "error": ["", "Traceback ..."]})
    shown = _numbers_as_numbers(summary).to_html(index=False, float_format=lambda v: f"{v:.3f}", na_rep="")
    assert "13.457" in shown and "13.456789" not in shown and "Traceback ..." in shown
    # Empty cells stay empty (an all-empty text column, and whole numbers beside a failed run were '<NA>').
    assert "NA" not in shown and "<td>400</td>" in shown and "<td>3000</td>" in shown


def test_report_names_an_emptied_audit_csv_of_the_batch(tmp_path):
    (tmp_path / "batch_summary.csv").write_text("run_id,scenario,variant,seed,status\nhw/0,hw,,0,ok\n")
    (tmp_path / "episodes.csv").write_text("")
    with pytest.raises(SumoRssError, match=r"episodes\.csv: not a CSV file as 'sumo-rss batch' writes it"):
        write_report(tmp_path)


def test_a_worker_whose_batch_died_while_it_started_exits_at_once():
    """A worker process sets 'die with my parent' only once its Python code runs (~1 s after it is spawned); a
    batch killed before that left it adopted by init, running its whole simulation beside the next batch. It now
    checks that its parent is still the batch that started it."""
    code = ("import sys; from sumo_rss.batch.executors import _die_with_parent; _die_with_parent(int(sys.argv[1])); "
            "print('ran')")
    for parent, expected in ((os.getpid(), (0, "ran\n")), (os.getpid() + 4_000_000, (1, ""))):
        proc = subprocess.run([sys.executable, "-c", code, str(parent)], capture_output=True, text=True, cwd=REPO,
                              check=False)
        assert (proc.returncode, proc.stdout) == expected, proc.stderr


def test_json_files_take_numpy_numbers(tmp_path):
    """A controller's summary() with numpy numbers (planner.json) is written as plain JSON."""
    import json

    import numpy as np

    from sumo_rss.files import write_json

    write_json(tmp_path / "p.json", {"count": np.int64(3), "mean": np.float64(0.5), "values": np.arange(2)})
    assert json.loads((tmp_path / "p.json").read_text()) == {"count": 3, "mean": 0.5, "values": [0, 1]}
    with pytest.raises(TypeError, match="expected JSON data, got object"):
        write_json(tmp_path / "q.json", {"x": object()})


def test_report_keeps_numeric_looking_names_as_text_and_counts_whole_beside_a_failed_run(valid_scenario, tmp_path):
    """A scenario named '007' stays '007' in every table (pandas read it as 7 from episodes.csv alone, splitting
    its row in two); a failed run's empty cells do not turn the Runs table's counts into 200.000."""
    valid_scenario["duration_s"] = 20.0
    valid_scenario["demand"]["flows"][0]["veh_per_hour"] = 3000
    write_scenario(tmp_path, valid_scenario, "007.toml")
    valid_scenario["sumo"] = {"extra_args": ["--max-depart-delay", "soon"]}
    write_scenario(tmp_path, valid_scenario, "broken.toml")
    (tmp_path / "batch.toml").write_text('[batch]\nscenarios = ["007.toml", "broken.toml"]\nseeds = [0]\n')
    out = tmp_path / "b"
    rows = run_batch(load_batch(tmp_path / "batch.toml").tasks(), out, LocalExecutor(workers=1), progress=False)
    assert rows.status.tolist() == ["ok", "failed"]
    page = write_report(out).read_text()
    episodes = read_batch_csv(out, "episodes")
    assert set(episodes.scenario) == {"007"} and len(episodes) > 0
    table = responsibility_table(episodes, ["007", "broken"])
    assert table.index.tolist() == ["007", "broken"] and int(table.loc["007"].sum()) == len(episodes)
    assert "<td>200</td>" in page and "200.000" not in page  # 20 s in 0.1 s steps
