"""Where SUMO's files are: the eclipse-sumo wheel's SUMO_HOME (binaries, XML schemas), else PATH."""
from __future__ import annotations

import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from functools import lru_cache
from pathlib import Path

from .errors import SumoRssError

_XSD = "{http://www.w3.org/2001/XMLSchema}"


def sumo_home() -> Path | None:
    """SUMO_HOME of the eclipse-sumo package, else ``$SUMO_HOME``, else None."""
    try:
        import sumo  # the eclipse-sumo wheel

        return Path(sumo.SUMO_HOME)
    except ImportError:
        env = os.environ.get("SUMO_HOME")
        return Path(env) if env else None


def sumo_tool(name: str) -> Path:
    """Path of a SUMO executable (``netconvert``, ``sumo``...)."""
    home = sumo_home()
    if home is not None and (home / "bin" / name).is_file():
        return home / "bin" / name
    found = shutil.which(name)
    if found is None:
        raise SumoRssError(f"SUMO's {name} was not found: install the 'eclipse-sumo' package (make install)")
    return Path(found)


def sumo_errors(args: list[str], timeout: float = 60.0) -> str:
    """SUMO's own error message for the command-line ``args`` (without the program name) that libsumo refused:
    libsumo raises a bare "Process Error" or similar, so the sumo binary is run with them and its error lines
    (with their indented continuations) are returned, joined; '' if it printed none."""
    try:
        stderr = subprocess.run([str(sumo_tool("sumo")), *args], capture_output=True, text=True, timeout=timeout,
                                check=False).stderr
    except (OSError, subprocess.TimeoutExpired):
        return ""
    lines, continuing = [], False
    for line in stderr.splitlines():
        continuing = line.startswith("Error") or (continuing and line.startswith(" "))
        if continuing:
            lines.append(line.strip())
    return " ".join(lines)


@lru_cache(maxsize=1)
def vtype_attribute_names() -> frozenset[str]:
    """Every attribute SUMO's route-file schema allows on a ``<vType>`` (SUMO ignores unknown ones silently)."""
    home = sumo_home()
    schema = home / "data" / "xsd" / "types" / "route.xsd" if home is not None else None
    if schema is None or not schema.is_file():
        raise SumoRssError("SUMO's route schema (data/xsd/types/route.xsd) was not found: install 'eclipse-sumo'")
    for complex_type in ET.parse(schema).getroot().iter(f"{_XSD}complexType"):
        if complex_type.get("name") == "vTypeBaseType":
            return frozenset(a.get("name", "") for a in complex_type.iter(f"{_XSD}attribute"))
    raise SumoRssError(f"{schema}: no vTypeBaseType found; unsupported SUMO version")
