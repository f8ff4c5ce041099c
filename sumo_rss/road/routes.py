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
        self._matrix = np.full((16, 1), -1, dtype=int)  # rows beyond len(self._ids) are spare (grown by doubling)
        self._width = 1  # the longest route so far (at least 1)
        # The row of each route object seen lately, by identity (a route's tuple comes again at every step: hashing
        # its edge ids per vehicle and step was ~2 % of a city audit); kept with the object, so an id is never reused
        # while it is here, and emptied when it outgrows the routes known (sources that make new tuples each step).
        self._by_object: dict[int, tuple[tuple[str, ...] | None, int]] = {}

    def remaining(self, snapshot: WorldSnapshot) -> np.ndarray:
        """[n, k] edge indices of each vehicle's remaining route, -1 padded (all -1 where unknown)."""
        n = len(snapshot)
        routes = snapshot.route_edges or (None,) * n
        if len(self._by_object) > 4 * len(self._ids) + 4096:
            self._by_object.clear()
        ids = np.fromiter(map(self._row_of_object, routes), dtype=int, count=n)
        table = self._matrix[ids, : self._width]
        passed = np.arange(table.shape[1])[None, :] < snapshot.route_index[:, None]
        return np.where(passed, -1, table)

    def _row_of_object(self, route: tuple[str, ...] | None) -> int:
        """:meth:`_row` of ``route``, found by the object's identity where it was seen before."""
        known = self._by_object.get(id(route))
        if known is not None and known[0] is route:
            return known[1]
        row = self._row(route)
        self._by_object[id(route)] = (route, row)
        return row

    def _row(self, route: tuple[str, ...] | None) -> int:
        """Row of ``route`` (edge indices, -1 padded) in the matrix, added on first sight."""
        key = route or None
        row = self._ids.get(key)
        if row is None:
            edges = self.network.edge_indices(key) if key else np.zeros(0, dtype=int)
            row = len(self._ids)
            rows, width = self._matrix.shape
            if row == rows or len(edges) > width:  # grown by doubling: adding R routes copies O(R) rows
                grown = np.full((2 * rows if row == rows else rows, max(width, 2 * len(edges))), -1, dtype=int)
                grown[:rows, :width] = self._matrix
                self._matrix = grown
            self._matrix[row, : len(edges)] = edges
            self._width = max(self._width, len(edges))
            self._ids[key] = row
        return row
