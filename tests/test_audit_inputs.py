"""Silent wrong inputs of an offline audit made loud (issue 46, item 8): a network with signals audited without
their states, and a lane-change warning that named SUMO's own jumps within a lane as instantaneous lane changes."""
from __future__ import annotations

import warnings

from conftest import NETWORKS, run_cli
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.fcd import FcdReader

HIGHWAY = NETWORKS / "highway" / "highway.net.xml"
TLS_NET = NETWORKS / "intersection_tls" / "intersection_tls.net.xml"
TLS_FCD = ('<fcd-export><timestep time="0.00"><vehicle id="a" x="200.00" y="4.80" angle="270.00" speed="10.00" '
           'pos="100.00" lane="E_in_0"/></timestep></fcd-export>\n')


def test_an_audit_of_a_network_with_signals_and_no_signal_states_says_so(tmp_path):
    """Without --tls-states the net's own programs stand for the signals (acosta: 392 red-light violations SUMO never
    showed): a warning before the audit, and the summary line, say so."""
    fcd = tmp_path / "f.xml"
    fcd.write_text(TLS_FCD)
    proc = run_cli("audit", str(fcd), "--net", str(TLS_NET), "--out", str(tmp_path / "out"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert f"sumo-rss: warning: {TLS_NET}: the network has 1 traffic signal(s) and no signal states were given " \
           "(--tls-states)" in proc.stderr
    assert "the states of the network's 1 signals from its own programs: no --tls-states" in proc.stdout
    states = tmp_path / "tls.xml"
    states.write_text('<tlsStates><tlsState time="0.00" id="C" programID="fixed" phase="0" state="GGgrrrGGgrrr"/>'
                      "</tlsStates>")
    proc = run_cli("audit", str(fcd), "--net", str(TLS_NET), "--tls-states", str(states), "--out",
                   str(tmp_path / "out2"), "--quiet")
    assert proc.returncode == 0 and "signal" not in proc.stderr + proc.stdout.split("->")[0], proc.stderr
    # A network without signals: nothing to say.
    highway = tmp_path / "h.xml"
    highway.write_text(TLS_FCD.replace("E_in_0", "hw0_1").replace('x="200.00" y="4.80"', 'x="100.00" y="-5.25"'))
    proc = run_cli("audit", str(highway), "--net", str(HIGHWAY), "--out", str(tmp_path / "out3"), "--quiet")
    assert proc.returncode == 0 and "signal" not in proc.stderr, proc.stderr


def _sideways(lane_after: str, lat_after: str) -> str:
    """Car a in hw0_1 on its centre line, then 0.1 s later in ``lane_after`` at posLat ``lat_after``."""
    steps = [("0.00", "hw0_1", "-5.25", "0.00"), ("0.10", lane_after, "-4.05" if lane_after == "hw0_1" else "-1.75",
                                                 lat_after)]
    return "<fcd-export>" + "".join(
        f'<timestep time="{t}"><vehicle id="a" x="{100 + 0.3 * k:.2f}" y="{y}" angle="90.00" speed="3.00" '
        f'pos="{100 + 0.3 * k:.2f}" lane="{lane}" posLat="{lat}"/></timestep>'
        for k, (t, lane, y, lat) in enumerate(steps)) + "</fcd-export>\n"


def test_only_a_lane_change_done_in_one_step_is_named_an_instantaneous_lane_change(tmp_path):
    """SUMO moves a car sideways within its lane at times (MoST car207 at 234.1 s: 1.2 m on a one-lane edge, in a
    run with --lanechange.duration 3): that is no instantaneous lane change, and the warning saying that the run was
    made without --lanechange.duration was wrong. A change to the next lane in one step still is one."""
    network = RoadNetwork.from_file(HIGHWAY)
    within = tmp_path / "within.xml"
    within.write_text(_sideways("hw0_1", "1.20"))
    with warnings.catch_warnings():
        warnings.filterwarnings("error", ".*sideways")
        assert len(list(FcdReader(within, network))) == 2
    across = tmp_path / "across.xml"
    across.write_text(_sideways("hw0_2", "0.00"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        list(FcdReader(across, network))
    assert [str(w.message) for w in caught if "sideways" in str(w.message)][0].startswith(
        f"{across}: a moves 3.50 m sideways onto another lane in one 0.1 s step at 0.1 s")
