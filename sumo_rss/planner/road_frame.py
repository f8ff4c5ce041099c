"""One Frenet frame for a planning cycle: the ego's lane chain, with the centre lines of its neighbours as
lateral-offset profiles along it (epsilon.md port: the forward simulation runs in this frame).

In the frame a vehicle is (s, d): s [m] along the ego's chain from the start of the ego's own lane, d [m] its
offset from that chain's centre line, + = left. The neighbour chains are sampled every metre and projected once,
so "where is the left lane's centre at s" is an interpolation, and nothing is projected during the simulation.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..angles import wrap_angle
from .lanes import CURRENT, LEFT, RIGHT, LaneChains

GRID_STEP = 1.0  # [m] spacing of the offset profiles


@dataclass(frozen=True, eq=False)
class FrameCells:
    """Frame positions located on the profiles' grid (:meth:`RoadFrame.locate`), for several look-ups at the same
    positions: the cell ``index`` and the ``fraction`` [0, 1) of the way to the next grid point."""

    index: np.ndarray
    fraction: np.ndarray


@dataclass(frozen=True, eq=False)
class RoadFrame:
    """``centre[c, g]``: d of chain c's centre line at s = s0 + g·GRID_STEP (edge values continued where the
    chain does not reach; ``extent[c]`` is where it does). ``end_s[c]``: where chain c's lane ends for good
    (inf if it goes on; the ego's own chain also ends where its lane leaves the ego's route), ``lane_width[c]`` its narrowest lane [m]. Chains that do not exist copy the current
    chain (``exists[c]`` False)."""

    chains: LaneChains
    s0: float
    centre: np.ndarray  # [3, G]
    extent: np.ndarray  # [3, 2] (first, last) s of each chain in the frame
    end_s: np.ndarray  # [3]
    exists: np.ndarray  # [3] bool
    lane_width: np.ndarray  # [3] m
    slope_grid: np.ndarray  # [3, G-1] heading [rad] of each chain's centre line between grid points

    @classmethod
    def build(cls, chains: LaneChains) -> RoadFrame:
        shapes, cur = chains.shapes, int(chains.chain_of[CURRENT])
        n_cur = int(shapes.count[cur])
        s_first = -float(chains.start_s[cur])
        s_last = float(shapes.cumulative[cur, n_cur - 1]) - float(chains.start_s[cur])
        grid = np.arange(s_first, s_last + GRID_STEP, GRID_STEP)
        centre = np.zeros((3, grid.size))
        extent = np.tile([s_first, s_last], (3, 1)).astype(float)
        end_s = np.full(3, np.inf)
        exists = np.zeros(3, dtype=bool)
        widths = np.full(3, float(chains.width[cur]))
        for which in range(3):
            row = int(chains.chain_of[which])
            if row < 0:
                continue
            exists[which] = True
            widths[which] = float(chains.width[row])
            n = int(shapes.count[row])
            length = float(shapes.cumulative[row, n - 1])
            along = np.arange(0.0, length + GRID_STEP, GRID_STEP)
            xs = np.interp(along, shapes.cumulative[row, :n], shapes.points[row, :n, 0])
            ys = np.interp(along, shapes.cumulative[row, :n], shapes.points[row, :n, 1])
            if which == CURRENT:
                s, d = along - chains.start_s[row], np.zeros_like(along)
            else:
                s, d = chains.project(CURRENT, xs, ys)
            order = np.argsort(s, kind="stable")
            s, d = s[order], d[order]
            centre[which] = np.interp(grid, s, d)
            extent[which] = (s[0], s[-1])
            if chains.dead_end[row]:
                end_s[which] = s[-1]
        # The ego's own lane ends where it leaves the route (an exit it must take from another lane).
        end_s[CURRENT] = min(end_s[CURRENT], chains.route_end)
        return cls(chains, float(grid[0]), centre, extent, end_s, exists, widths,
                   np.arctan(np.diff(centre, axis=1) / GRID_STEP))

    def centre_d(self, chain: Any, s: Any) -> np.ndarray:
        """d [m] of the centre line of ``chain`` (RIGHT/CURRENT/LEFT, any array shape) at frame positions ``s``
        (or their :class:`FrameCells`)."""
        i, f = self._cells(s)
        base = np.asarray(chain, dtype=np.intp) * self.centre.shape[1] + i
        flat = self.centre.ravel()
        return flat[base] * (1.0 - f) + flat[base + 1] * f

    def centres_at(self, s: Any) -> np.ndarray:
        """[3, *s.shape]: d of every chain's centre line at ``s`` (or their :class:`FrameCells`)."""
        i, f = self._cells(s)
        return self.centre.take(i, axis=1) * (1.0 - f) + self.centre.take(i + 1, axis=1) * f

    def locate(self, s: Any) -> FrameCells:
        """The grid cells of frame positions ``s`` [m] (clamped to the profiles' ends)."""
        g = np.minimum(np.maximum((np.asarray(s, dtype=float) - self.s0) / GRID_STEP, 0.0),
                       self.centre.shape[1] - 1.000001)
        i = g.astype(np.intp)
        return FrameCells(i, g - i)

    def _cells(self, s: Any) -> tuple[np.ndarray, np.ndarray]:
        cells = s if isinstance(s, FrameCells) else self.locate(s)
        return cells.index, cells.fraction

    def chain_of_offsets(self, offset: np.ndarray, s: Any) -> np.ndarray:
        """The existing chain nearest to each point at ``s``, given ``offset`` = |d − centres_at(s)| [3, ...] [m]
        (the first of equally near ones)."""
        s = np.asarray(s, dtype=float)
        shape = (3,) + (1,) * s.ndim
        usable = self.exists.reshape(shape) & (s >= self.extent[:, 0].reshape(shape)) & \
            (s <= self.extent[:, 1].reshape(shape))
        right, current, left = np.where(usable, offset, np.inf)
        return np.where(left < np.minimum(right, current), LEFT, np.where(current < right, CURRENT, RIGHT))

    def slope(self, chain: Any, s: Any) -> np.ndarray:
        """Heading [rad] of ``chain``'s centre line relative to the frame at ``s`` (or their :class:`FrameCells`;
        lanes that converge)."""
        i, _ = self._cells(s)
        return self.slope_grid.ravel().take(np.asarray(chain, dtype=np.intp) * self.slope_grid.shape[1] + i)

    @staticmethod
    def lane_ahead(centre_d: Any, slope: Any, ahead: Any) -> np.ndarray:
        """d [m] of a lane's centre line ``ahead`` [m] beyond s, continued straight from its offset ``centre_d``
        [m] at s along its direction ``slope`` = :meth:`slope` (chain, s) [rad] (the pure-pursuit target of a car
        on that lane: bends are taken when reached, not anticipated)."""
        return centre_d + np.tan(slope) * ahead

    def nearest_chain(self, s: Any, d: Any) -> np.ndarray:
        """The existing chain whose centre line is nearest to each (s, d), within its extent."""
        s, d = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(d, dtype=float))
        return self.chain_of_offsets(np.abs(d - self.centres_at(s)), s)

    def to_frame(self, x: Any, y: Any, heading: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, d, heading relative to the centre line) of points in the world [m, m, rad]."""
        x, y = np.atleast_1d(np.asarray(x, dtype=float)), np.atleast_1d(np.asarray(y, dtype=float))
        row = int(self.chains.chain_of[CURRENT])
        s, d, lane_heading = self.chains.shapes.project(np.full(x.size, row), x, y)
        rel = wrap_angle(np.asarray(heading, dtype=float) - lane_heading)
        return s - self.chains.start_s[row], d, rel

    def to_world(self, s: Any, d: Any, heading_rel: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Inverse of :meth:`to_frame`: (x, y, heading) of frame points."""
        base, tangent = self._reference_at(s)
        d = np.asarray(d, dtype=float)
        x = base[..., 0] - tangent[..., 1] * d
        y = base[..., 1] + tangent[..., 0] * d
        return x, y, np.arctan2(tangent[..., 1], tangent[..., 0]) + np.asarray(heading_rel, dtype=float)

    def bumper_at(self, s: Any, d: Any, heading_rel: Any, half_length: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading) of the front bumper of a vehicle whose centre is at frame (s, d) [m] with heading
        ``heading_rel`` [rad] against the centre line, placed as SUMO places vehicles on a lane: the bumper's
        lateral offset from the lane's polyline is d + half·sin(heading_rel), and its heading is the polyline
        segment's plus ``heading_rel``. (Rotating a bumper by the vehicle's heading instead would move it
        across the polyline at every vertex of a curve: a phantom lateral speed of ±v·Δangle/2.)"""
        heading_rel = np.asarray(heading_rel, dtype=float)
        return self.to_world(np.asarray(s, dtype=float) + half_length * np.cos(heading_rel),
                             np.asarray(d, dtype=float) + half_length * np.sin(heading_rel), heading_rel)

    def centre_of_bumper(self, x: Any, y: Any, heading: Any, half_length: float
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Inverse of :meth:`bumper_at`: the centre's (s, d, heading_rel) of a vehicle whose front bumper is at
        (x, y) [m] with heading ``heading`` [rad]."""
        s_f, d_f, _ = self.to_frame(x, y, 0.0)
        _, tangent = self._reference_at(s_f)
        rel = wrap_angle(np.asarray(heading, dtype=float) - np.arctan2(tangent[..., 1], tangent[..., 0]))
        return s_f - half_length * np.cos(rel), d_f - half_length * np.sin(rel), rel

    def _reference_at(self, s: Any) -> tuple[np.ndarray, np.ndarray]:
        """Point [..., 2] and unit tangent [..., 2] of the frame's centre line at ``s`` (continued straight
        beyond its ends)."""
        shapes, row = self.chains.shapes, int(self.chains.chain_of[CURRENT])
        n = int(shapes.count[row])
        along = np.asarray(s, dtype=float) + self.chains.start_s[row]
        cum, pts = shapes.cumulative[row, :n], shapes.points[row, :n]
        k = np.clip(np.searchsorted(cum, along, side="right") - 1, 0, n - 2)
        seg = pts[k + 1] - pts[k]
        tangent = seg / np.maximum(np.linalg.norm(seg, axis=-1), 1e-9)[..., None]
        return pts[k] + tangent * (along - cum[k])[..., None], tangent
