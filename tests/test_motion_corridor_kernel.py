"""The corridor's compiled cell loops (sumo_rss.planner.motion.corridor_kernel) on small grids worked by hand."""
from __future__ import annotations

import numpy as np

from sumo_rss.planner.motion.corridor_kernel import cube_chain, rasterise

TIMES = np.array([0.0, 0.2, 0.4])  # [s]
# s_back [m], s_res [m], reach_accel, reach_brake [m/s²], reach_time [s], min_back_cells, step_cells, min_slices
REACH = (2.0, 1.0, 3.0, 6.0, 1.0, 0, 5, 2)


def _ints(rows):
    return np.array(rows, dtype=np.int64)


def test_boxes_are_rasterised_inclusive_and_clipped_to_the_grid():
    # Slice 0: box s 1..2 x d 0..1, and a box s 5..8 x d -3..0 that the 6 x 4 grid clips to s 5 x d 0.
    # Slice 1: an empty box (s_lo > s_hi) and one box the grid's d range does not reach.
    s_lo, s_hi = _ints([[1, 5], [3, 0]]), _ints([[2, 8], [2, 5]])
    d_lo, d_hi = _ints([[0, -3], [0, 4]]), _ints([[1, 0], [3, 6]])
    grid = rasterise(s_lo, s_hi, d_lo, d_hi, 6, 4)
    expected = np.zeros((2, 6, 4), dtype=bool)
    expected[0, 1:3, 0:2] = True
    expected[0, 5, 0] = True
    assert grid.shape == (2, 6, 4) and np.array_equal(grid, expected)


def test_a_cube_grows_five_cells_a_round_within_the_kinematic_reach_and_stops_at_occupied_cells():
    # Seeds at s cell 2, d cell 2, slices 0 and 1; at v0 = 10 m/s the s reach (t = 0.4 s) is
    # 2 + 10·0.4 + ½·3·0.4² + 10·1 = 16.24 m ahead (cell 16) and 2 + 4 − ½·6·0.16 − 10 = −4.48 behind (cell 0).
    occupied = np.zeros((3, 30, 5), dtype=bool)
    occupied[1, 2, 4] = True  # the +d growth stops at d cell 3
    occupied[0, 9, 2] = True  # the last +s pass stops at s cell 8
    cells, a, b = cube_chain(occupied, _ints([2, 2]), _ints([2, 2]), _ints([0, 1]), TIMES, 10.0, *REACH)
    # Round 1: +s 5 free rows (to 7, goes on), −s 2 rows (to 0, the reach), +d 1 column (3), −d 2 columns (0).
    # Then +s to the reach's cell 16 stops before row 9; the cube ends at the last seed's slice.
    assert (a, b) == (-1, -1)
    assert cells.tolist() == [[0, 8, 0, 3, 0, 1]]


def test_an_occupied_seed_box_is_reported_with_its_seeds():
    occupied = np.zeros((3, 30, 5), dtype=bool)
    occupied[1, 3, 2] = True  # inside the box of seeds 0 (s 2) and 1 (s 4)
    cells, a, b = cube_chain(occupied, _ints([2, 4]), _ints([2, 2]), _ints([0, 1]), TIMES, 10.0, *REACH)
    assert (a, b) == (0, 1) and cells.shape == (0, 6)
