"""SUMO outputs that break off (SUMO killed while writing them): read and audited up to their last complete record,
with a warning; damage inside a file stays an error (test_rss_offline)."""
from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from conftest import NETWORKS, run_cli
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import ParamResolver
from sumo_rss.rss.fcd import FcdError, FcdReader, audit_fcd, read_collisions, read_vehicle_info
from sumo_rss.rss.signals import SignalStates

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
pytestmark = pytest.mark.filterwarnings("ignore:.*vType .* is not defined")  # the readers are given no route file


def _cut_points(text: str) -> dict[str, tuple[int, str]]:
    """Where to cut the FCD ``text`` (offset) and the last time step complete before it."""
    middle = text.index("<timestep", len(text) // 2)
    inside_vehicle = text.index("<vehicle", middle) + 20  # inside an attribute of a vehicle
    after_step = text.index("</timestep>", middle) + len("</timestep>\n")
    complete = re.findall(r'<timestep time="([^"]+)"', text[:after_step])
    return {"inside a vehicle": (inside_vehicle, complete[-2]), "after a time step": (after_step, complete[-1])}


@pytest.mark.parametrize("where", ["inside a vehicle", "after a time step"])
def test_a_cut_fcd_gives_the_time_steps_before_the_cut(dense_run, tmp_path, where):
    text = (dense_run / "fcd.xml").read_text()
    offset, last = _cut_points(text)[where]
    cut = tmp_path / "cut.xml"
    cut.write_text(text[:offset])
    network = RoadNetwork.from_file(HIGHWAY)
    with pytest.warns(UserWarning, match=rf"cut\.xml: the file breaks off after time step {float(last):g} s"):
        snapshots = list(FcdReader(cut, network))
    assert snapshots[-1].time == pytest.approx(float(last))
    for part, whole in zip(snapshots, FcdReader(dense_run / "fcd.xml", network)):
        assert part.time == whole.time and np.array_equal(part.ids, whole.ids) and np.array_equal(part.x, whole.x)


def test_an_fcd_cut_inside_its_first_time_step_is_an_error(dense_run, tmp_path):
    text = (dense_run / "fcd.xml").read_text()
    cut = tmp_path / "cut.xml"
    cut.write_text(text[:text.index("</timestep>")])
    with pytest.raises(FcdError, match=r"cut\.xml: malformed or truncated FCD after time step 0\.0+ s"):
        list(FcdReader(cut, RoadNetwork.from_file(HIGHWAY)))


def test_a_cut_collision_file_gives_its_complete_records(tmp_path):
    path = tmp_path / "collisions.xml"
    path.write_text('<collisions>\n    <collision time="3.10" collider="a" victim="b" type="collision"/>\n'
                    '    <collision time="4.20" collider="c" vic')
    with pytest.warns(UserWarning, match=r"collisions\.xml: the file ends before its end tag </collisions> .*its 1 "
                                         r"complete <collision> records"):
        assert [(c.time, c.collider) for c in read_collisions(path)] == [(3.1, "a")]


def test_a_collision_file_cut_in_its_header_comment_has_no_records(tmp_path):
    """SUMO writes its configuration as a comment first and the root element with the first record: a run killed
    before any collision leaves the comment unclosed, which was 'not a readable collision-output file'."""
    path = tmp_path / "collisions.xml"
    path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n\n<!-- generated on 2026-11-23 by Eclipse SUMO libsumo\n'
                    '<libsumoConfiguration>\n    <input>\n')
    with pytest.warns(UserWarning, match=r"collisions\.xml: the file ends before its root element <collisions> .*no "
                                         r"<collision> records"):
        assert read_collisions(path) == []


def test_auditing_a_killed_runs_outputs_equals_auditing_them_closed_at_the_cut(dense_run, tmp_path):
    """What `sumo-rss audit` writes for outputs cut off mid-record is what it writes for the same records with their
    end tags: every complete time step and collision is audited, and the command succeeds with a warning."""
    text = (dense_run / "fcd.xml").read_text()
    offset, last = _cut_points(text)["inside a vehicle"]
    kept = text[:text.index("</timestep>", text.index(f'<timestep time="{last}"')) + len("</timestep>\n")]
    collisions = ('<collisions>\n    <collision time="1.00" collider="main.0" victim="main.1" type="collision"/>\n')
    (tmp_path / "cut.xml").write_text(text[:offset])
    (tmp_path / "cut_collisions.xml").write_text(collisions + '    <collision time="1')
    (tmp_path / "closed.xml").write_text(kept + "</fcd-export>\n")
    (tmp_path / "closed_collisions.xml").write_text(collisions + "</collisions>\n")
    results = {}
    for name in ("cut", "closed"):
        proc = run_cli("audit", str(tmp_path / f"{name}.xml"), "--net", str(HIGHWAY), "--vtypes",
                       str(dense_run / "routes.rou.xml"), "--collisions", str(tmp_path / f"{name}_collisions.xml"),
                       "--out", str(tmp_path / name), "--quiet")
        assert proc.returncode == 0, proc.stderr
        results[name] = proc
    assert f"cut.xml: the file breaks off after time step {float(last):g} s" in results["cut"].stderr
    assert "cut_collisions.xml: the file ends before its end tag" in results["cut"].stderr
    episodes = (tmp_path / "closed" / "episodes.csv").read_text()
    assert episodes.count("\n") > 20
    for name in ("episodes.csv", "violations.csv", "collisions.csv"):
        assert (tmp_path / "cut" / name).read_text() == (tmp_path / "closed" / name).read_text(), name


def test_fcd_steps_after_a_cut_signal_state_file_are_named(tmp_path):
    """A signal-state file that breaks off (SUMO killed: its buffer reached the disk before the FCD's last one) left
    the later time steps audited with its last states without a word."""
    net = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
    states = tmp_path / "tls.xml"
    states.write_text('<tlsStates>\n' + "".join(f'    <tlsState time="{t:.2f}" id="C" programID="0" phase="0" '
                                               f'state="GGgrrrGGgrrr"/>\n' for t in (0.0, 0.1, 0.2))
                      + '    <tlsState time="0.30" id="C" progr')
    with pytest.warns(UserWarning, match=r"tls\.xml: the file ends before its end tag </tlsStates>"):
        assert SignalStates(net, states).known_until == pytest.approx(0.2)
    steps = "".join(f'<timestep time="{t:.2f}"><vehicle id="v" x="{200.0 - t:.6f}" y="4.800000" angle="270" '
                    f'speed="10" lane="E_in_0" pos="{100.0 + t:.6f}" acceleration="0" type="DEFAULT_VEHTYPE"/>'
                    "</timestep>" for t in (0.0, 0.1, 0.2, 0.3, 0.4))
    (tmp_path / "fcd.xml").write_text(f"<fcd-export>{steps}</fcd-export>")
    with pytest.warns(UserWarning, match=r"tls\.xml: the signal states break off at 0\.2 s; the time steps of "
                                         r".*fcd\.xml after it \(to 0\.4 s\) were audited with the states at 0\.2 s"):
        audit_fcd(tmp_path / "fcd.xml", RoadNetwork.from_file(net), ParamResolver(), tls_states=states)


def test_an_audit_stopped_after_a_step_equals_the_audit_of_the_file_ending_there(dense_run, tmp_path):
    """Ctrl-C on 'sumo-rss audit' (its stop request) ends the audit after the current step; what it writes is the
    audit of the same file ending at that step."""
    network = RoadNetwork.from_file(HIGHWAY)
    vehicles = read_vehicle_info(dense_run / "routes.rou.xml", HIGHWAY)
    asked = []

    def stop() -> bool:
        asked.append(True)
        return len(asked) == 250  # after the step at 24.9 s

    with pytest.warns(UserWarning, match=r"fcd\.xml: stopped after time step 24\.9 s: audited up to there"):
        stopped = audit_fcd(dense_run / "fcd.xml", network, ParamResolver(), vehicles=vehicles, stop=stop)
    text = (dense_run / "fcd.xml").read_text()
    end = text.index("</timestep>", re.search(r'<timestep time="24\.90*"', text).start()) + len("</timestep>\n")
    (tmp_path / "closed.xml").write_text(text[:end] + "</fcd-export>\n")
    closed = audit_fcd(tmp_path / "closed.xml", network, ParamResolver(), vehicles=vehicles)
    assert len(asked) == 250 and len(closed.episodes) > 20
    for name in ("episodes", "violations", "collisions"):
        pd.testing.assert_frame_equal(getattr(stopped, name), getattr(closed, name))
