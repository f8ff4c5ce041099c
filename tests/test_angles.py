"""The angle helpers: the fast cos/sin against numpy's, and wrapping into (-π, π]."""
import numpy as np

from sumo_rss.angles import cos_sin, wrap_angle


def test_cos_sin_matches_numpy_over_many_turns():
    angle = np.concatenate([np.linspace(-25.0, 25.0, 200_001), [np.pi, -np.pi, 0.5 * np.pi, -0.5 * np.pi, 0.0]])
    cos, sin = cos_sin(angle)
    assert np.max(np.abs(cos - np.cos(angle))) < 1e-15
    assert np.max(np.abs(sin - np.sin(angle))) < 1e-15


def test_wrap_angle_range_and_identity_inside():
    inside = np.array([0.0, 1e-12, -3.0, 3.0, np.pi])
    assert np.array_equal(wrap_angle(inside), inside)
    wrapped = wrap_angle(np.array([-np.pi, 3 * np.pi, 7.0, -7.0, 2 * np.pi]))
    assert np.allclose(wrapped, [np.pi, np.pi, 7.0 - 2 * np.pi, 2 * np.pi - 7.0, 0.0], atol=1e-12)
    assert np.all((wrapped > -np.pi) & (wrapped <= np.pi))
    assert isinstance(wrap_angle(7.0), float) and wrap_angle(-np.pi) == np.pi
