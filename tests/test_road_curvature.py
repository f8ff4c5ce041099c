"""Curvature of lane polylines: exact on circles, blind to SUMO's split points and rounding."""
from __future__ import annotations

import numpy as np
import pytest

from sumo_rss.road.curvature import simplified, vertex_curvature
from sumo_rss.road.network import RoadNetwork
from sumo_rss.scenario import networks_root


def _cumulative(points: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])


def _arc(radius: float, angles: np.ndarray) -> np.ndarray:
    return np.stack([radius * np.sin(angles), radius * (1.0 - np.cos(angles))], axis=1)


def test_points_on_a_circle_read_its_curvature_whatever_their_spacing():
    angles = np.array([0.0, 0.05, 0.3, 0.35, 0.9, 1.0, 1.5])  # 3 m to 30 m apart on a 60 m radius
    points = _arc(60.0, angles)
    s, kappa = vertex_curvature(points, _cumulative(points))
    assert kappa == pytest.approx(np.full(5, 1.0 / 60.0), rel=1e-9)
    assert np.array_equal(s, _cumulative(points)[1:-1])  # at the vertices, along the polyline


def test_a_gentle_curve_sampled_every_metre_keeps_its_curvature():
    points = _arc(2000.0, np.arange(0.0, 300.0) / 2000.0)  # 300 m of a 2000 m radius, a vertex per metre
    kept = simplified(points)
    assert 5 < kept.size < 20  # a vertex every ~28 m is enough at 0.05 m
    s, kappa = vertex_curvature(points, _cumulative(points))
    assert kappa == pytest.approx(np.full(kappa.size, 1.0 / 2000.0), rel=1e-6)


def test_a_split_point_on_a_chord_rounded_to_sumo_precision_changes_nothing():
    """SUMO splits a turn into internal lanes at a point on the chord between two samples and writes 0.01 m."""
    points = _arc(12.0, np.linspace(0.0, np.pi / 2, 5))
    split = np.round(points[2] + 0.17 * (points[3] - points[2]), 2)
    with_split = np.round(np.insert(points, 3, split, axis=0), 2)
    s0, k0 = vertex_curvature(points, _cumulative(points))
    s1, k1 = vertex_curvature(with_split, _cumulative(with_split))
    assert k1.size == k0.size == 3
    assert k1 == pytest.approx(k0, rel=0.01) and k0 == pytest.approx(np.full(3, 1.0 / 12.0), rel=1e-9)


def test_a_straight_line_with_rounding_noise_does_not_bend():
    x = np.linspace(0.0, 100.0, 41)
    points = np.stack([x, np.round(0.004 * np.sin(x), 2)], axis=1)
    s, kappa = vertex_curvature(points, _cumulative(points))
    assert s.size == 0 and kappa.size == 0


def _chain_kappa(network: str, lanes: list[str]) -> float:
    net = RoadNetwork.from_file(networks_root() / network / f"{network}.net.xml")
    pts: list[np.ndarray] = []
    for k in net.lane_indices(np.array(lanes)):
        shape = net.shapes.points[k, : net.shapes.count[k]]
        pts.extend(shape if not pts else shape[1:])
    points = np.asarray(pts, dtype=float)
    return float(vertex_curvature(points, _cumulative(points))[1].max())


def test_the_same_turn_split_in_different_places_reads_the_same():
    """intersection_priority: two left turns of identical shape, one a single internal lane, the other split in
    two at a point on a chord. The heading gradient read them as 0.134 and 0.194 1/m."""
    one = _chain_kappa("intersection_priority", ["N_in_0", ":J_2_0", "J_E_0"])
    split = _chain_kappa("intersection_priority", ["E_in_0", ":J_5_0", ":J_12_0", "J_S_0"])
    assert one == pytest.approx(split, rel=1e-3)
    assert one == pytest.approx(0.151, abs=0.001)  # circle through SUMO's middle three samples of the turn
