"""Vehicles' remaining routes as one padded array of edge indices (for vectorised 'where does it go next')."""
from __future__ import annotations

import numpy as np

from ..sim.snapshot import WorldSnapshot
from .network import RoadNetwork


class RouteTable:
    """Each distinct route is turned into edge indices once; a snapshot's remaining routes are then one gather."""

    def __init__(self, network: RoadNetwork):
        self.network = network
        self._ids: dict[tuple[str, ...] | None, int] = {}
        self._matrix = np.full((0, 1), -1, dtype=int)

    def remaining(self, snapshot: WorldSnapshot) -> np.ndarray:
        """[n, k] edge indices of each vehicle's remaining route, -1 padded (all -1 where unknown)."""
        n = len(snapshot)
        routes = snapshot.route_edges or (None,) * n
        ids = np.fromiter((self._row(r) for r in routes), dtype=int, count=n)
        table = self._matrix[ids]
        passed = np.arange(table.shape[1])[None, :] < snapshot.route_index[:, None]
        return np.where(passed, -1, table)

    def _row(self, route: tuple[str, ...] | None) -> int:
        """Row of ``route`` (edge indices, -1 padded) in the matrix, added on first sight."""
        key = route or None
        row = self._ids.get(key)
        if row is None:
            edges = self.network.edge_indices(key) if key else np.zeros(0, dtype=int)
            width = max(self._matrix.shape[1], len(edges), 1)
            matrix = np.full((self._matrix.shape[0] + 1, width), -1, dtype=int)
            matrix[:-1, : self._matrix.shape[1]] = self._matrix
            matrix[-1, : len(edges)] = edges
            self._matrix, row = matrix, matrix.shape[0] - 1
            self._ids[key] = row
        return row
