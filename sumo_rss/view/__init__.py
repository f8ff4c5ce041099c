"""The replay viewer: a run's or audit's folder → one self-contained ``view.html`` (``sumo-rss view``).

Reads only files (the trajectory file, the audit's CSVs and episode states, the net.xml); imports nothing from
``sim`` or ``planner``. Its names load on first use, so the command line starts without pandas.
"""
from __future__ import annotations

import importlib

_EXPORTS = {"VIEW_FILE": "page", "write_view": "page", "write_run_views": "page", "NEAR_EGO_M": "trajectories",
            "TRAJECTORY_FILE": "trajectories", "Trajectories": "trajectories", "TrajectoryRecorder": "trajectories"}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> object:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
