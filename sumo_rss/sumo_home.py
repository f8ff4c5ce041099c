"""Where SUMO's files are: the eclipse-sumo wheel's SUMO_HOME (binaries, XML schemas), else PATH."""
from __future__ import annotations

import os
import shutil
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
