"""Where batch tasks run: local processes (default) or a Ray cluster.

Both run :func:`execute` per task, which writes the run directory (or ``<run>.failed/failed.json`` with the
traceback) and never raises: a run whose failure record cannot be written either (its folder is not writable, the
disk is full) still ends as a failed outcome with both reasons, and the batch goes on. The local executor starts one
spawned process per task, at most ``workers`` at a time: libsumo is a process-wide singleton, and a task that crashes
SUMO takes down only its own process. Each child dies with its parent (Linux ``PR_SET_PDEATHSIG``), so a killed
batch leaves no orphan simulations, and is started with Ctrl-C ignored (a worker still importing printed a
``KeyboardInterrupt`` traceback; the batch stops its workers itself).
"""
from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import pickle
import shutil
import signal
import socket
import sys
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from ..errors import SumoRssError
from ..files import make_folder, read_json_object, write_json
from .runner import SUMMARY_FILE, run_directory, run_one
from .spec import Task

FAILED_FILE = "failed.json"
CONNECT_TIMEOUT_S = 5.0  # [s] for a Ray cluster's address to answer


@dataclass(frozen=True)
class Outcome:
    run_id: str
    status: str  # 'ok' | 'failed'
    error: str = ""


def failure_directory(out_dir: Path, task: Task) -> Path:
    run_dir = run_directory(out_dir, task)
    return run_dir.with_name(f"{run_dir.name}.failed")


def record_failure(out_dir: Path, task: Task, error: str, trace: str) -> Outcome:
    """Write the task's ``<run>.failed/failed.json``; where that fails too, the outcome's error says so (it is what
    the batch summary shows for the run)."""
    folder = failure_directory(out_dir, task)
    try:
        make_folder(folder)
        write_json(folder / FAILED_FILE, {"run_id": task.run_id, "scenario": task.spec.name, "variant": task.variant,
                                          "seed": task.spec.seed, "error": error, "traceback": trace})
    except (OSError, SumoRssError) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        _remove_empty_folders(folder.parent, Path(out_dir))
        return Outcome(task.run_id, "failed", f"{error}; its failure record could not be written either: {exc}")
    return Outcome(task.run_id, "failed", error)


def _remove_empty_folders(folder: Path, top: Path) -> None:
    """``folder`` and its parents up to (not including) ``top`` where they are empty."""
    while folder != top and top in folder.parents:
        try:
            folder.rmdir()
        except OSError:  # not empty, or gone
            return
        folder = folder.parent


def execute(task: Task, out_dir: str | Path) -> Outcome:
    """Run one task; a failure is recorded with its traceback, never raised (Ctrl-C still is)."""
    out_dir = Path(out_dir)
    shutil.rmtree(failure_directory(out_dir, task), ignore_errors=True)
    try:
        run_one(task.spec, out_dir, variant=task.variant)
    except Exception as exc:
        return record_failure(out_dir, task, f"{type(exc).__name__}: {exc}", traceback.format_exc())
    return Outcome(task.run_id, "ok")


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this process when its parent (pid ``parent``) dies; exit now if it already has (the
    batch was killed while this process started: it was adopted by init and ran its task alone)."""
    if sys.platform.startswith("linux"):
        pr_set_pdeathsig = 1
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != parent:
        raise SystemExit(1)


def _child(task: Task, out_dir: str, started: Any, parent: int, report: Connection) -> None:
    # Ctrl-C reaches the whole process group: the batch stops its workers. The process was started with Ctrl-C
    # ignored and blocked (_ctrl_c_ignored); ignored it stays, and its own processes (SUMO) get it unblocked.
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _die_with_parent(parent)
    started.set()
    outcome = execute(task, out_dir)
    report.send(outcome)  # the error also where its failure record could not be written
    raise SystemExit(0 if outcome.status == "ok" else 1)


@contextmanager
def _ctrl_c_ignored() -> Iterator[None]:
    """Processes started in the block begin with Ctrl-C ignored: Python keeps an ignored SIGINT ignored, so a
    worker still importing the modules does not stop with a KeyboardInterrupt traceback. Ctrl-C is blocked first, so
    one that arrives meanwhile waits for this process's own handler (Linux keeps an ignored signal pending while it
    is blocked)."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


class LocalExecutor:
    """At most ``workers`` spawned processes, one task each."""

    def __init__(self, workers: int = 1):
        if workers < 1:
            raise SumoRssError(f"--workers: expected an integer >= 1, got {workers}")
        self.workers = workers

    def run(self, tasks: list[Task], out_dir: Path, on_result: Callable[[Outcome], None]) -> None:
        ctx = mp.get_context("spawn")
        pending = deque(tasks)
        running: dict[object, tuple[mp.process.BaseProcess, Task, Any, Connection]] = {}
        try:
            while pending or running:
                while pending and len(running) < self.workers:
                    task = pending.popleft()
                    started = ctx.Event()  # set once the worker runs our code (after importing __main__)
                    receive, send = ctx.Pipe(duplex=False)
                    proc = ctx.Process(target=_child, args=(task, str(out_dir), started, os.getpid(), send),
                                       name=task.run_id)
                    with _ctrl_c_ignored():
                        proc.start()
                    send.close()
                    running[proc.sentinel] = (proc, task, started, receive)
                for sentinel in wait(list(running)):
                    proc, task, started, receive = running.pop(sentinel)
                    proc.join()
                    reported = _received(receive)
                    on_result(self._outcome(proc, task, out_dir, started.is_set(), reported))
        except BaseException:
            for proc, _, _, _ in running.values():
                proc.kill()
            for proc, _, _, _ in running.values():
                proc.join()
            raise

    @staticmethod
    def _outcome(proc: mp.process.BaseProcess, task: Task, out_dir: Path, started: bool,
                 reported: Outcome | None = None) -> Outcome:
        """The outcome the worker reported, or what its exit and its files tell (a worker that died)."""
        if reported is not None and proc.exitcode in (0, 1):
            return reported
        if (run_directory(out_dir, task) / SUMMARY_FILE).is_file() and proc.exitcode == 0:
            return Outcome(task.run_id, "ok")
        recorded = read_json_object(failure_directory(out_dir, task) / FAILED_FILE)
        if recorded is not None and isinstance(recorded.get("error"), str):
            return Outcome(task.run_id, "failed", recorded["error"])
        killed = proc.exitcode is not None and proc.exitcode < 0
        how = f"killed by signal {-proc.exitcode}" if killed else f"exit code {proc.exitcode}"
        if not started and killed:  # killed from outside (or out of memory) while importing
            return record_failure(out_dir, task, f"worker process died ({how}) while starting, before it began the "
                                  "run (out of memory?)", "")
        if not started:  # it failed importing the main module again, as spawned processes do
            return record_failure(out_dir, task, f"worker process died ({how}) before it started the run: a script "
                                  "that runs batches must start them under `if __name__ == \"__main__\":` (each "
                                  "worker is a spawned process that imports the script again); see the worker's "
                                  "error above", "")
        return record_failure(out_dir, task, f"worker process died ({how}); SUMO crashed?", "")


def _received(receive: Connection) -> Outcome | None:
    """The outcome a worker sent before it ended (None: it sent none, or died while sending); closes the pipe."""
    try:
        return receive.recv() if receive.poll() else None
    except (EOFError, OSError, pickle.UnpicklingError):
        return None
    finally:
        receive.close()


class RayExecutor:
    """Tasks as Ray remote functions on the cluster at ``address`` ('auto', 'host:port', or 'local' for a
    fresh local instance). The output folder must be shared by all nodes."""

    def __init__(self, address: str):
        """Connects at once, so that a batch without a cluster fails before it creates its folder."""
        try:
            import ray
        except ImportError:
            raise SumoRssError("--ray-address needs Ray: pip install 'sumo-rss[ray]'") from None
        self.address = address
        self.connected_here = not ray.is_initialized()  # this executor connected (and disconnects on a stop)
        if self.connected_here:
            _check_listening(address)
            try:
                ray.init(address=None if address == "local" else address, log_to_driver=False)
            except ConnectionError as exc:  # a one-line error, not Ray's traceback
                if address in ("auto", "local"):
                    raise _no_cluster(address, "to connect to", exc) from None
                # Something listens there (checked above) but refused or did not answer as a Ray cluster.
                raise SumoRssError(f"--ray-address {address}: the Ray cluster there refused the connection or did "
                                   f"not answer ({exc})") from None

    def run(self, tasks: list[Task], out_dir: Path, on_result: Callable[[Outcome], None]) -> None:
        import ray

        remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        futures = {remote.remote(task, str(out_dir)): task for task in tasks}
        try:
            while futures:
                done, _ = ray.wait(list(futures), num_returns=1)
                task = futures.pop(done[0])
                try:
                    on_result(ray.get(done[0]))
                except ray.exceptions.RayError as exc:  # the worker died: SUMO crashed, node lost, ...
                    on_result(record_failure(out_dir, task, f"{type(exc).__name__}: {exc}", ""))
        except BaseException:
            # Stop the runs still going. Cancelling a task whose result is arriving can crash the driver's Ray core
            # worker (ray 2.60: "Tried to complete task that was not pending", exit code 1 instead of the batch's
            # 130). Where this executor connected, disconnecting stops them instead: a local instance ends with its
            # processes, and a cluster's raylets end a finished job's workers.
            if self.connected_here:
                ray.shutdown()
            else:
                for future in futures:
                    ray.cancel(future, force=True)
            raise


def _check_listening(address: str) -> None:
    """For a 'host:port' address, that something listens there: Ray itself retries an address without a cluster
    for ever (every 40 s, 'Failed to connect to GCS')."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return  # 'auto', 'local' or a form Ray resolves itself
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise _no_cluster(address, "listens there", exc) from None


def _no_cluster(address: str, where: str, cause: Exception) -> SumoRssError:
    return SumoRssError(f"--ray-address {address}: no Ray cluster {where} ({cause}); start one with 'ray start "
                        "--head', or use 'local'")
