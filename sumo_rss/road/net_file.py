"""A fast reader of SUMO .net.xml files: edges, lanes, junctions, connections and signal programs.

One expat pass with a handler per element kind, into light objects (``__slots__``). Their accessors are named
as those of ``sumolib.net`` (``getLanes``, ``getOutgoing``, ``getViaLaneID``, ...), which the road model was
written against, and return what ``sumolib.net.readNet(path, withInternal=True, withPrograms=True)`` returns
for them (tests/test_net_file.py compares both on real networks): the same edges (normal, internal, crossing
and walking-area ones; macro connectors left out), lanes, connections in file order and link indices. Reading
MoST's 18,732-edge Monaco takes a fifth of sumolib's time (and one pass serves the road model, the junction
model and the signal programs).
"""
from __future__ import annotations

import gzip
from dataclasses import dataclass
from pathlib import Path
from xml.parsers import expat

from sumolib.net.lane import get_allowed

SUMO_LANE_WIDTH = 3.2  # [m] a lane's width where the network does not give one (SUMO's and sumolib's default)
LOADED_FUNCTIONS = frozenset(("", "internal", "crossing", "walkingarea"))  # the edges read ('connector' is not)
_PEDESTRIAN_ONLY = ("walkingarea", "crossing")


class NetNode:
    """A junction (or a node only named by edges)."""

    __slots__ = ("_id", "_type", "_inc_lanes", "_incoming", "_foes", "_prohibits", "_link_index")

    def __init__(self, node_id: str):
        self._id = node_id
        self._type: str | None = None
        self._inc_lanes: list[str] = []
        self._incoming: list[NetEdge] = []
        self._foes: dict[int, str] = {}  # request index → foes bit string (as SUMO writes it, last link first)
        self._prohibits: dict[int, str] = {}  # request index → response bit string
        self._link_index: dict[int, int] | None = None  # id(connection) → junction link index, built on first ask

    def getID(self) -> str:
        return self._id

    def getType(self) -> str | None:
        return self._type

    def getIncoming(self) -> list[NetEdge]:
        """The edges that end here (internal, crossing and walking-area ones included), in file order."""
        return self._incoming

    def link_index(self, connection: NetConnection) -> int:
        """SUMO's index of ``connection`` among the junction's links (the bit of its ``<request>``), -1 if it is
        none: the connections of the junction's incoming lanes (``incLanes``) in order, leaving out those into a
        walking area and those out of one other than onto a crossing."""
        if self._link_index is None:
            self._link_index = {}
            edges = {e.getID(): e for e in reversed(self._incoming)}  # the first of an id, as listed
            for lane_id in self._inc_lanes:
                cut = lane_id.rfind("_")
                if cut <= 0:
                    continue
                for candidate in edges[lane_id[:cut]].getLane(int(lane_id[cut + 1:])).getOutgoing():
                    to_function = candidate._to_lane._edge._function
                    from_function = candidate._from_lane._edge._function
                    if to_function == "walkingarea" or (from_function == "walkingarea" and to_function != "crossing"):
                        continue
                    self._link_index[id(candidate)] = len(self._link_index)
        return self._link_index.get(id(connection), -1)


class NetEdge:
    __slots__ = ("_id", "_function", "_from", "_to", "_lanes")

    def __init__(self, edge_id: str, function: str, from_node: NetNode, to_node: NetNode):
        self._id, self._function, self._from, self._to = edge_id, function, from_node, to_node
        self._lanes: list[NetLane] = []

    def getID(self) -> str:
        return self._id

    def getFunction(self) -> str:
        """'' for a normal edge, else 'internal', 'crossing' or 'walkingarea'."""
        return self._function

    def getFromNode(self) -> NetNode:
        return self._from

    def getToNode(self) -> NetNode:
        return self._to

    def getLanes(self) -> list[NetLane]:
        return self._lanes

    def getLane(self, index: int) -> NetLane:
        return self._lanes[index]


class NetLane:
    __slots__ = ("_edge", "_index", "_id", "_speed", "_length", "_width", "_shape", "_outgoing", "_allow", "_disallow")

    def __init__(self, edge: NetEdge, speed: float, length: float, width: float, shape: str,
                 allow: str | None = None, disallow: str | None = None):
        self._edge, self._index = edge, len(edge._lanes)
        self._id = f"{edge._id}_{self._index}"
        self._speed, self._length, self._width, self._shape = speed, length, width, shape
        self._allow, self._disallow = allow, disallow
        self._outgoing: list[NetConnection] = []
        edge._lanes.append(self)

    def getID(self) -> str:
        return self._id

    def getIndex(self) -> int:
        return self._index

    def getEdge(self) -> NetEdge:
        return self._edge

    def getSpeed(self) -> float:
        return self._speed  # [m/s]

    def getLength(self) -> float:
        return self._length  # [m]

    def getWidth(self) -> float:
        return self._width  # [m]

    def getShape(self) -> list[tuple[float, float]]:
        """The centre line's points (x, y) [m] (a z coordinate is dropped)."""
        return [(x, y) for x, y, _ in self.getShape3D()]

    def getShape3D(self) -> list[tuple[float, float, float]]:
        """The centre line's points (x, y, z) [m] (z = 0 where the network gives none)."""
        points = []
        for point in self._shape.split():
            xyz = point.split(",")
            if len(xyz) not in (2, 3):
                raise ValueError(f"lane {self._id}: invalid shape point {point!r}, expected x,y or x,y,z")
            points.append((float(xyz[0]), float(xyz[1]), float(xyz[2]) if len(xyz) == 3 else 0.0))
        return points

    def getPermissions(self) -> set[str]:
        """The vehicle classes the lane permits (its ``allow`` / ``disallow``, as sumolib reads them)."""
        return get_allowed(self._allow, self._disallow)

    def getOutgoing(self) -> list[NetConnection]:
        """The connections that leave this lane, in file order."""
        return self._outgoing


class NetConnection:
    __slots__ = ("_from_lane", "_to_lane", "_direction", "_tls", "_tl_link", "_via")

    def __init__(self, from_lane: NetLane, to_lane: NetLane, direction: str, tls: str, tl_link: int, via: str):
        self._from_lane, self._to_lane, self._direction = from_lane, to_lane, direction
        self._tls, self._tl_link, self._via = tls, tl_link, via
        from_lane._outgoing.append(self)

    def getFromLane(self) -> NetLane:
        return self._from_lane

    def getToLane(self) -> NetLane:
        return self._to_lane

    def getViaLaneID(self) -> str:
        """The first internal lane of the connection ('' for none)."""
        return self._via

    def getDirection(self) -> str:
        return self._direction

    def getTLSID(self) -> str:
        return self._tls

    def getTLLinkIndex(self) -> int:
        return self._tl_link

    def getJunctionIndex(self) -> int:
        return self._from_lane._edge._to.link_index(self)


class NetPhase:
    __slots__ = ("duration", "state")

    def __init__(self, duration: float, state: str):
        self.duration, self.state = duration, state  # [s], one character per link


class NetProgram:
    __slots__ = ("_type", "_offset", "_phases")

    def __init__(self, program_type: str, offset: float):
        self._type, self._offset = program_type, offset  # [s]
        self._phases: list[NetPhase] = []

    def getType(self) -> str:
        return self._type

    def getOffset(self) -> float:
        return self._offset

    def getPhases(self) -> list[NetPhase]:
        return self._phases


class NetSignal:
    __slots__ = ("_id", "_programs")

    def __init__(self, signal_id: str):
        self._id = signal_id
        self._programs: dict[str, NetProgram] = {}

    def getID(self) -> str:
        return self._id

    def getPrograms(self) -> dict[str, NetProgram]:
        return self._programs


class NetFile:
    """The contents of one .net.xml."""

    def __init__(self, path: Path):
        self.path = path
        self._edges: list[NetEdge] = []
        self._edge_by_id: dict[str, NetEdge] = {}
        self._nodes: dict[str, NetNode] = {}
        self._signals: dict[str, NetSignal] = {}

    def getEdges(self, withInternal: bool = True) -> list[NetEdge]:  # noqa: N803 (sumolib's name)
        return self._edges if withInternal else [e for e in self._edges if e._function == ""]

    def getEdge(self, edge_id: str) -> NetEdge:
        return self._edge_by_id[edge_id]

    def getNodes(self) -> list[NetNode]:
        return list(self._nodes.values())

    def getTrafficLights(self) -> list[NetSignal]:
        """The signals named by a vehicle connection or a ``<tlLogic>``, in the order first named."""
        return list(self._signals.values())

    def _node(self, node_id: str) -> NetNode:
        node = self._nodes.get(node_id)
        if node is None:
            node = self._nodes[node_id] = NetNode(node_id)
        return node

    def _signal(self, signal_id: str) -> NetSignal:
        signal = self._signals.get(signal_id)
        if signal is None:
            signal = self._signals[signal_id] = NetSignal(signal_id)
        return signal


def read_net(path: str | Path) -> NetFile:
    """Read a SUMO network (``.net.xml``, or gzipped). Raises ``ValueError`` naming the file for a file that is
    not a readable network."""
    path = Path(path)
    net = _NetHandler(NetFile(path))
    parser = expat.ParserCreate()
    parser.StartElementHandler = net.start
    parser.EndElementHandler = net.end
    try:
        with (gzip.open(path, "rb") if _is_gzip(path) else open(path, "rb")) as source:
            parser.ParseFile(source)
    except (expat.ExpatError, EOFError, gzip.BadGzipFile) as exc:
        raise ValueError(f"{path}: not a SUMO network ({exc})") from exc
    except (KeyError, IndexError, ValueError) as exc:
        raise ValueError(f"{path}: not a consistent SUMO network (near line {parser.CurrentLineNumber}: "
                         f"{type(exc).__name__} {exc})") from exc
    if net.root != "net":
        raise ValueError(f"{path}: expected a SUMO network (root element <net>), found "
                         f"{'no element' if net.root is None else f'<{net.root}>'}")
    return net.net


def _is_gzip(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(2) == b"\x1f\x8b"


class _NetHandler:
    """expat callbacks building a NetFile."""

    def __init__(self, net: NetFile):
        self.net = net
        self.root: str | None = None
        self._edge: NetEdge | None = None
        self._node: NetNode | None = None
        self._program: NetProgram | None = None
        self._skipped: set[str] = set()  # ids of edges not read (macro connectors): their connections are not either

    def start(self, name: str, attrs: dict[str, str]) -> None:
        if self.root is None:
            self.root = name
        if name == "lane":
            if self._edge is not None:
                NetLane(self._edge, float(attrs["speed"]), float(attrs["length"]),
                        float(attrs.get("width", SUMO_LANE_WIDTH)), attrs.get("shape", ""), attrs.get("allow"),
                        attrs.get("disallow"))
        elif name == "connection":
            self._connection(attrs)
        elif name == "edge":
            self._start_edge(attrs)
        elif name == "request":
            if self._node is not None:
                index = int(attrs["index"])
                self._node._foes[index] = attrs["foes"]
                self._node._prohibits[index] = attrs["response"]
        elif name == "junction":
            if attrs["id"][0] != ":":  # internal junctions are not nodes
                self._node = self.net._node(attrs["id"])
                self._node._type = attrs["type"]
                self._node._inc_lanes = attrs["incLanes"].split(" ")
        elif name == "tlLogic":
            self._program = NetProgram(attrs["type"], float(attrs["offset"]))
            self.net._signal(attrs["id"])._programs[attrs["programID"]] = self._program
        elif name == "phase" and self._program is not None:
            self._program._phases.append(NetPhase(float(attrs["duration"]), attrs["state"]))

    def end(self, name: str) -> None:
        if name == "edge":
            self._edge = None
        elif name == "junction":
            self._node = None
        elif name == "tlLogic":
            self._program = None

    def _start_edge(self, attrs: dict[str, str]) -> None:
        function = attrs.get("function", "")
        edge_id = attrs["id"]
        if function not in LOADED_FUNCTIONS:
            self._skipped.add(edge_id)
            self._edge = None
            return
        if function:  # the nodes of an internal (crossing, walking-area) edge: its junction
            from_id = to_id = edge_id[1:edge_id.rfind("_")]
        else:
            from_id, to_id = attrs["from"], attrs["to"]
        net = self.net
        if edge_id in net._edge_by_id:
            raise ValueError(f"edge {edge_id!r} is defined twice")
        edge = NetEdge(edge_id, function, net._node(from_id), net._node(to_id))
        edge._to._incoming.append(edge)
        net._edges.append(edge)
        net._edge_by_id[edge_id] = edge
        self._edge = edge

    def _connection(self, attrs: dict[str, str]) -> None:
        from_id, to_id = attrs["from"], attrs["to"]
        if from_id in self._skipped or to_id in self._skipped:
            return
        edges = self.net._edge_by_id
        from_lane = edges[from_id]._lanes[int(attrs["fromLane"])]
        to_lane = edges[to_id]._lanes[int(attrs["toLane"])]
        tls = attrs.get("tl", "")
        if tls and not from_lane._edge._function:
            self.net._signal(tls)
        NetConnection(from_lane, to_lane, attrs["dir"], tls, int(attrs["linkIndex"]) if tls else -1,
                      attrs.get("via", ""))


@dataclass(frozen=True)
class SignalProgram:
    """One program of a signal: SUMO's type ('static', 'actuated', ...), offset [s] and phases (duration [s],
    state)."""

    type: str
    offset: float
    phases: tuple[tuple[float, str], ...]


def signal_programs(path: str | Path) -> dict[str, tuple[SignalProgram, ...]]:
    """Every signal of the network file ``path`` (in the order first named) with its programs."""
    return {signal.getID(): tuple(SignalProgram(p.getType(), p.getOffset(), tuple((ph.duration, ph.state)
                                                                                  for ph in p.getPhases()))
                                  for p in signal.getPrograms().values())
            for signal in read_net(path).getTrafficLights()}
