"""Vehicle types as SUMO resolves them, for audits of FCD files (no simulation is run).

A vType may leave out its length, width, tau or decel; SUMO then takes the default of its vClass (a truck is
7.1 m x 2.4 m, a bicycle 1.6 m x 0.65 m), and a vehicle without a type uses one of SUMO's built-in types. Rather than
keeping a copy of SUMO's tables, :func:`sumo_vtypes` loads the vTypes into libsumo and reads them back.
"""
from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import libsumo

from ..errors import SessionError, shown
from ..files import output_error
from ..sumo_home import captured_stderr, error_lines, sumo_errors
from . import session


# What the audit takes from a vType, within the bounds of a road or rail vehicle [unit]: the longest trains, SUMO's
# shortest step as the shortest reaction time (and the RSS response time of the krauss preset, at most 10 s).
VTYPE_BOUNDS = {"length": (0.1, 2000.0, "m"), "width": (0.1, 20.0, "m"), "tau": (0.001, 10.0, "s"),
                "decel": (0.01, 100.0, "m/s²")}


@dataclass(frozen=True)
class VTypeParameters:
    """What the audit uses of a vType."""

    length: float  # [m]
    width: float  # [m]
    tau: float  # [s] desired time headway
    decel: float  # [m/s²] comfortable deceleration
    height: float  # [m] (rule 4: taller road users block the line of sight)
    vclass: str = "passenger"  # SUMO's vClass ('bicycle' gets its own RSS parameters)


def sumo_vtypes(net_file: Path, documents: Sequence[ET.Element] = (), source: str = "") -> dict[str, VTypeParameters]:
    """Every vType SUMO knows after loading ``net_file`` with the vTypes and vType distributions of ``documents``
    (the roots of parsed route or additional files, in SUMO's order; their vehicles, trips and routes are left
    out): SUMO's built-in types and the files', with SUMO's vClass defaults for what a vType does not set. Starts
    libsumo for a moment, so no :class:`~sumo_rss.sim.session.Session` may be open in this process. Raises
    ``ValueError`` naming ``source`` (the files) when SUMO rejects a vType."""
    if session.libsumo_in_use():
        raise SessionError("vTypes cannot be resolved while a Session is open in this process (libsumo runs one "
                           "simulation per process)")
    with tempfile.TemporaryDirectory(prefix="sumo_rss_vtypes_") as folder:
        additional = Path(folder) / "vtypes.add.xml"
        root = ET.Element("additional")
        for document in documents:
            root.extend(_vtype_elements(document))
        try:
            ET.ElementTree(root).write(additional, encoding="utf-8")
        except OSError as exc:  # the temporary folder's disk is full
            raise output_error(additional, exc) from None
        args = ["--net-file", str(net_file), "--additional-files", str(additional), "--no-warnings", "true"]
        try:
            with captured_stderr() as printed:
                libsumo.start(["sumo", *args])
        except libsumo.TraCIException as exc:
            reason = error_lines(printed) or sumo_errors(args) or str(exc)
            raise ValueError(f"{source or net_file}: SUMO cannot load the vTypes ({reason})") from exc
        try:
            vt = libsumo.vehicletype
            types = {t: VTypeParameters(vt.getLength(t), vt.getWidth(t), vt.getTau(t), vt.getDecel(t),
                                        vt.getHeight(t), vt.getVehicleClass(t))
                     for t in vt.getIDList()}
        finally:
            libsumo.close()
    for type_id, parameters in types.items():
        _check(source or str(net_file), type_id, parameters)
    return types


def _check(source: str, type_id: str, parameters: VTypeParameters) -> None:
    """ValueError naming the vType and attribute whose value (as SUMO resolved it) no vehicle can have: SUMO
    accepts a length of 1e300 m, which made gaps of -1e300 m in episodes.csv."""
    for name, (low, high, unit) in VTYPE_BOUNDS.items():
        value = getattr(parameters, name)
        if not low <= value <= high:
            raise ValueError(f"{source}: vType {shown(type_id)}: {name}: expected a number in [{low:g}, {high:g}] "
                             f"{unit}, got {value:.6g}")


def _vtype_elements(elem: ET.Element) -> list[ET.Element]:
    """The vType and vTypeDistribution elements under ``elem`` (a distribution with the vTypes inside it), in
    document order."""
    found = []
    for child in elem:
        found.extend([child] if child.tag in ("vType", "vTypeDistribution") else _vtype_elements(child))
    return found


def running_heights() -> dict[str, float]:
    """[m] the height of every vType of the simulation running in this process (SUMO's vClass default where a vType
    sets none): rule 4's tall road users."""
    vt = libsumo.vehicletype
    return {t: vt.getHeight(t) for t in vt.getIDList()}
