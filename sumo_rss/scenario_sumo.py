"""What a scenario file passes to SUMO beyond the generated demand: the ``[sumo]`` table (lane-change duration,
teleporting, collision gap, additional files, further options) and SUMO input files of the user's own, resolved
relative to the scenario file and checked when it is loaded (docs/scenarios.md, "SUMO files of your own")."""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path

from .sumo_home import sumo_options
from .sumo_xml import MALFORMED, root_tag
from .validation import TableReader

INPUT_ROOTS = ("routes", "additional")  # root elements of the SUMO route and additional files a scenario may name
# SUMO options a session sets itself (sim/session.py, sumo_arguments), and the scenario key that sets each (SUMO
# refuses an option given twice).
OWN_OPTIONS = {
    "net-file": "network", "route-files": "demand.route_files", "additional-files": "sumo.additional_files",
    "begin": "duration_s", "end": "duration_s", "step-length": "step_s", "seed": "seed",
    "lanechange.duration": "sumo.lanechange_duration_s", "time-to-teleport": "sumo.time_to_teleport_s",
    "collision.mingap-factor": "sumo.collision_mingap_factor", "fcd-output": "outputs.fcd",
    "fcd-output.attributes": "outputs.fcd", "collision-output": "outputs.collisions_xml",
    "collision.action": "", "collision.check-junctions": "", "no-step-log": "", "duration-log.disable": "",
    "precision": "", "error-log": "", "no-warnings": "",
}


@dataclass(frozen=True)
class SumoSpec:
    lanechange_duration_s: float = 3.0
    time_to_teleport_s: float = 300.0  # 0 disables teleporting
    collision_mingap_factor: float = 0.0  # 0: a collision is a physical overlap
    additional_files: tuple[Path, ...] = ()  # absolute: signal programs, detectors, stops, vTypes ...
    extra_args: tuple[str, ...] = ()


def read_sumo(t: TableReader, scenario_file: Path) -> SumoSpec:
    spec = SumoSpec(
        lanechange_duration_s=t.number("lanechange_duration_s", 3.0, min=0.0, max=20.0, min_exclusive=True),
        time_to_teleport_s=t.number("time_to_teleport_s", 300.0, min=0.0),
        collision_mingap_factor=t.number("collision_mingap_factor", 0.0, min=0.0, max=1.0),
        additional_files=read_input_files(t, "additional_files", scenario_file),
        extra_args=t.string_list("extra_args", [], min_len=0),
    )
    _check_extra_args(t, spec.extra_args)
    t.finish()
    return spec


def _check_extra_args(t: TableReader, args: tuple[str, ...]) -> None:
    """Every option of ``extra_args`` is one of SUMO's, and not one that the session sets (or --random)."""
    options = sumo_options()
    for i, arg in enumerate(args):
        if not arg.startswith("-") or arg.lstrip("-")[:1].isdigit():
            continue  # a value (a negative number is one too)
        name = arg.lstrip("-").split("=", 1)[0]
        if name not in options:
            close = difflib.get_close_matches(name, list(options), n=1)
            hint = f" (did you mean --{close[0]}?)" if close else ""
            raise t.error(f"extra_args[{i}]", f"expected an option of SUMO's command line (sumo --help){hint}", arg)
        if options[name][0] == "random":  # SUMO's own seed from the clock
            raise t.error(f"extra_args[{i}]", "expected no --random: the scenario's seed makes a run repeatable "
                                             "(the same scenario and seed give byte-identical outputs)", arg)
        own = OWN_OPTIONS.get(options[name][0])
        if own is not None:
            instead = f"set it with the scenario key {own}" if own else \
                "sumo_rss sets it for every run (docs/scenarios.md, 'Fixed SUMO settings')"
            raise t.error(f"extra_args[{i}]", f"expected an option that sumo_rss does not set itself: {instead}", arg)


def read_input_files(t: TableReader, key: str, scenario_file: Path) -> tuple[Path, ...]:
    """The table's ``key``: SUMO route or additional files (``*.xml`` or gzipped ``*.xml.gz``, as SUMO reads them),
    relative to the scenario file, as absolute paths. Each must exist and be an XML file whose root is <routes> or
    <additional>; no ',' or ';' in a path (SUMO splits its file lists there)."""
    files = []
    for i, name in enumerate(t.string_list(key, [], min_len=0)):
        path = (scenario_file.parent / name).resolve()
        if "," in str(path) or ";" in str(path):
            raise t.error(f"{key}[{i}]", "expected a path without ',' or ';' (SUMO splits its file lists there)", name)
        if not path.is_file():
            raise t.error(f"{key}[{i}]", f"expected an existing SUMO file, relative to the scenario file (looked for "
                                         f"{path})", name)
        try:
            root = root_tag(path)
        except (*MALFORMED, OSError) as exc:
            raise t.error(f"{key}[{i}]", f"expected a readable SUMO XML file ({path}: {' '.join(str(exc).split())})",
                          name) from None
        if root not in INPUT_ROOTS:
            raise t.error(f"{key}[{i}]", f"expected a SUMO route or additional file (root element <routes> or "
                                         f"<additional>; {path} has <{root}>)", name)
        files.append(path)
    return tuple(files)
