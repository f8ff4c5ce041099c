"""Where the strips of two paths through a junction overlap: the s-interval along one path, for many path pairs
in one numpy pass.

Each source path is sampled every SAMPLE_SPACING_M along its centre line once; a sample lies in the other path's
strip where its offset from that path's centre line is within half that path's width plus half the source's
width across it (its cosine to the other path's direction), and its position along that path between the path's
ends, widened by half the source's width along it (the sine).
"""
from __future__ import annotations

import numpy as np

from .frenet import LaneShapes

SAMPLE_SPACING_M = 0.2  # [m] resolution of conflict-area boundaries


def strip_overlaps(paths: list[np.ndarray], widths: np.ndarray, src: np.ndarray, dst: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) [m] along path ``src[k]`` of where its strip overlaps the strip of path ``dst[k]`` (NaN where
    they do not): ``paths`` are centre lines (points [m], at least two each), ``widths`` [m] their strips'."""
    start, end = np.full(len(src), np.nan), np.full(len(src), np.nan)
    if not len(src):  # also a network without junction links (no paths)
        return start, end
    shapes = LaneShapes.from_polylines(paths)
    # The samples of every path that is a source: s along it, the point there and the path's heading.
    sources = np.unique(src)
    samples = [np.arange(0.0, float(shapes.cumulative[k, -1]) + 1e-9, SAMPLE_SPACING_M) for k in sources.tolist()]
    first = np.zeros(len(paths), dtype=int)
    count = np.zeros(len(paths), dtype=int)
    count[sources] = [len(s) for s in samples]
    first[sources] = np.concatenate([[0], np.cumsum(count[sources])[:-1]])
    s_all = np.concatenate(samples)
    x_all = np.concatenate([np.interp(s, shapes.cumulative[k, : shapes.count[k]], paths[k][:, 0])
                            for k, s in zip(sources.tolist(), samples)])
    y_all = np.concatenate([np.interp(s, shapes.cumulative[k, : shapes.count[k]], paths[k][:, 1])
                            for k, s in zip(sources.tolist(), samples)])
    heading_all = shapes.heading_at(np.repeat(sources, count[sources]), s_all)
    # Every pair's samples: those of its source, projected onto its other path.
    n = count[src]
    pair = np.repeat(np.arange(len(src)), n)
    at = np.repeat(first[src] - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(int(n.sum()))
    s, other = s_all[at], dst[pair]
    s_dst, d_dst, heading_dst = shapes.project(other, x_all[at], y_all[at])
    # The source's cross-section reaches half its width across the other path (cos) and along it (sin): a path
    # running just past the other's end, nearly along its end line, overlaps the strip its centre line misses.
    cos, sin = np.abs(np.cos(heading_all[at] - heading_dst)), np.abs(np.sin(heading_all[at] - heading_dst))
    half = widths[src[pair]] / 2.0
    inside = (np.abs(d_dst) < widths[other] / 2.0 + half * cos) & (s_dst >= -half * sin) & \
        (s_dst <= shapes.cumulative[other, -1] + half * sin)
    found = np.zeros(len(src), dtype=bool)
    found[pair[inside]] = True
    bounds = np.concatenate([[0], np.cumsum(n)[:-1]])
    has = found & (n > 0)
    start[has] = np.minimum.reduceat(np.where(inside, s, np.inf), bounds)[has]
    end[has] = np.maximum.reduceat(np.where(inside, s, -np.inf), bounds)[has]
    return start, end
