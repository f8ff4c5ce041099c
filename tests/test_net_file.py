"""The fast network reader returns what sumolib.net.readNet returns, on the shipped networks and on real city
networks from the eclipse-sumo package, and names a file that is no network."""
from __future__ import annotations

import gzip

import pytest
import sumolib

from conftest import NETWORKS
from sumo_rss.road.net_file import read_net, signal_programs
from sumo_rss.sumo_home import sumo_home

GAME = sumo_home() / "tools" / "game"
NETS = [NETWORKS / n / f"{n}.net.xml" for n in ("highway", "merge", "intersection_tls", "intersection_priority")] + [
    GAME / "DRT" / "osm.net.xml",  # a city: 8,109 edges with sidewalks, crossings and walking areas, 21 signals
    GAME / "bs3d" / "bs.net.xml",  # Braunschweig, 3-D shapes
    GAME / "fkk_in" / "ingolstadt.net.xml.gz",  # gzipped
]


def _connection(c) -> tuple:
    return (c.getToLane().getID(), c.getViaLaneID() or "", c.getDirection(), c.getTLSID(), c.getTLLinkIndex(),
            c.getJunctionIndex())


@pytest.mark.parametrize("path", NETS, ids=lambda p: p.parent.name)
def test_the_reader_reads_what_sumolib_reads(path):
    mine, ref = read_net(path), sumolib.net.readNet(str(path), withInternal=True)
    assert [e.getID() for e in mine.getEdges()] == [e.getID() for e in ref.getEdges(withInternal=True)]
    assert [e.getID() for e in mine.getEdges(withInternal=False)] == [e.getID() for e in ref.getEdges(withInternal=False)]
    for a, b in zip(mine.getEdges(), ref.getEdges(withInternal=True)):
        assert (a.getFunction(), a.getFromNode().getID(), a.getToNode().getID()) == \
            (b.getFunction(), b.getFromNode().getID(), b.getToNode().getID()), a.getID()
        assert [(la.getID(), la.getIndex(), la.getSpeed(), la.getLength(), la.getWidth(), la.getShape())
                for la in a.getLanes()] == \
            [(lb.getID(), lb.getIndex(), lb.getSpeed(), lb.getLength(), lb.getWidth(), lb.getShape())
             for lb in b.getLanes()], a.getID()
        assert [[_connection(c) for c in la.getOutgoing()] for la in a.getLanes()] == \
            [[_connection(c) for c in lb.getOutgoing()] for lb in b.getLanes()], a.getID()
    assert [(n.getID(), n.getType(), n._foes, n._prohibits, [e.getID() for e in n.getIncoming()])
            for n in mine.getNodes()] == \
        [(n.getID(), n.getType(), n._foes, n._prohibits, [e.getID() for e in n.getIncoming()]) for n in ref.getNodes()]


@pytest.mark.parametrize("path", NETS, ids=lambda p: p.parent.name)
def test_signal_programs_are_sumolibs(path):
    ref = sumolib.net.readNet(str(path), withPrograms=True)
    expected = {tls.getID(): [(p.getType(), float(p._offset), [(float(ph.duration), ph.state) for ph in p.getPhases()])
                              for p in tls.getPrograms().values()] for tls in ref.getTrafficLights()}
    found = {tl: [(p.type, p.offset, list(p.phases)) for p in programs] for tl, programs in signal_programs(path).items()}
    assert list(found) == list(expected) and found == expected


def test_a_file_that_is_no_network_is_named(tmp_path):
    broken = tmp_path / "broken.net.xml"
    broken.write_text('<net version="1.20"><edge id="a" from="x" to="y"><lane id="a_0"')
    with pytest.raises(ValueError, match=r"broken.net.xml: not a SUMO network \("):
        read_net(broken)
    other = tmp_path / "routes.xml"
    other.write_text("<routes/>")
    with pytest.raises(ValueError, match=r"routes.xml: expected a SUMO network \(root element <net>\), found <routes>"):
        read_net(other)
    cut = tmp_path / "cut.net.xml.gz"
    cut.write_bytes(gzip.compress((NETWORKS / "merge" / "merge.net.xml").read_bytes())[:-200])
    with pytest.raises(ValueError, match=r"cut.net.xml.gz: not a SUMO network \("):
        read_net(cut)
    dangling = tmp_path / "dangling.net.xml"
    dangling.write_text('<net><edge id="a" from="x" to="y"><lane id="a_0" index="0" speed="1" length="5" shape="0,0 5,0"/>'
                        '</edge><connection from="a" to="b" fromLane="0" toLane="0" dir="s" state="M"/></net>')
    with pytest.raises(ValueError, match="dangling.net.xml: not a consistent SUMO network"):
        read_net(dangling)
