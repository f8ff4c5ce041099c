"""Checks of the records of an offline audit's side files against the network and the FCD: SUMO's signal-state
output (``SaveTLSStates``) and its collision output. What contradicts the network or the FCD is an error naming the
file, the record and the attribute; a run's files that merely do not fit together are named in a warning."""
from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import SumoRssError, cut, shown
from ..road.net_check import SIGNAL_STATE_CHARACTERS
from ..road.topology import read_topology
from ..sim.collisions import CollisionEvent

if TYPE_CHECKING:  # signals.py imports this module
    from .signals import SignalStates


def signal_state(path: Path, number: int, elem: ET.Element, links: dict[str, int],
                 previous: float | None) -> tuple[float, str]:
    """(time [s], state) of the ``number``-th ``<tlsState>`` of ``path``: a finite time >= 0, not before the
    signal's state before (``previous``), and a state of SUMO's characters with one per link of the signal
    (``links``: signal id → links, as its programs in the network have them; signals not in it are left to the
    caller). SumoRssError naming the file, the record and the attribute otherwise."""
    signal = elem.get("id", "")
    record = f"{path}: <tlsState> {number} (signal {shown(signal)})"
    if not signal:
        raise SumoRssError(f"{path}: <tlsState> {number}: id: expected the id of a signal of the network, got "
                           "nothing")
    text = elem.get("time")
    try:
        time = float(text) if text is not None else math.nan
    except ValueError:
        time = math.nan
    if not (math.isfinite(time) and time >= 0.0):
        raise SumoRssError(f"{record}: time: expected a number of seconds >= 0, got "
                         f"{'nothing' if text is None else shown(text)}")
    if previous is not None and time < previous:
        raise SumoRssError(f"{record}: time: expected no earlier than the signal's state before ({previous:g} s), "
                         f"got {shown(text)}")
    state = elem.get("state", "")
    expected = links.get(signal)
    if not state or not set(state) <= set(SIGNAL_STATE_CHARACTERS) or (expected is not None and len(state) != expected):
        count = f"{expected} characters" if expected is not None else "characters"
        raise SumoRssError(f"{record}: state: expected {count} of {SIGNAL_STATE_CHARACTERS}, one per "
                         f"link the network's signal controls, got {shown(state)}"
                         f"{f' ({len(state)} characters)' if state and expected is not None else ''}")
    return time, state


def warn_without_signal_states(net_file: Path) -> None:
    """The warning of an offline audit without SUMO's signal states on a network with signals: their states then
    come from the network's own programs, which need not be what the run's signals showed."""
    signals = read_topology(net_file).signals
    if signals:
        warnings.warn(
            f"{net_file}: the network has {len(signals)} traffic signal(s) and no signal states were given "
            "(--tls-states): the audit takes their states from the network's own programs, run unchanged from 0 s. "
            "A run whose signals ran other programs (from its additional files, actuated, switched by TraCI) gets "
            "red-light violations and priorities that SUMO never showed; give the run's signal states "
            "(SaveTLSStates, docs/rss.md)", stacklevel=3)


def warn_late_signal_states(signals: SignalStates, fcd: Path, first_time: float) -> None:
    """The warning of an offline audit whose signal-state file begins some signal's states after the FCD's first
    time step ``first_time`` [s] (files of different runs, or a SaveTLSStates output begun late)."""
    late = signals.begin_after(first_time)
    if late:
        first = ", ".join(f"{cut(tl)} at {time:g} s" for tl, time in list(late.items())[:3])
        warnings.warn(f"{signals.saved_states}: the states of signal(s) {first}{', ...' if len(late) > 3 else ''} "
                      f"begin after the first time step of {fcd} ({first_time:g} s): until then the links of those "
                      "signals are audited as of equal priority, without the signal rule; is it the signal-state "
                      "file of this run?", stacklevel=3)


def check_collision_record(report: CollisionEvent, record: str) -> None:
    """A collision is between two road users (SUMO never reports a vehicle colliding with itself)."""
    if report.collider == report.victim:
        raise SumoRssError(f"{record}: collider and victim are both {shown(report.collider)} (expected two "
                           "different vehicles)")


def check_collisions_in_fcd(collisions: Path, fcd: Path, audited: list[CollisionEvent], unseen: set[str]) -> None:
    """Every audited collision report names road users of the FCD (``unseen``: the colliders and victims that none
    of its time steps shows, as a vehicle, person or container): a report of a vehicle the FCD never shows is from
    another run."""
    for report in audited:
        absent = [who for who in (report.collider, report.victim) if who in unseen]
        if absent:
            raise SumoRssError(
                f"{collisions}: <collision> at {report.time:g} s ({shown(report.collider)} and "
                f"{shown(report.victim)}): {' and '.join(shown(a) for a in absent)} not in {fcd} (expected the "
                "collision output of the run that wrote the FCD)")
