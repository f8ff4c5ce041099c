"""``sumo-rss view``: one self-contained ``view.html`` of a run or audit folder (no server, no network: the page's
script, style and data are all inside it)."""
from __future__ import annotations

import base64
import html
import json
import warnings
from importlib import resources
from pathlib import Path

from collections.abc import Callable, Iterable

from ..errors import SumoRssError
from ..files import write_text
from .network import NetGeometry, read_geometry
from .payload import build_payload
from .trajectories import TRAJECTORY_FILE, Trajectories

VIEW_FILE = "view.html"


def write_view(run_dir: Path, out: Path | None = None, net: Path | None = None, every: int = 1, *,
               geometry: Callable[[Path], NetGeometry] = read_geometry) -> Path:
    """Write the replay page of ``run_dir`` (a folder of ``sumo-rss run``, a batch's run or ``sumo-rss audit
    --out``) to ``out`` (default ``run_dir/view.html``); ``net``: the network, where it is not where the run or
    audit found it; ``every``: keep every n-th recorded step; ``geometry``: reads a net (e.g. a cache of them).
    Returns the page's path."""
    run_dir = Path(run_dir)
    if every < 1:
        raise SumoRssError(f"--every: expected an integer >= 1, got {every}")
    source = run_dir / TRAJECTORY_FILE
    if not run_dir.is_dir():
        raise SumoRssError(f"{run_dir}: not a folder (expected a run folder of 'sumo-rss run' or 'batch', or the "
                           "--out folder of 'sumo-rss audit')")
    if not source.is_file():
        raise SumoRssError(f"{source}: not found: the folder is no run or audit of this sumo-rss version (run or "
                           "audit it again to record it)")
    trajectories = Trajectories.read(source)
    net_file = Path(net) if net is not None else Path(trajectories.net_file)
    if not net_file.is_file():
        named = "" if net is not None else f" (the network {source.name} names)"
        raise SumoRssError(f"{net_file}: network file not found{named}; give it with --net")
    header, scene, states = build_payload(run_dir, trajectories, geometry(net_file), every)
    out = Path(out) if out is not None else run_dir / VIEW_FILE
    write_text(out, render_page(header, scene.compressed(), states.compressed()))
    return out


def write_run_views(run_dirs: Iterable[Path], on_done: Callable[[], None] | None = None) -> dict[Path, Path]:
    """The view of every run folder that has a trajectory file (written where it is missing or older than that
    file; each network read once; a folder whose page cannot be written is warned about and left out); returns run
    folder → page. ``on_done()`` after each folder."""
    nets: dict[Path, NetGeometry] = {}

    def cached(path: Path) -> NetGeometry:
        if path not in nets:
            nets[path] = read_geometry(path)
        return nets[path]

    views = {}
    for run_dir in run_dirs:
        source, page = run_dir / TRAJECTORY_FILE, run_dir / VIEW_FILE
        if source.is_file():
            try:
                if not page.is_file() or page.stat().st_mtime < source.stat().st_mtime:
                    write_view(run_dir, geometry=cached)
                views[run_dir] = page
            except SumoRssError as exc:  # one run's page: not a reason to give up the others
                warnings.warn(f"no view of {run_dir}: {exc}", stacklevel=2)
        if on_done is not None:
            on_done()
    return views


def render_page(header: dict, scene: bytes, states: bytes) -> str:
    """The page: the template with the style, the viewer module, the header (JSON) and the blobs (base64) inside."""
    folder = resources.files(__package__)
    text = json.dumps(header, separators=(",", ":"), allow_nan=False)
    page = folder.joinpath("template.html").read_text(encoding="utf-8")
    parts = {"{{title}}": html.escape(str(header["title"])), "{{css}}": folder.joinpath("viewer.css").read_text(
        encoding="utf-8"), "{{header}}": text.replace("</", "<\\/"), "{{scene}}": base64.b64encode(scene).decode("ascii"),
             "{{states}}": base64.b64encode(states).decode("ascii"),
             "{{js}}": folder.joinpath("viewer.js").read_text(encoding="utf-8")}
    for marker, value in parts.items():
        page = page.replace(marker, value)
    return page
