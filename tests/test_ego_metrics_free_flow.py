"""Free flow as issue 48 checks it (`report.ego_metrics.free_flow_shortfalls`), on hand-made FCDs of the shipped
highway network: a slower car beyond 150 m but within RSS reach is a leader, one beyond it is not; a car in the
next lane signalling towards the ego's lane is one, the same car not signalling is not.

Hand-worked numbers (ad_rss parameters: ρ = 1 s, a_acc = 3.5, b_min = 4, b_max = 8 m/s²): ego at 33 m/s behind a
car at 27 m/s: v_ρ = 36.5 m/s, D = 33 + 1.75 + 36.5²/8 = 201.28 m, d_min = 201.28 − 27²/16 = 155.72 m, plus
(33 − 27)²/(2·1.67) = 10.78 m: a leader within 166.5 m.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from sumo_rss.batch.runner import param_resolver
from sumo_rss.report.ego_metrics import free_flow_shortfalls
from sumo_rss.scenario import EGO_TYPE, load_scenario

REPO = Path(__file__).resolve().parent.parent
EGO_SPEEDS = (32.9, 32.5, 32.2)  # [m/s] 0.99 x 33 = 32.67 reached at the first step, then lost: two shortfall steps
EGO_POS = 100.0  # [m] along hw0_0 at the first step


def _run_dir(tmp_path: Path, other: str) -> Path:
    """A run folder with the shipped highway_sparse scenario, its RSS parameters and a three-step FCD: the ego on
    hw0_0 slowing from 32.9 m/s and ``other`` (a vehicle element's attributes without id and type) beside it each
    step."""
    run = tmp_path / "run"
    run.mkdir(parents=True)
    shutil.copy(REPO / "scenarios" / "highway_sparse.toml", run / "scenario.toml")
    resolver = param_resolver(load_scenario(run / "scenario.toml"))  # rss_params.json as a run writes it
    for vclass, vtype in (("ego", EGO_TYPE), ("background", "car")):
        resolver.get(vclass, vtype)
    (run / "rss_params.json").write_text(json.dumps(resolver.resolved()), encoding="utf-8")
    steps, pos = [], EGO_POS
    for k, speed in enumerate(EGO_SPEEDS):
        steps.append(f'<timestep time="{20.0 + 0.1 * k:.2f}">'
                     f'<vehicle id="ego" x="0" y="0" angle="90" type="ego_type" speed="{speed}" pos="{pos:.2f}" '
                     f'lane="hw0_0" signals="0"/><vehicle id="main.1" type="car" {other}/></timestep>')
        pos += 0.1 * speed
    (run / "fcd.xml").write_text("<fcd-export>" + "".join(steps) + "</fcd-export>", encoding="utf-8")
    return run


def _ahead(gap: float, speed: float, lane: str = "hw0_0", signals: int = 0) -> str:
    """A car (4.5 m long) whose rear is ``gap`` m ahead of the ego's first-step front bumper (it keeps its place:
    three steps of 0.1 s move the ego by < 10 m, far less than the margins tested)."""
    return f'x="0" y="0" angle="90" speed="{speed}" pos="{EGO_POS + gap + 4.5:.2f}" lane="{lane}" signals="{signals}"'


@pytest.mark.parametrize("gap, is_leader", [(100.0, True), (160.0, True), (180.0, False)])
def test_a_slower_car_leads_within_rss_reach(tmp_path, gap, is_leader):
    shortfalls = free_flow_shortfalls(_run_dir(tmp_path, _ahead(gap, 27.0)))
    assert (shortfalls == []) == is_leader, shortfalls
    if not is_leader:
        assert [t for t, _, _ in shortfalls] == pytest.approx([20.1, 20.2])
        assert all(target == 33.0 for _, _, target in shortfalls)


def test_a_faster_car_leads_only_within_150_m(tmp_path):
    assert free_flow_shortfalls(_run_dir(tmp_path, _ahead(140.0, 35.0))) == []
    assert len(free_flow_shortfalls(_run_dir(tmp_path / "b", _ahead(160.0, 35.0)))) == 2


@pytest.mark.parametrize("signals, is_leader", [(1, True), (0, False), (2, False)])
def test_a_car_signalling_into_the_lane_leads(tmp_path, signals, is_leader):
    """A car in lane 1 (left of the ego's lane 0), 50 m ahead: signalling right (SUMO's bit 0) it cuts in."""
    shortfalls = free_flow_shortfalls(_run_dir(tmp_path, _ahead(50.0, 30.0, "hw0_1", signals)))
    assert (shortfalls == []) == is_leader, shortfalls
