"""Damaged inputs found by a sweep of the command line with damaged copies of real runs' files, table-driven as
tests/test_bad_input.py (whose helpers build them): a route over an edge the network does not have (it crashed the
audit with a KeyError); persons whose values no person can have or that contradict the network or the vehicles, a
time step written twice, an empty vehicle or person id or lane, report and view CSVs cut off mid-row, an occluder
corner at 1e300 m (all read without a word). Each must end with exit code 2 and one line naming the file and the
field (docs/outputs.md, "Bad input, full disks and interruptions"). Two that are suspicious, not impossible, must
be named in a warning: a signal-state file that begins after the FCD, and an FCD of another network with the same
lane ids whose cars are on its sidewalks."""
from __future__ import annotations


import pytest

from sumo_rss.cli import main
from sumo_rss.errors import SumoRssError
from conftest import NETWORKS
from test_bad_input import (BATCH, ROUTES, TLS_FCD, TLS_NET, TLS_STATES, Case, assert_refused, audit,
                            fcd_text, handlers, report, with_signal_states, write)

__all__ = ["handlers"]  # the fixture, used by name

PERSON = {"id": "p", "x": "20.00", "y": "-12.00", "angle": "90.00", "type": "DEFAULT_PEDTYPE", "speed": "1.00",
          "pos": "20.00", "edge": "hw0"}


def with_person(**changed: str) -> str:
    """The valid FCD of test_bad_input with a person walking beside the road at 0.1 s (``changed``: its attributes
    replaced); ``twice=...``: listed twice."""
    twice = changed.pop("twice", None)
    attributes = {**PERSON, **changed}
    element = "        <person " + " ".join(f'{k}="{v}"' for k, v in attributes.items()) + "/>\n"
    text = fcd_text()
    step = text.index('<timestep time="0.10">') + len('<timestep time="0.10">\n')
    return text[:step] + element * (2 if twice else 1) + text[step:]


def with_outside_step(tag: str, after: str) -> tuple[str, int]:
    """The valid FCD of test_bad_input with a ``<tag>`` (a vehicle's attributes) on a line of its own after the
    first line that starts with ``after``, outside every time step; and that line's number."""
    lines = fcd_text().split("\n")
    at = next(k for k, line in enumerate(lines) if line.lstrip().startswith(after)) + 1
    lines.insert(at, f'    <{tag} id="c" x="1.00" y="-5.25" angle="90.00" type="car" speed="3.00" lane="hw0_1"/>')
    return "\n".join(lines), at + 1


def outside_step(tag: str, after: str) -> Case:
    """A road user outside every time step (after the line starting with ``after``): an error naming the file, the
    line and the form SUMO writes (it was skipped without a word)."""
    text, line = with_outside_step(tag, after)
    return Case(audit(text), (f"f.xml: line {line}: <{tag}> outside a <timestep>: expected every <{tag}> inside a "
                              '<timestep time="..."> element', "(SUMO writes <fcd-export><timestep"))


def cut_mid_row(name: str) -> str:
    """BATCH's CSV ``name`` cut in the middle of its last row, as a copy or a full disk leaves it."""
    text = BATCH[name]
    return text[:text.rstrip("\n").rindex(",")]


CASES: dict[str, Case] = {
    "vtypes-route-edge-not-in-the-net": Case(audit(routes=ROUTES.replace('edges="hw0 hw1 hw2"', 'edges="hw0 zz hw2"')), (
        "r.rou.xml: <route id='r'>: edges: expected edges of the network highway.net.xml, got 'zz'",)),
    "vtypes-inline-route-edge-not-in-the-net": Case(audit(routes=ROUTES.replace(
        '<vehicle id="b" type="car" route="r" depart="0"/>',
        '<vehicle id="b" type="car" depart="0"><route edges="hw0 nowhere"/></vehicle>')), (
        "r.rou.xml: <vehicle id='b'>: <route>: edges:", "got 'nowhere'")),
    "fcd-person-speed-negative": Case(audit(with_person(speed="-1")), (
        "f.xml, time step 0.1 s: person 'p': speed: expected a number in [0, 200] m/s, got '-1'",)),
    "fcd-person-x-1e15": Case(audit(with_person(x="1e15")), ("f.xml, time step 0.1 s: person 'p': x:", "1e+08",)),
    "fcd-person-angle-1e6": Case(audit(with_person(angle="1e6")), ("f.xml", "person 'p': angle:",)),
    "fcd-person-edge-not-in-the-net": Case(audit(with_person(edge="nowhere")), (
        "f.xml, time step 0.1 s: person 'p': edge: expected an edge of highway.net.xml, got 'nowhere'",)),
    "fcd-person-twice": Case(audit(with_person(twice="yes")), ("f.xml, time step 0.1 s: person 'p' is listed more "
                                                               "than once",)),
    "fcd-person-with-a-vehicles-id": Case(audit(with_person(id="b")), (
        "f.xml, time step 0.1 s: person and vehicle 'b': id: expected the ids of persons and vehicles to differ",)),
    "occluders-shape-1e300": Case(lambda folder: audit()(folder) + ["--occluders", str(write(
                                      folder, "o.poly.xml", '<additional><poly id="h" type="building" '
                                      'shape="20,20 1e300,20 40,40"/></additional>'))],
                                  ("o.poly.xml: <poly id='h'>: shape: expected three or more points",
                                   "within 1e+08 m of the origin", "1e300")),
    "fcd-vehicle-id-empty": Case(audit(fcd_text(id="")), (
        "f.xml, time step 0.1 s: vehicle '?' (vehicle 1 of the step): id: expected SUMO's vehicle id, got ''",)),
    "fcd-lane-empty": Case(audit(fcd_text(lane="")), (
        "f.xml, time step 0.1 s: vehicle 'a' (vehicle 1 of the step): lane: expected SUMO's lane id, got ''",)),
    "fcd-person-id-empty": Case(audit(with_person(id="")), (
        "f.xml, time step 0.1 s: person: id: expected SUMO's person id, got ''",)),
    "fcd-vehicle-between-time-steps": outside_step("vehicle", "</timestep>"),
    "fcd-vehicle-before-the-first-time-step": outside_step("vehicle", "<fcd-export>"),
    "fcd-person-after-the-last-time-step": outside_step("person", "</timestep>"),
    "fcd-time-step-repeated": Case(audit(fcd_text().replace('time="0.20"', 'time="0.10"')), (
        "f.xml: time step 0.1 s is repeated: time: expected a time after the step before's",)),
    "report-summary-cut-mid-row": Case(report(**{"batch_summary.csv": cut_mid_row("batch_summary.csv")}), (
        "batch_summary.csv: line 2: expected 7 cells", "got 6 and no line end: the file is cut off mid-row")),
    "report-episodes-cut-mid-row": Case(report(**{"episodes.csv": cut_mid_row("episodes.csv")}), (
        "episodes.csv: line 2: expected 25 cells", "cut off mid-row")),
    "report-ego-trace-cut-mid-row": Case(report(**{"hw/0/ego_trace.csv": cut_mid_row("hw/0/ego_trace.csv")}), (
        "ego_trace.csv: line 2: expected 8 cells", "as 'sumo-rss run' writes them", "cut off mid-row")),
}


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_a_damaged_input_is_one_line_naming_the_file_and_field_and_leaves_nothing(case, tmp_path, capfd, handlers):
    assert_refused(CASES[case], tmp_path, capfd)


def test_the_valid_person_and_routes_the_cases_damage_are_valid(tmp_path, capfd, handlers):
    """The control: the FCD with the undamaged person, and the routes, are audited."""
    assert main(audit(with_person())(tmp_path)) == 0
    assert "sumo-rss: error" not in capfd.readouterr().err


def test_a_csv_without_a_last_line_end_is_read_where_its_last_row_is_whole(tmp_path):
    """A file edited by hand may lack the last line end: its rows are all there, and it is read; one cut mid-row
    is not (the cells pandas would fill in are not the file's)."""
    from sumo_rss.files import read_csv_table

    whole = write(tmp_path, "whole.csv", "a,b,c\n1,2,3\n4,,6")
    table = read_csv_table(whole, "x", dtype=str, keep_default_na=False)
    assert table.to_dict("list") == {"a": ["1", "4"], "b": ["2", ""], "c": ["3", "6"]}
    with pytest.raises(SumoRssError, match=r"cut.csv: line 3: expected 3 cells .*got 2 and no line end"):
        read_csv_table(write(tmp_path, "cut.csv", "a,b,c\n1,2,3\n4,5"), "x")


def test_signal_states_that_begin_after_the_fcd_are_named_in_a_warning(tmp_path, capfd, handlers):
    """States of signal C from 30 s on, for an FCD at 0 s: before 30 s the signal's links have no state (audited as
    of equal priority): said in a warning naming the file, the signal and the times."""
    assert main(with_signal_states(TLS_STATES.replace('time="0.00"', 'time="20.00"'))(tmp_path)) == 0
    err = capfd.readouterr().err
    assert "t.xml: the states of signal(s) C at 20 s begin after the first time step of" in err, err
    assert "f.xml (0 s): until then the links of those signals are audited as of equal priority" in err, err
    assert main(with_signal_states(TLS_STATES)(tmp_path / "whole")) == 0
    assert "begin after the first time step" not in capfd.readouterr().err


def test_a_vehicle_on_a_sidewalk_is_named_in_a_warning(tmp_path, capfd, handlers):
    """intersection_tls's FCD audited on intersection_tls_peds's net, which has the same lane ids with a sidewalk
    as lane 0 of every edge: car a on E_in_0 (2.6 m from the sidewalk's centre line, so within the positions'
    tolerance) is on a lane only pedestrians may use, which SUMO never does: said in a warning."""
    peds_net = NETWORKS / "intersection_tls_peds" / "intersection_tls_peds.net.xml"
    assert main(audit(TLS_FCD, net=peds_net, routes=None)(tmp_path)) == 0
    err = capfd.readouterr().err
    assert ("f.xml, time step 0.0 s: vehicle 'a' is on lane 'E_in_0', which only pedestrians may use in "
            "intersection_tls_peds.net.xml; is --net the network of this run?") in err, err
    assert main(audit(TLS_FCD, net=TLS_NET, routes=None)(tmp_path / "own")) == 0
    assert "only pedestrians may use" not in capfd.readouterr().err


def test_an_npz_that_is_no_zip_file_says_so(tmp_path):
    """A text file where episode_states.npz should be: numpy says it 'contains pickled (object) data' and suggests
    loading it unsafely; the error says what it is not instead."""
    from sumo_rss.rss.episode_states import EpisodeStates

    with pytest.raises(SumoRssError, match=r"episode_states.npz: not an episode-state file as sumo-rss writes it "
                                           r"\(not a .npz archive: not a zip file\)$"):
        EpisodeStates.read(write(tmp_path, "episode_states.npz", "garbage\n"))
