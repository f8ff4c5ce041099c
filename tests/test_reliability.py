"""What the tool promises when the disk, the results folders or the user get in the way (docs/outputs.md, "Bad
input, full disks and interruptions"): a run cut by a file-size limit fails naming the file, an audit writes its
outputs all or none, a run that cannot even record its failure does not end its batch, a resumed batch re-runs a
damaged run, Ctrl-C while the workers still start prints no traceback, warnings never share the progress bar's
line."""
from __future__ import annotations

import errno
import json
import os
import resource
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import NETWORKS, REPO, run_cli, two_scenario_batch
from sumo_rss.batch.executors import LocalExecutor
from sumo_rss.batch.orchestrator import run_batch
from sumo_rss.batch.spec import load_batch
from sumo_rss.errors import OutputError
from sumo_rss.files import output_error, write_file_set
from sumo_rss.report.summary import read_batch_csv

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"


@pytest.fixture
def two_scenarios(tmp_path, valid_scenario):
    """Two 10 s highway scenarios (different demand) and a batch file over seed 0."""
    return two_scenario_batch(tmp_path, valid_scenario, 10.0, "[0]")


def _file_size_limit(size: int):
    """For a child process: writes past ``size`` bytes fail with EFBIG (Python ignores SIGXFSZ), as on a full
    disk they fail with ENOSPC."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


def _one_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr and lines and lines[-1].startswith("sumo-rss: error: "), stderr
    assert all(line.startswith("sumo-rss: ") for line in lines), stderr
    return lines[-1]


def test_a_run_whose_fcd_sumo_could_not_write_to_its_end_fails_naming_the_file(two_scenarios, tmp_path):
    """SUMO does not notice a write that fails: its fcd.xml ended mid-element and the run said 'ok'."""
    out = tmp_path / "out"
    proc = run_cli("run", str(two_scenarios / "busy.toml"), "--fcd", "--out", str(out), "--quiet",
                   preexec_fn=_file_size_limit(100_000))
    assert proc.returncode == 2, proc.stderr
    line = _one_error_line(proc.stderr)
    # named where the run's folder would be (not in the hidden folder it was built in, which is gone)
    assert f"{out / 'busy' / '1' / 'fcd.xml'}: SUMO's output ends before its end tag </fcd-export>" in line
    assert "file-size limit" in line
    assert not out.exists()  # a failed run leaves nothing behind


def test_a_write_error_names_the_file_written_not_its_temporary():
    """A full disk while an npz of an audit's file set was written named '.episode_states.npz.tmp'."""
    for temporary in (".episode_states.npz.tmp", "..episode_states.npz.tmp.tmp"):
        exc = OSError(errno.ENOSPC, "No space left on device", f"out/{temporary}")
        assert str(output_error(Path("out") / temporary, exc)) == \
            "out/episode_states.npz: cannot be written: no space left on its disk (free some, or write elsewhere)"


def test_an_audit_that_cannot_write_its_outputs_writes_none_and_names_the_file(two_scenarios, tmp_path):
    run = tmp_path / "run"
    assert run_cli("run", str(two_scenarios / "busy.toml"), "--fcd", "--out", str(run), "--quiet").returncode == 0
    folder = run / "busy" / "1"
    # [bytes] the vType file SUMO is given (~1 kB) and collisions.csv fit, episodes.csv does not, nor the steps of the
    # episodes spooled to disk while the audit runs (docs/viewer.md)
    limit = (folder / "episodes.csv").stat().st_size - 1
    assert limit > 1500 > (folder / "collisions.csv").stat().st_size
    out = tmp_path / "audit"
    out.mkdir()
    (out / "collisions.csv").write_text("an older audit's\n")
    proc = run_cli("audit", str(folder / "fcd.xml"), "--net", str(HIGHWAY), "--vtypes", str(folder / "routes.rou.xml"),
                   "--out", str(out), "--quiet", preexec_fn=_file_size_limit(limit))
    assert proc.returncode == 2
    line = _one_error_line(proc.stderr)
    # Whichever file first outgrows the limit is named: the steps of the episodes spooled while the audit runs
    # (with where their rows go) or episodes.csv when it is written.
    named = re.search(r"(\S+): cannot be written: the file grew beyond the file-size limit", line)
    assert named and Path(named.group(1)).name in ("episode_states.npz", "episodes.csv"), line
    assert Path(named.group(1)).name == "episodes.csv" or f"(its rows go to {out}/.spool-" in line
    assert sorted(p.name for p in out.iterdir()) == ["collisions.csv"]  # no new file, no temporary file
    assert (out / "collisions.csv").read_text() == "an older audit's\n"


def test_a_file_set_is_written_whole_or_not_at_all(tmp_path):
    """An audit's outputs (AuditResult.to_csv): one that fails leaves every file as it was, and no temporary."""
    (tmp_path / "b.csv").write_text("older\n")

    def fail(path: Path) -> None:
        raise OSError(errno.EFBIG, "File too large")

    with pytest.raises(OutputError, match="b.csv: cannot be written: the file grew beyond the file-size limit"):
        write_file_set({tmp_path / "a.csv": lambda path: path.write_text("new\n"), tmp_path / "b.csv": fail})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.csv"] and (tmp_path / "b.csv").read_text() == "older\n"


def test_a_run_that_cannot_record_its_failure_does_not_end_the_batch(two_scenarios, tmp_path):
    """The results folder of one scenario is a file: its run cannot be written, nor its failure record; the other
    scenario's run is done all the same, and the summary says what happened to both."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "light").write_text("not a folder")
    proc = run_cli("batch", str(two_scenarios / "batch.toml"), "--out", str(out), "--workers", "2", "--quiet")
    assert proc.returncode == 1 and "1 runs ok, 1 failed" in proc.stdout, proc.stderr
    assert "Traceback" not in proc.stderr
    summary = read_batch_csv(out, "batch_summary").set_index("run_id")
    assert summary.loc["busy/0", "status"] == "ok" and summary.loc["light/0", "status"] == "failed"
    error = summary.loc["light/0", "error"]
    assert f"{out / 'light'} is a file (expected a folder there)" in error
    assert "its failure record could not be written either" in error


def test_a_resumed_batch_runs_a_damaged_run_again_and_names_the_file(two_scenarios, tmp_path):
    """A finished run's episodes.csv deleted, another's violations.csv cut short: the batch said '2 runs ok' and its
    CSVs lost their rows. Each is run again, with a warning naming the file, and the batch CSVs are whole again."""
    tasks = load_batch(two_scenarios / "batch.toml").tasks()
    out = tmp_path / "out"
    run_batch(tasks, out, LocalExecutor(workers=1), progress=False)
    whole = {name: (out / f"{name}.csv").read_bytes() for name in ("episodes", "violations")}
    (out / "light" / "0" / "episodes.csv").unlink()
    cut = out / "busy" / "0" / "violations.csv"
    cut.write_bytes(cut.read_bytes()[:-40])
    with pytest.warns(UserWarning) as warned:
        rows = run_batch(tasks, out, LocalExecutor(workers=1), progress=False)
    (message,) = [str(w.message) for w in warned]
    assert "2 run folder(s) are not a finished run" in message and "running them again" in message
    assert f"{out / 'light' / '0' / 'episodes.csv'} is missing" in message
    assert f"{cut} has " in message and "bytes, the run wrote" in message
    assert rows.status.tolist() == ["ok", "ok"]
    assert {name: (out / f"{name}.csv").read_bytes() for name in whole} == whole  # same bytes as before the damage
    # A manifest lists every file of its run folder, with its size and SHA-256.
    listed = json.loads((out / "light" / "0" / "manifest.json").read_text())["files"]
    assert {"episodes.csv", "summary.json", "routes.rou.xml", "sumo.log"} <= set(listed)
    assert listed["episodes.csv"]["bytes"] == (out / "light" / "0" / "episodes.csv").stat().st_size
    assert len(listed["episodes.csv"]["sha256"]) == 64
    # A file where a run's folder belongs is no finished run either (it was a NotADirectoryError traceback).
    shutil.rmtree(out / "light" / "0")
    (out / "light" / "0").write_text("not a run")
    with pytest.warns(UserWarning, match="1 run folder\\(s\\) are not a finished run"):
        assert run_batch(tasks, out, LocalExecutor(workers=1), progress=False).status.tolist() == ["ok", "ok"]
    assert (out / "episodes.csv").read_bytes() == whole["episodes"]


def _worker_pids(parent: int) -> list[int]:
    """The batch's spawned workers (not multiprocessing's resource tracker)."""
    try:
        children = Path(f"/proc/{parent}/task/{parent}/children").read_text().split()
    except OSError:
        return []
    workers = []
    for pid in children:
        try:
            if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes():
                workers.append(int(pid))
        except OSError:
            pass
    return workers


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_while_the_workers_still_start_prints_no_traceback(two_scenarios, tmp_path):
    """A terminal's Ctrl-C reaches the whole process group, workers still importing the modules included: each
    printed a KeyboardInterrupt traceback from multiprocessing's spawn_main."""
    out = tmp_path / "out"
    parent = subprocess.Popen([sys.executable, "-m", "sumo_rss", "batch", str(two_scenarios / "batch.toml"), "--out",
                               str(out), "--workers", "2", "--quiet"], cwd=REPO, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint, start_new_session=True)
    deadline = time.time() + 60
    while len(_worker_pids(parent.pid)) < 2 and time.time() < deadline:
        time.sleep(0.005)
    assert len(_worker_pids(parent.pid)) == 2
    time.sleep(0.2)  # the workers are importing sumo_rss (about a second)
    os.killpg(parent.pid, signal.SIGINT)
    _, err = parent.communicate(timeout=60)
    assert parent.returncode == 130 and "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.strip().splitlines()[-1] == "sumo-rss: interrupted"
    assert not list(out.glob("**/.*.partial"))


def test_warnings_get_their_own_line_also_while_the_progress_bar_is_shown(tmp_path):
    """A warning during an audit with its progress bar (here at its end: an ego id not in the FCD) was printed onto
    the bar's line."""
    fcd = tmp_path / "f.xml"
    steps = "".join(f'<timestep time="{k / 10:.2f}"><vehicle id="a" x="{20 + 0.3 * k:.2f}" y="-5.25" angle="90" '
                    f'speed="3" lane="hw0_1" pos="{20 + 0.3 * k:.2f}"/></timestep>\n' for k in range(200))
    fcd.write_text(f"<fcd-export>\n{steps}</fcd-export>\n")
    proc = run_cli("audit", str(fcd), "--net", str(HIGHWAY), "--ego", "nobody", "--out", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert "audit:" in proc.stderr  # the bar was shown (the audit took longer than its 0.5 s delay)
    segments = [part for line in proc.stderr.split("\n") for part in line.split("\r")]
    warned = [part for part in segments if "sumo-rss: warning:" in part]
    assert warned and all(part.startswith("sumo-rss: warning: ") for part in warned), proc.stderr
