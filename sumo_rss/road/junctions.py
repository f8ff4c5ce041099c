"""Junction model: links through each junction, their conflict areas, right of way and signal indices.

A *link* is one connection through a junction: incoming lane → internal lane(s) → outgoing lane. Two links
that SUMO marks as foes and whose lane strips overlap share a *conflict area*, given as an s-interval along
each link's internal path. Right of way comes from SUMO's junction logic (``<request response=...>``: link i
yields to link j when bit j of its response is set); at signals the current link states override it
(``G`` over ``g`` over ``y``/``r``).
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from .link_pairs import LinkBlocks, LinkPairList, LinkPairs
from .model_cache import cached
from .net_file import read_net
from .network import RoadNetwork
from .strip_overlap import strip_overlaps

SIGNAL_RANK = {"G": 2, "g": 1}  # every other state ('y', 'r', 'u', 'o', 's', ...) ranks 0
RANK_OF_BYTE = np.zeros(256, dtype=int)  # SIGNAL_RANK by the state character's (ASCII) byte
for _state, _rank in SIGNAL_RANK.items():
    RANK_OF_BYTE[ord(_state)] = _rank


@dataclass(frozen=True)
class Link:
    """One connection through a junction. Lanes are RoadNetwork lane indices."""

    junction: str
    index: int  # SUMO's link index within the junction (bit position in <request>)
    from_lane: int
    to_lane: int
    path: tuple[int, ...]  # internal lanes in driving order
    length: float  # length of the internal path [m]
    tls: str  # traffic light id, '' if unsignalised
    tls_index: int  # index into the signal's state string, -1 if unsignalised
    direction: str  # SUMO's dir: 's', 'l', 'r', 't', ...


@dataclass(frozen=True)
class ConflictArea:
    """Where the strips of two foe links overlap, as an s-interval along each link's path [m]."""

    id: str  # '<junction>:<link a>x<link b>'
    link_a: int  # indices into JunctionModel.links
    link_b: int
    a_start: float
    a_end: float
    b_start: float
    b_end: float
    kind: str  # 'merging' (both links lead into the same lane), 'diverging' (both come from the same lane) or 'crossing'
    static_priority: str  # 'a', 'b' or 'same', from SUMO's junction logic


@dataclass(frozen=True, eq=False)
class ConflictPairs:
    """Every ordered pair of links (a, b) that share a conflict area, as arrays over the pair numbers of ``pairs``
    (the per-pair values of JunctionModel's link-pair tables, gathered once)."""

    pairs: LinkPairList
    area: np.ndarray  # [K] the conflict area (index into JunctionModel.conflicts)
    start: np.ndarray  # [K] its start along a's path [m]
    end: np.ndarray  # [K] its end along a's path [m]
    static_priority: np.ndarray  # [K] +1: a has priority, -1: a yields, 0: same
    area_id: np.ndarray  # [K] the conflict area's id (str, not object: cheap to gather and to look up)


@dataclass(frozen=True, eq=False)
class JunctionModel:
    """Links and conflict areas, plus lookup arrays for vectorised per-step use (L links, n lanes; the link-pair
    tables are indexed as [L, L] arrays, stored per junction)."""

    links: tuple[Link, ...]
    conflicts: tuple[ConflictArea, ...]
    link_of_lane: dict[int, tuple[int, float]]  # internal lane → (link, offset of the lane along the link path [m])
    lane_links: np.ndarray  # [n, k] links starting at each incoming lane, -1 padded
    lane_link: np.ndarray  # [n] link of an internal lane, -1 otherwise
    lane_link_offset: np.ndarray  # [n] offset of an internal lane along its link's path [m]
    link_to_edge: np.ndarray  # [L] edge the link leads into
    link_tls: np.ndarray  # [L] signal id ('' if none)
    link_tls_index: np.ndarray  # [L] index into the signal state (-1 if none)
    area_index: LinkPairs  # [L, L] conflict area of a link pair, -1 if none
    area_start: LinkPairs  # [L, L] start of that area along the first link's path [m]
    area_end: LinkPairs  # [L, L] its end [m]
    static_priority: LinkPairs  # [L, L] +1: the first link has priority, -1: it yields, 0: same
    link_to_lane: np.ndarray  # [L] lane the link leads into
    link_length: np.ndarray  # [L] length of the link's internal path [m]
    area_crossing: np.ndarray  # [areas] its two links cross there (they share no lane before or after it)

    @classmethod
    def from_file(cls, path: str | Path, network: RoadNetwork) -> JunctionModel:
        """The junction model of the network file ``path`` (whose road model is ``network``): from the road model
        cache (:mod:`.model_cache`) when it holds one of this file's content, else built and stored there."""
        return cached(Path(path), "junctions", lambda: cls.build(path, network), keep=True)

    @classmethod
    def build(cls, path: str | Path, network: RoadNetwork) -> JunctionModel:
        """The junction model of the network file ``path``, read and built (no cache)."""
        net = read_net(path)
        lane_idx = {lane_id: k for k, lane_id in enumerate(network.lane_ids)}
        links: list[Link] = []
        prohibits: dict[str, list[str]] = {}
        foes: dict[str, list[str]] = {}
        for node in net.getNodes():
            if node.getType() in ("internal", "dead_end") or not node._foes:
                continue
            prohibits[node.getID()] = [node._prohibits[i] for i in sorted(node._prohibits)]
            foes[node.getID()] = [node._foes[i] for i in sorted(node._foes)]
            for edge in node.getIncoming():
                if edge.getFunction() == "internal":  # with internal lanes loaded, they are incoming too
                    continue
                for inc in edge.getLanes():
                    for c in inc.getOutgoing():
                        if not c.getViaLaneID():
                            continue
                        path = _internal_path(lane_idx[c.getViaLaneID()], network)
                        links.append(Link(
                            junction=node.getID(), index=c.getJunctionIndex(), from_lane=lane_idx[inc.getID()],
                            to_lane=lane_idx[c.getToLane().getID()], path=path,
                            length=float(network.lane_length[list(path)].sum()),
                            tls=c.getTLSID() or "", tls_index=c.getTLLinkIndex() if c.getTLSID() else -1,
                            direction=c.getDirection()))
        links.sort(key=lambda link: (link.junction, link.index))
        link_of_lane = {}
        for k, link in enumerate(links):
            offset = 0.0
            for lane in link.path:
                link_of_lane[lane] = (k, offset)
                offset += float(network.lane_length[lane])
        conflicts = _conflict_areas(links, network, foes, prohibits)
        n_lanes, n_links = len(network.lane_ids), len(links)
        starting: dict[int, list[int]] = {}
        for k, link in enumerate(links):
            starting.setdefault(link.from_lane, []).append(k)
        lane_links = np.full((n_lanes, max((len(v) for v in starting.values()), default=1)), -1, dtype=int)
        for lane, ks in starting.items():
            lane_links[lane, : len(ks)] = ks
        lane_link = np.full(n_lanes, -1, dtype=int)
        lane_link_offset = np.zeros(n_lanes)
        for lane, (k, offset) in link_of_lane.items():
            lane_link[lane], lane_link_offset[lane] = k, offset
        blocks = LinkBlocks.of([link.junction for link in links])
        area_index = LinkPairs.full(blocks, -1, int)
        area_start, area_end = LinkPairs.full(blocks, 0.0, float), LinkPairs.full(blocks, 0.0, float)
        static_priority = LinkPairs.full(blocks, 0, np.int8)
        for m, c in enumerate(conflicts):
            a, b = c.link_a, c.link_b
            sign = {"a": 1, "b": -1, "same": 0}[c.static_priority]
            for table, ab, ba in ((area_index, m, m), (area_start, c.a_start, c.b_start), (area_end, c.a_end, c.b_end),
                                  (static_priority, sign, -sign)):
                table.set(a, b, ab)
                table.set(b, a, ba)
        return cls(tuple(links), tuple(conflicts), link_of_lane, lane_links, lane_link, lane_link_offset,
                   np.array([network.lane_edge[link.to_lane] for link in links], dtype=int),
                   np.array([link.tls for link in links], dtype=object),
                   np.array([link.tls_index for link in links], dtype=int),
                   area_index, area_start, area_end, static_priority,
                   np.array([link.to_lane for link in links], dtype=int),
                   np.array([link.length for link in links], dtype=float),
                   np.array([c.kind == "crossing" for c in conflicts], dtype=bool))

    @cached_property
    def conflict_pairs(self) -> ConflictPairs:
        """The link pairs that share a conflict area and their areas' tables (built on first use)."""
        pairs = self.area_index.pairs()
        area = self.area_index.values[pairs.flat]
        return ConflictPairs(pairs, area, self.area_start.values[pairs.flat],
                             self.area_end.values[pairs.flat], self.static_priority.values[pairs.flat],
                             np.array([c.id for c in self.conflicts], dtype=str)[area])

    @cached_property
    def _signals(self) -> tuple[list[str], np.ndarray]:
        """(the signals with links, sorted; each link's number among them, -1 if unsignalised)."""
        tls = self.link_tls.astype(str)
        names = np.unique(tls[tls != ""])
        return names.tolist(), np.where(tls != "", np.searchsorted(names, tls), -1)

    def signal_ranks(self, tls_states: dict[str, str] | None) -> np.ndarray:
        """[L] rank of every link's current signal (G 2, g 1, anything else 0); -1 if unsignalised or unknown. Read
        it, never write it: it is the same array while the states stay the same (:meth:`signal_chars`)."""
        return self._last_signals(tls_states)[2]

    def signal_chars(self, tls_states: dict[str, str] | None) -> np.ndarray:
        """[L] uint8: every link's current signal state character (its ASCII byte); 0 if unsignalised or unknown.
        Worked out again only when the states differ from those of the last call (they change at a phase switch,
        every few seconds, not every step); read it, never write it."""
        return self._last_signals(tls_states)[1]

    def _last_signals(self, tls_states: dict[str, str] | None) -> tuple[tuple, np.ndarray, np.ndarray]:
        """(the states as a key, :meth:`signal_chars`, :meth:`signal_ranks`) of ``tls_states``, kept per model for
        the last states asked about."""
        key = tuple(tls_states.items()) if tls_states else ()
        last = _LAST_SIGNALS.get(self)
        if last is None or last[0] != key:
            chars = self._signal_chars(tls_states)
            last = _LAST_SIGNALS[self] = (key, chars, np.where(chars > 0, RANK_OF_BYTE[chars], -1))
        return last

    def _signal_chars(self, tls_states: dict[str, str] | None) -> np.ndarray:
        """:meth:`signal_chars`, worked out."""
        out = np.zeros(len(self.links), dtype=np.uint8)
        if tls_states:
            names, number = self._signals
            states = [tls_states.get(name, "") for name in names]  # unknown: as long as no index
            length = np.array([len(state) for state in states], dtype=int)
            chars = np.frombuffer("".join(states).encode("ascii", "replace"), dtype=np.uint8)
            k = np.flatnonzero(number >= 0)
            k = k[(self.link_tls_index[k] >= 0) & (self.link_tls_index[k] < length[number[k]])]
            out[k] = chars[(np.cumsum(length) - length)[number[k]] + self.link_tls_index[k]]
        return out


# Per junction model, the last signal states asked about and their links' characters and ranks
# (:meth:`JunctionModel._last_signals`; the model is frozen).
_LAST_SIGNALS: weakref.WeakKeyDictionary[JunctionModel, tuple[tuple, np.ndarray, np.ndarray]] = \
    weakref.WeakKeyDictionary()


def _internal_path(via: int, network: RoadNetwork) -> tuple[int, ...]:
    """The internal lanes of a link: its via lane and the internal lanes chained after it (a left turn's
    waiting position, for instance)."""
    path = [via]
    while True:
        nxt = [lane for lane in network.lane_successors[path[-1]] if network.edge_internal[network.lane_edge[lane]]]
        if not nxt or nxt[0] in path:
            return tuple(path)
        path.append(nxt[0])


def path_polyline(path: tuple[int, ...], network: RoadNetwork) -> np.ndarray:
    """The centre line [m] of the lanes of ``path`` in order, as one (n, 2) polyline."""
    pts = []
    for lane in path:
        shape = network.shapes.points[lane, : network.shapes.count[lane]]
        pts.extend(shape if not pts else shape[1:])
    return np.asarray(pts, dtype=float)


def _conflict_areas(links: list[Link], network: RoadNetwork, foes: dict[str, list[str]],
                    prohibits: dict[str, list[str]]) -> list[ConflictArea]:
    polylines = [path_polyline(link.path, network) for link in links]
    widths = np.array([float(network.lane_width[link.path[0]]) for link in links])
    by_junction: dict[str, list[int]] = {}
    for k, link in enumerate(links):
        by_junction.setdefault(link.junction, []).append(k)
    foe_pairs = []  # (a, b): links of one junction that SUMO marks as foes
    for junction, members in by_junction.items():
        n = len(foes[junction])
        for ia, a in enumerate(members):
            for b in members[ia + 1:]:
                if foes[junction][links[a].index][n - 1 - links[b].index] == "1":
                    foe_pairs.append((a, b))
    pair_a = np.array([a for a, _ in foe_pairs], dtype=int)
    pair_b = np.array([b for _, b in foe_pairs], dtype=int)
    # Where each strip overlaps the other, along each of the two paths.
    start, end = strip_overlaps(polylines, widths, np.concatenate([pair_a, pair_b]), np.concatenate([pair_b, pair_a]))
    on_a = np.column_stack([start[: len(foe_pairs)], end[: len(foe_pairs)]]).tolist()
    on_b = np.column_stack([start[len(foe_pairs):], end[len(foe_pairs):]]).tolist()
    areas = []
    for (a, b), interval_a, interval_b in zip(foe_pairs, on_a, on_b):
        if np.isnan(interval_a[0]) or np.isnan(interval_b[0]):
            continue
        la, lb = links[a], links[b]
        n = len(foes[la.junction])
        a_yields = prohibits[la.junction][la.index][n - 1 - lb.index] == "1"
        b_yields = prohibits[la.junction][lb.index][n - 1 - la.index] == "1"
        priority = "b" if a_yields and not b_yields else "a" if b_yields and not a_yields else "same"
        kind = "merging" if la.to_lane == lb.to_lane else "diverging" if la.from_lane == lb.from_lane else "crossing"
        areas.append(ConflictArea(f"{la.junction}:{la.index}x{lb.index}", a, b, *interval_a, *interval_b, kind,
                                  priority))
    return areas
