"""Rule 4's line of sight (rss.md §9, paper §3.9): whether two road users can see each other at a step.

The sight line joins the two drivers' points (1/3 of the vehicle's length behind its front bumper, on its centre
line). It is blocked by the box of a third road user taller than ``min_height_m`` (its vType's height) or by an edge
of a static occluder polygon (a SUMO additional file's ``<poly>``, by default every one whose ``type`` starts with
"building"). Both tests are array operations over the (sight line, obstacle) candidates: third road users within
reach of the line's midpoint (a k-d tree), polygon edges in the grid cells the line's bounding box covers.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ..errors import SumoRssError, shown
from ..road.net_check import MAX_COORDINATE_M
from ..road.link_pairs import expand_ranges
from ..sim.snapshot import WorldSnapshot

DRIVER_SHARE = 1.0 / 3.0  # the driver sits this share of the vehicle's length behind its front bumper
OCCLUDER_TYPE_PREFIX = "building"  # polygons taken as occluders by default (their ``type`` starts with it)
GRID_CELL_M = 20.0  # [m] side of the grid cells that index the occluder polygons' edges


@dataclass(frozen=True)
class OcclusionParams:
    """Rule 4's settings (rss.md §9; the ``[rss]`` key of each is named in its comment; docs/rss.md "Rule 4")."""

    enabled: bool = False  # (occlusion) rule 4 on; also on with occluder files; off by default (docs/rss.md)
    min_height_m: float = 1.6  # [m] road users taller than this block the sight line (occluder_min_height_m)
    speed_factor: float = 1.1  # a hidden car may drive at up to this times its lane's limit (occluded_speed_factor)
    yield_speed_ms: float = 8.3  # [m/s] the lower-priority hidden car near a conflict area (occluded_yield_speed_ms)
    yield_zone_m: float = 30.0  # [m] ... within this of the area (occluded_yield_zone_m)
    lat_speed_ms: float = 1.0  # [m/s] a hidden car's mean lateral speed (occluded_lat_speed_ms)
    occluders: tuple[Path, ...] = ()  # (occluders) SUMO additional files with <poly> occluders


@dataclass(frozen=True, eq=False)
class OccluderEdges:
    """The edges of static occluder polygons [m], indexed by a uniform grid: ``cell_keys`` (sorted) names a cell
    for each entry of ``edge_of`` (an edge whose bounding box touches that cell)."""

    x0: np.ndarray
    y0: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    origin: tuple[float, float]  # [m] the grid's lower-left corner
    shape: tuple[int, int]  # cells along x and y
    cell_keys: np.ndarray  # int64, sorted
    edge_of: np.ndarray  # int64, an edge index per entry of cell_keys
    count: int  # polygons

    @classmethod
    def from_polygons(cls, polygons: Sequence[np.ndarray], cell: float = GRID_CELL_M) -> OccluderEdges:
        """Index closed polygons (each an [k, 2] array of corners [m], the last joined back to the first)."""
        rings = [np.asarray(p, dtype=float) for p in polygons if len(p) >= 2]
        if not rings:
            empty = np.zeros(0)
            return cls(empty, empty, empty, empty, (0.0, 0.0), (0, 0), np.zeros(0, np.int64), np.zeros(0, np.int64),
                       0)
        start = np.concatenate(rings)
        end = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
        keep = np.any(start != end, axis=1)
        start, end = start[keep], end[keep]
        origin = (float(min(start[:, 0].min(), end[:, 0].min())), float(min(start[:, 1].min(), end[:, 1].min())))
        lo = np.floor((np.minimum(start, end) - origin) / cell).astype(np.int64)
        hi = np.floor((np.maximum(start, end) - origin) / cell).astype(np.int64)
        shape = (int(hi[:, 0].max()) + 1, int(hi[:, 1].max()) + 1)
        edge, ix, iy = _cells(lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1])
        keys = ix * shape[1] + iy
        order = np.argsort(keys, kind="stable")
        return cls(start[:, 0], start[:, 1], end[:, 0], end[:, 1], origin, shape, keys[order], edge[order],
                   len(rings))

    def __len__(self) -> int:
        return int(self.x0.shape[0])

    def crossed(self, ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray,
                cell: float = GRID_CELL_M) -> np.ndarray:
        """Per segment (a → b) [m]: it crosses an edge of an occluder polygon."""
        out = np.zeros(len(ax), dtype=bool)
        if not len(ax) or not len(self):
            return out
        nx, ny = self.shape
        lo_x = np.floor((np.minimum(ax, bx) - self.origin[0]) / cell).astype(np.int64)
        hi_x = np.floor((np.maximum(ax, bx) - self.origin[0]) / cell).astype(np.int64)
        lo_y = np.floor((np.minimum(ay, by) - self.origin[1]) / cell).astype(np.int64)
        hi_y = np.floor((np.maximum(ay, by) - self.origin[1]) / cell).astype(np.int64)
        inside = (hi_x >= 0) & (lo_x < nx) & (hi_y >= 0) & (lo_y < ny)
        rows = np.flatnonzero(inside)
        seg, ix, iy = _cells(np.clip(lo_x[rows], 0, nx - 1), np.clip(hi_x[rows], 0, nx - 1),
                             np.clip(lo_y[rows], 0, ny - 1), np.clip(hi_y[rows], 0, ny - 1))
        seg = rows[seg]
        keys = ix * ny + iy
        first = np.searchsorted(self.cell_keys, keys, side="left")
        last = np.searchsorted(self.cell_keys, keys, side="right")
        owner, entry = expand_ranges(first, last)
        seg = seg[owner]
        edge = self.edge_of[entry]
        hit = _segments_cross(ax[seg], ay[seg], bx[seg], by[seg], self.x0[edge], self.y0[edge], self.x1[edge],
                              self.y1[edge])
        out[seg[hit]] = True
        return out


def _cells(lo_x: np.ndarray, hi_x: np.ndarray, lo_y: np.ndarray, hi_y: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row, ix, iy): every grid cell of each row's cell range [lo, hi] on both axes."""
    span_y = hi_y - lo_y + 1
    count = (hi_x - lo_x + 1) * span_y
    row, local = expand_ranges(np.zeros_like(count), count)
    return row, lo_x[row] + local // span_y[row], lo_y[row] + local % span_y[row]


def _segments_cross(ax, ay, bx, by, cx, cy, dx, dy) -> np.ndarray:
    """Segments a–b and c–d cross (each one's ends strictly on both sides of the other's line)."""
    d1 = (dx - cx) * (ay - cy) - (dy - cy) * (ax - cx)
    d2 = (dx - cx) * (by - cy) - (dy - cy) * (bx - cx)
    d3 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    d4 = (bx - ax) * (dy - ay) - (by - ay) * (dx - ax)
    return (d1 * d2 < 0.0) & (d3 * d4 < 0.0)


def segment_hits_box(ax, ay, bx, by, cx, cy, heading, half_length, half_width) -> np.ndarray:
    """Segment a–b [m] meets the box of centre (cx, cy), ``heading`` [rad] and half sizes [m] (slab clipping in the
    box's frame)."""
    cos, sin = np.cos(heading), np.sin(heading)
    ux, uy = (ax - cx) * cos + (ay - cy) * sin, -(ax - cx) * sin + (ay - cy) * cos
    vx, vy = (bx - cx) * cos + (by - cy) * sin, -(bx - cx) * sin + (by - cy) * cos
    t_in, t_out = np.zeros(np.shape(ux)), np.ones(np.shape(ux))
    for p, d, half in ((ux, vx - ux, half_length), (uy, vy - uy, half_width)):
        flat = d == 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (-half - p) / d, (half - p) / d
        enter = np.where(flat, np.where(np.abs(p) <= half, -np.inf, np.inf), np.minimum(t0, t1))
        leave = np.where(flat, np.where(np.abs(p) <= half, np.inf, -np.inf), np.maximum(t0, t1))
        t_in, t_out = np.maximum(t_in, enter), np.minimum(t_out, leave)
    return t_in <= t_out


def driver_points(snapshot: WorldSnapshot) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) [m] of every road user's driver: 1/3 of its length behind the front bumper, on its centre line."""
    back = DRIVER_SHARE * snapshot.length
    return snapshot.x - back * np.cos(snapshot.heading), snapshot.y - back * np.sin(snapshot.heading)


def line_of_sight(snapshot: WorldSnapshot, a: np.ndarray, b: np.ndarray, heights: np.ndarray, min_height: float,
                  occluders: OccluderEdges | None) -> np.ndarray:
    """Per pair (snapshot rows ``a``, ``b``): the two drivers see each other (``heights`` [m] per snapshot row)."""
    px, py = driver_points(snapshot)
    ax, ay, bx, by = px[a], py[a], px[b], py[b]
    blocked = occluders.crossed(ax, ay, bx, by) if occluders is not None else np.zeros(len(a), dtype=bool)
    tall = np.flatnonzero(heights > min_height)
    if len(tall) and len(a):
        cx, cy = snapshot.centres()
        half_l, half_w = 0.5 * snapshot.length[tall], 0.5 * snapshot.width[tall]
        radius = np.hypot(half_l, half_w)  # [m] a box's circumradius
        reach = 0.5 * np.hypot(bx - ax, by - ay) + float(radius.max())
        # Trees built without balancing: faster to build, the same neighbours (in another order).
        near = cKDTree(np.column_stack([0.5 * (ax + bx), 0.5 * (ay + by)]), balanced_tree=False,
                       compact_nodes=False).sparse_distance_matrix(
            cKDTree(np.column_stack([cx[tall], cy[tall]]), balanced_tree=False, compact_nodes=False),
            float(reach.max()), output_type="ndarray")
        pair, k = near["i"].astype(np.int64), near["j"].astype(np.int64)
        other = tall[k]
        third = (near["v"] <= reach[pair]) & (other != a[pair]) & (other != b[pair])
        pair, k, other = pair[third], k[third], other[third]
        # A segment that meets a box comes within its circumradius of its centre: the cheap test first.
        dx, dy = bx[pair] - ax[pair], by[pair] - ay[pair]
        qx, qy = cx[other] - ax[pair], cy[other] - ay[pair]
        s = np.clip((qx * dx + qy * dy) / np.maximum(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
        close = np.hypot(qx - s * dx, qy - s * dy) <= radius[k] + 1e-9
        pair, k, other = pair[close], k[close], other[close]
        hit = segment_hits_box(ax[pair], ay[pair], bx[pair], by[pair], cx[other], cy[other],
                               snapshot.heading[other], half_l[k], half_w[k])
        blocked[pair[hit]] = True
    return ~blocked


def vtype_heights(snapshot: WorldSnapshot, heights: Mapping[str, float]) -> np.ndarray:
    """[m] per snapshot row: its vType's height (0 where unknown: not an occluder)."""
    types, inverse = np.unique(snapshot.vtype.astype(str), return_inverse=True)
    return np.array([heights.get(t, 0.0) for t in types.tolist()], dtype=float)[inverse]


def read_occluders(paths: Sequence[Path], type_prefix: str = OCCLUDER_TYPE_PREFIX) -> OccluderEdges:
    """The ``<poly>`` elements of SUMO additional files ``paths`` whose ``type`` starts with ``type_prefix``, in
    network coordinates; SumoRssError naming the file, polygon and attribute where one cannot be read."""
    polygons = []
    for path in paths:
        path = Path(path)
        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            raise SumoRssError(f"{path}: not a readable SUMO additional file with <poly> occluders ({exc})") from exc
        if root.tag != "additional":
            raise SumoRssError(f"{path}: not a SUMO additional file (root element <{root.tag}>, expected "
                               "<additional>)")
        for poly in root.iter("poly"):
            if not poly.get("type", "").startswith(type_prefix):
                continue
            where = f"{path}: <poly id={poly.get('id', '?')!r}>"
            if poly.get("geo", "false").lower() in ("1", "true"):
                raise SumoRssError(f"{where}: geo=\"{poly.get('geo')}\": expected network coordinates (x,y in m), "
                                   "not longitude/latitude")
            try:
                corners = np.array([[float(v) for v in point.split(",")[:2]]
                                    for point in poly.get("shape", "").split()], dtype=float)
            except ValueError:
                corners = np.zeros((0, 2))
            if corners.ndim != 2 or len(corners) < 3 or not (np.abs(corners) <= MAX_COORDINATE_M).all():
                raise SumoRssError(f"{where}: shape: expected three or more points 'x,y x,y x,y' [m] within "
                                   f"{MAX_COORDINATE_M:g} m of the origin, got {shown(poly.get('shape', ''))}")
            polygons.append(corners)
    return OccluderEdges.from_polygons(polygons)
