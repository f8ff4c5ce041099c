"""Build the shipped networks from their plain-XML sources with SUMO's netconvert."""
from __future__ import annotations

import re
import subprocess
import warnings
from pathlib import Path

from ..errors import SumoRssError
from ..sumo_home import sumo_tool

_GENERATOR_HEADER = re.compile(r"\A<\?xml[^>]*\?>\s*<!--.*?-->\s*", re.DOTALL)


def network_config(network_dir: Path) -> Path:
    config = network_dir / f"{network_dir.name}.netccfg"
    if not config.is_file():
        raise SumoRssError(f"{network_dir}: expected a netconvert configuration {config.name}")
    return config


def build_network(network_dir: Path, output: Path | None = None) -> Path:
    """Run netconvert on ``<dir>/<name>.netccfg``; writes ``output`` (default: the configured net file)."""
    config = network_config(network_dir)
    cmd = [str(sumo_tool("netconvert")), "-c", config.name]
    if output is not None:
        cmd += ["--output-file", str(Path(output).resolve())]
    proc = subprocess.run(cmd, cwd=network_dir, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise SumoRssError(f"netconvert failed for {config}: {' '.join(proc.stderr.split())}")  # one line
    for line in proc.stderr.splitlines():  # what netconvert warned about (e.g. a junction shape it moved)
        if line.startswith("Warning:"):
            warnings.warn(f"{config}: netconvert: {line.removeprefix('Warning:').strip()}", stacklevel=2)
    return Path(output) if output is not None else network_dir / f"{network_dir.name}.net.xml"


def network_dirs(root: Path) -> list[Path]:
    """Every folder under ``root`` holding a ``<name>/<name>.netccfg``."""
    return sorted(p for p in root.iterdir() if (p / f"{p.name}.netccfg").is_file())


def without_generator_header(net_xml: str) -> str:
    """The network text without netconvert's leading comment (build date, version, options)."""
    return _GENERATOR_HEADER.sub("", net_xml, count=1)
