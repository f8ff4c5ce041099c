"""sumo_rss: responsibility-aware traffic simulation with SUMO and an RSS auditor.

Public API (libsumo is imported only by ``sumo_rss.sim.session``, on first use of :class:`Session`).
"""
from __future__ import annotations

__version__ = "0.1.0"

from .errors import ScenarioError, SessionError, SumoRssError
from .scenario import ScenarioSpec, load_scenario
from .sim.snapshot import WorldSnapshot
from .trajectory import Trajectory

__all__ = ["ScenarioError", "ScenarioSpec", "SessionError", "SumoRssError", "Trajectory", "WorldSnapshot",
           "__version__", "load_scenario"]
