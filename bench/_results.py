"""Shared by the benchmarks: machine facts and atomic updates of bench/results.json."""
from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results.json"


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
            "numpy": numpy.__version__, "sumo": libsumo.getVersion()[1], "platform": platform.platform()}


def record(name: str, figures: dict) -> None:
    """Store ``figures`` under ``benchmarks.<name>`` with the machine they were measured on."""
    data = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    data.setdefault("benchmarks", {})[name] = {"measured_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                                               "machine": machine(), **figures}
    tmp = RESULTS.with_name(".results.json.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, RESULTS)
