"""The replay viewer: a run's or audit's folder → one self-contained ``view.html`` (``sumo-rss view``).

Reads only files (the trajectory file, the audit's CSVs and episode states, the net.xml); imports nothing from
``sim`` or ``planner``.
"""
from .page import VIEW_FILE, write_view
from .trajectories import NEAR_EGO_M, TRAJECTORY_FILE, Trajectories, TrajectoryRecorder

__all__ = ["NEAR_EGO_M", "TRAJECTORY_FILE", "VIEW_FILE", "Trajectories", "TrajectoryRecorder", "write_view"]
