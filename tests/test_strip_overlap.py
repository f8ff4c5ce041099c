"""Where two paths' strips overlap (road/strip_overlap.py), hand-worked."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.road.strip_overlap import SAMPLE_SPACING_M, strip_overlaps


def test_a_path_running_past_the_other_ones_end_overlaps_its_strip():
    """A runs east from (0, 0) to (10, 0); B runs north along x = 10.5, 0.5 m past A's end; B 3.2 m wide. A's
    samples within 1.6 m of B's centre line: s in (8.9, 10]. B's centre line misses A's strip (it runs beyond A's
    end), but B's strip reaches 1.6 m back along A, over A's end: B's samples within A's half width (A 3.0 m wide)
    of A's centre line, |y| < 1.5, s = y + 5 in (3.5, 6.5). (Before, B's interval was empty and the pair had no
    conflict area: MoST's 25847:2x11.)"""
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[10.5, -5.0], [10.5, 5.0]])
    start, end = strip_overlaps([a, b], np.array([3.0, 3.2]), np.array([0, 1]), np.array([1, 0]))
    assert SAMPLE_SPACING_M == 0.2
    assert (start[0], end[0]) == pytest.approx((9.0, 10.0), abs=1e-9)  # the samples every 0.2 m inside
    assert (start[1], end[1]) == pytest.approx((3.6, 6.4), abs=1e-9)


def test_paths_apart_by_more_than_their_half_widths_do_not_overlap():
    """B 3.3 m past A's end (more than the 1.6 m + 1.6 m its strip and A's reach): no overlap either way."""
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[13.3, -5.0], [13.3, 5.0]])
    start, _ = strip_overlaps([a, b], np.array([3.2, 3.2]), np.array([0, 1]), np.array([1, 0]))
    assert np.isnan(start).all()
