"""Where SUMO's files are: the eclipse-sumo wheel's SUMO_HOME (binaries, XML schemas), else PATH."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
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
    return error_lines(stderr.splitlines())


def error_lines(lines: list[str]) -> str:
    """SUMO's error lines among what it printed (``lines``), each with its indented continuations, joined."""
    found, continuing = [], False
    for line in lines:
        continuing = line.startswith("Error") or (continuing and line.startswith(" "))
        if continuing:
            found.append(line.strip())
    return " ".join(found)


@contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """What is printed to this process's standard error (file descriptor 2: SUMO's C++ messages too) while the block
    runs, kept from the terminal: the list yielded holds its lines once the block has ended. libsumo prints its
    errors and load warnings there; a command prints one line per error, and its progress bar stays whole."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            lines.extend(capture.read().decode("utf-8", errors="replace").splitlines())


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


@lru_cache(maxsize=1)
def sumo_options() -> dict[str, tuple[str, str]]:
    """Every option of SUMO's command line, under its name and each of its synonyms (``n`` and ``net`` for
    ``net-file``): its name and its type (``FILE``, ``BOOL``, ``TIME``, ...), from SUMO's own configuration template
    (``sumo --save-template``)."""
    with tempfile.TemporaryDirectory(prefix="sumo_rss_options_") as folder:
        template = Path(folder) / "template.sumocfg"
        try:
            subprocess.run([str(sumo_tool("sumo")), "--save-template", str(template)], capture_output=True,
                           timeout=60, check=True)
            root = ET.parse(template).getroot()
        except (OSError, subprocess.SubprocessError, ET.ParseError) as exc:
            raise SumoRssError(f"SUMO's option template could not be read (sumo --save-template: {exc})") from None
    options = {}
    for section in root:
        for option in section:
            for name in (option.tag, *option.get("synonymes", "").split()):
                options[name] = (option.tag, option.get("type", ""))
    return options
