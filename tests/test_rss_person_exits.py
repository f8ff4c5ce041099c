"""A car leaving a junction whose rear is still over a crossing stays paired with the persons on it
(rss/junction_exits.py for crossings; docs/rss.md, "Leaving cars"). A hand-made FCD on the zebra of
tests/data/zebra, with the helpers of tests/test_rss_persons.py."""
from __future__ import annotations

import pytest

from test_rss_persons import DT, _audit, _car, _person, _write_fcd, zebra_net  # noqa: F401 (zebra_net: a fixture)


def test_a_person_walking_onto_a_zebra_a_car_is_still_over_is_the_rear_party(zebra_net, tmp_path):
    """Car c (5 m) leaves the junction eastbound at 1 m/s, its front 0.5 + t m onto MB_1 (x = 1.5 + that): along its
    link (AM_1 -> MB_1, 3 m; the crossing area is [0.2, 2.8] m of it) its front is at 3.5 + t, its rear at t - 1.5,
    in the area until 4.3 s; d_enter -3.3 - t. Person p walks north at 1.2 m/s along the crossing's line (x = 0),
    4 m before the crossing at 0 s; the car lane is [0.2, 3.0] m along the crossing, so its d_enter is 4.2 - 1.2 t.
    The person has priority at the zebra but the car is in the area: c is in front of p on the virtual line, and the
    person behind must stay D(1.2) = 0.6 + 0.25 + 2.2²/4 = 2.06 m (ρ 0.5 s, a_acc 2, b_min 2 m/s²) behind c's rear
    and short of the area: gap = min(4.2 - 1.2 t - (-3.3 - t) - 5, 4.2 - 1.2 t), the second from 1.7 s: safe at
    1.7 s (2.16 m), dangerous at 1.8 s (2.04 m). The person, the rear party, owes braking from t_b + ρ = 2.3 s and
    walks on: responsible.
    Before, the car was no entry once its front left its link, and the pair had no situation."""
    steps = []
    for k in range(51):
        t = k * DT
        pos = 0.5 + 1.0 * t
        y = -3.2 - 4.0 + 1.2 * t
        steps.append((t, [_car("c", 1.5 + pos, -1.6, "MB_1", pos, 1.0),
                          _person("p", 0.0, y, 0.0, 1.2, ":M_c0" if y >= -3.2 else ":M_w1")]))
    result = _audit(_write_fcd(tmp_path / "fcd.xml", steps), zebra_net)
    (e,) = result.episodes.itertuples()
    assert (e.vehicle_a, e.vehicle_b, e.situation, e.trigger, e.owed_a, e.owed_b, e.responsible) == \
        ("c", "p", "intersection-yield", "in-front", "", "int:brake-min", "b")
    assert e.t_b_s == pytest.approx(1.8)
    (v,) = result.violations.itertuples()
    assert (v.vehicle_id, v.constraint, v.bound) == ("p", "lon-brake-after-response-time", -2.0)
    assert 2.3 <= v.t_start_s <= 2.4 + 1e-9
