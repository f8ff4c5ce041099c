"""Build the Monaco-size run that tests/test_real_networks_acceptance.py and `bench/city_audit.py --realnet` audit:
MoST's network (Lara Codeca's Monaco SUMO Traffic, https://github.com/lcodeca/MoSTScenario) rebuilt from its road
OSM, random traffic driven by SUMO, and SUMO's own outputs of that run.

- Network: netconvert with MoST's own `tools/most.netcfg` and type maps, on `tools/data/network.osm` (the roads of
  `most.raw.osm`, which is in Git LFS and often absent; the shipped nets are too): 18,732 edges, 23,794 lanes.
- Demand (randomTrips, seed 42, validated): a car every --period s (0.6: 500 over 300 s) and a pedestrian every
  --person-period s (1.0: 300; 0: none), in one route file sorted by departure.
- Run: SUMO at 0.1 s steps for --seconds (300) with --lanechange.duration 3 --precision 6 --collision.action warn
  --collision.check-junctions, the FCD, the collisions and the signal states (a SaveTLSStates timedEvent).

Writes most.net.xml, most.rou.xml, most.fcd.xml, most.collisions.xml and most.tls.xml into OUT (the folder the
acceptance test reads: $SUMO_RSS_REALNETS, default /work/realnets). MOST is a MoST checkout: a working tree or a
bare git directory (files read with `git show HEAD:...`). Fetched data is never committed to this repository.

  python bench/build_most.py /path/to/MoSTScenario /work/realnets
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from sumo_rss.sumo_home import sumo_home, sumo_tool

SEED = 42
MIN_EDGES = 15_000  # issue 47: a Monaco-size net
SOURCES = ("tools/most.netcfg", "tools/data/network.osm")
LFS_POINTER = b"version https://git-lfs"
RUN_FILES = ("most.net.xml", "most.rou.xml", "most.fcd.xml", "most.collisions.xml", "most.tls.xml")  # what it writes


def main() -> int:
    parser = argparse.ArgumentParser(prog="python bench/build_most.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("most", type=Path, help="a MoSTScenario checkout (working tree or bare git directory)")
    parser.add_argument("out", type=Path, help="the folder to write the run into")
    parser.add_argument("--seconds", type=float, default=300.0, help="simulated seconds (default 300)")
    parser.add_argument("--period", type=float, default=0.6, help="a car every PERIOD s (default 0.6)")
    parser.add_argument("--person-period", type=float, default=1.0,
                        help="a pedestrian every PERIOD s (default 1.0; 0: no pedestrians)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "SUMO_HOME": str(sumo_home())}
    with tempfile.TemporaryDirectory(prefix="build_most_") as tmp:
        src = Path(tmp)
        net = build_net(args.most, src, args.out / "most.net.xml")
        edges = len(re.findall(rb"<edge ", net.read_bytes()))
        if edges < MIN_EDGES:
            raise SystemExit(f"{net}: {edges} edges, expected a Monaco-size net (>= {MIN_EDGES})")
        demand = [random_routes(net, src, "car", args.seconds, args.period, env)]
        if args.person_period > 0:
            demand.append(random_routes(net, src, "ped", args.seconds, args.person_period, env, "--pedestrians"))
        merged = merge_routes(demand, args.out / "most.rou.xml")
    simulate(net, args.out, args.seconds, env)
    print(f"{net}: {edges} edges; {merged['vehicle']} cars, {merged['person']} persons over {args.seconds:g} s; "
          f"{args.out / 'most.fcd.xml'}: {(args.out / 'most.fcd.xml').stat().st_size / 1e6:.0f} MB")
    return 0


def build_net(most: Path, src: Path, net: Path) -> Path:
    """netconvert with MoST's netcfg and type maps, on its road OSM instead of the merged raw OSM."""
    types = re.search(r'<type-files value="([^"]+)"', _read(most, "tools/most.netcfg").decode()).group(1)  # type: ignore[union-attr]
    for name in (*SOURCES, *(f"tools/{t}" for t in types.split(","))):
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_bytes(_read(most, name))
    _run([str(sumo_tool("netconvert")), "-c", "most.netcfg", "--osm-files", "data/network.osm", "--output-prefix",
          "", "--output-file", str(net.resolve()), "--verbose", "false", "--log", "netconvert.log"],
         cwd=src / "tools")
    return net


def random_routes(net: Path, src: Path, prefix: str, seconds: float, period: float, env: dict,
                  *extra: str) -> Path:
    """Validated random trips (seed SEED), routed: one every ``period`` s from 0 to ``seconds``."""
    routes = src / f"{prefix}.rou.xml"
    _run([sys.executable, str(sumo_home() / "tools" / "randomTrips.py"), "-n", str(net), "-o",
          str(src / f"{prefix}.trips.xml"), "-r", str(routes), "--seed", str(SEED), "-b", "0", "-e", str(seconds),
          "-p", str(period), "--validate", "--fringe-factor", "5", "--prefix", prefix, *extra], env=env)
    return routes


def merge_routes(files: list[Path], out: Path) -> dict[str, int]:
    """One route file of ``files``: their vTypes and other definitions first, then every vehicle and person by
    departure time (SUMO reads a route file in order). Returns the count of each element kind."""
    definitions, departing = [], []
    for path in files:
        for element in ET.parse(path).getroot():
            if element.get("depart") is None:
                definitions.append(element)
            else:
                departing.append(element)
    departing.sort(key=lambda e: float(e.get("depart")))  # stable: a file's order among equal times
    root = ET.Element("routes")
    root.extend(definitions + departing)
    ET.indent(root)
    ET.ElementTree(root).write(out, encoding="UTF-8", xml_declaration=True)
    return {kind: sum(e.tag == kind for e in departing) for kind in ("vehicle", "person")}


def simulate(net: Path, out: Path, seconds: float, env: dict) -> None:
    """SUMO's run of most.rou.xml on ``net``: the FCD, collisions and signal states in ``out``."""
    (out / "most.tls.add.xml").write_text('<additional><timedEvent type="SaveTLSStates" dest="most.tls.xml"/>'
                                          '</additional>\n')
    _run([str(sumo_tool("sumo")), "-n", str(net.resolve()), "-r", "most.rou.xml", "-a", "most.tls.add.xml",
          "--step-length", "0.1", "--begin", "0", "--end", str(seconds), "--seed", str(SEED),
          "--lanechange.duration", "3", "--precision", "6", "--collision.action", "warn",
          "--collision.check-junctions", "--collision-output", "most.collisions.xml", "--fcd-output", "most.fcd.xml",
          "--no-step-log", "--no-warnings"], cwd=out, env=env)


def _read(most: Path, name: str) -> bytes:
    """The file ``name`` of the MoST checkout: from its working tree, else from its git HEAD."""
    path = most / name
    if path.is_file() and not path.read_bytes().startswith(LFS_POINTER):
        return path.read_bytes()
    git_dir = most if (most / "HEAD").is_file() else most / ".git"
    shown = subprocess.run(["git", "--git-dir", str(git_dir), "show", f"HEAD:{name}"], capture_output=True,
                           check=False)
    if shown.returncode != 0 or shown.stdout.startswith(LFS_POINTER):
        raise SystemExit(f"{most}: no {name} (a MoSTScenario checkout has it)")
    return shown.stdout


def _run(cmd: list[str], cwd: Path | None = None, env: dict | None = None) -> None:
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{Path(cmd[1] if cmd[0] == sys.executable else cmd[0]).name} failed:\n"
                         f"{done.stderr[-3000:]}")


if __name__ == "__main__":
    raise SystemExit(main())
