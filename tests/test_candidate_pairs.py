"""The audit's candidate pairs (rss/road_kernel.candidate_keys over a grid of cells) against every pair checked
one by one: the same set, whatever the layout (clusters, a line along either axis, one spot, far-off coordinates)."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.rss.road_kernel import candidate_keys


def brute_force(cx, cy, reach, gap, size) -> set[int]:
    n = cx.size
    i, j = np.triu_indices(n, k=1)
    bound = reach[i] + reach[j] + np.maximum(gap[i], gap[j]) + size[i] + size[j]
    near = np.hypot(cx[i] - cx[j], cy[i] - cy[j]) <= bound
    return set((i[near] * n + j[near]).tolist())


def layouts(rng: np.random.Generator):
    n = 400
    yield "clusters", rng.normal(0, 30, n) + rng.integers(0, 8, n) * 400.0, rng.normal(0, 30, n)
    yield "along x", rng.uniform(0, 5000, n), rng.uniform(0, 10, n)
    yield "along y", rng.uniform(0, 10, n), rng.uniform(-5000, 0, n)
    yield "one spot", np.full(n, 3.0), np.full(n, -7.0)
    yield "far off", rng.uniform(1e6, 1e6 + 2000, n), rng.uniform(-3e6, -3e6 + 2000, n)
    yield "two cars", np.array([0.0, 50.0]), np.array([0.0, 0.0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_candidate_keys_are_every_near_pair(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for name, cx, cy in layouts(rng):
        n = cx.size
        reach = rng.uniform(0, 60, n) * (rng.random(n) < 0.7)  # standing cars reach nothing
        gap = rng.choice([1.0, 2.0, 4.0], n)
        size = rng.uniform(0.5, 9.0, n)
        keys = candidate_keys(cx, cy, reach, gap, size)
        assert len(set(keys.tolist())) == keys.size, name  # no pair twice
        assert set(keys.tolist()) == brute_force(cx, cy, reach, gap, size), name
        assert np.all(keys // n < keys % n), name


def test_one_vehicle_has_no_pair() -> None:
    one = np.array([1.0])
    assert candidate_keys(one, one, one, one, one).size == 0
