"""Shared by the benchmarks: their command line, machine facts and locked, atomic updates of bench/results.json."""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import platform
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from sumo_rss.files import write_json

RESULTS = Path(__file__).resolve().parent / "results.json"


def arguments(doc: str, script: str, add: Callable[[argparse.ArgumentParser], None] | None = None
              ) -> argparse.Namespace:
    """``--help`` (the benchmark's docstring) and ``--no-record`` (print the figures, leave results.json alone),
    and the benchmark's own options (``add(parser)``)."""
    parser = argparse.ArgumentParser(
        prog=f"python bench/{script}", description=doc, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"examples:\n  PYTHONPATH=. python bench/{script}              # measure, record in results.json\n"
               f"  PYTHONPATH=. python bench/{script} --no-record  # measure and print only")
    parser.add_argument("--no-record", dest="record", action="store_false",
                        help="print the figures instead of recording them in bench/results.json")
    if add is not None:
        add(parser)
    return parser.parse_args()


def machine() -> dict:
    import libsumo
    import numpy

    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": numpy.__version__, "sumo": libsumo.getVersion()[1], "platform": platform.platform(), **_code()}


def _code() -> dict:
    """The commit measured and whether the working tree had changes (figures from mixed versions show)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=RESULTS.parent, capture_output=True, text=True,
                              check=True).stdout.strip()
    try:
        # results.json itself (written by every benchmark) is not a change to the code measured.
        changes = git("status", "--porcelain", "--untracked-files=no", "--", ":(top)",
                      ":(top,exclude)bench/results.json")
        return {"commit": git("rev-parse", "HEAD"), "dirty": bool(changes)}
    except (OSError, subprocess.CalledProcessError):
        return {"commit": None, "dirty": None}


def record(name: str, figures: dict, options: argparse.Namespace) -> None:
    """Store ``figures`` under ``benchmarks.<name>`` with the machine and commit they were measured on (or print
    them, with ``--no-record``). Benchmarks run at the same time each keep their entry: the read-modify-write holds
    a lock, and the file is replaced by a complete temporary file (numpy numbers as their values)."""
    entry = {"measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "machine": machine(), **figures}
    if not options.record:
        print(json.dumps({name: entry}, indent=2, sort_keys=True))
        return
    with open(RESULTS.with_name(".results.json.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        data = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
        data.setdefault("benchmarks", {})[name] = entry
        write_json(RESULTS, data)
