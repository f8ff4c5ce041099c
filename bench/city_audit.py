"""Offline audit of a real city run: by default the DRT city network of the eclipse-sumo package (8,109 edges, 21
signals), driven by SUMO itself with random trips (fixed seed), written as an FCD with collisions and signal states
(`--step-length 0.1 --lanechange.duration 3 --precision 6 --collision.check-junctions`). Point it at another run
with --fcd and its files (--net, --vtypes, --collisions, --tls-states), e.g. Bologna's acosta, or with --realnet at
the folder bench/build_most.py wrote the Monaco-size run into (recorded as city_audit_most).

Figures: the network's load time cold (an empty road model cache) and from the cache, each in a fresh process; the
FCD reader's speed alone over the plain file and over its gzip (MB/s of XML); and `sumo-rss audit` as a user runs it
(cold cache, its own process): wall and CPU time, peak memory (its maximum resident set), the real-time factor
(simulated seconds per wall second, with and without the network load) and pair-steps/s.
"""
from __future__ import annotations

import gzip
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402
from build_most import RUN_FILES  # noqa: E402

from sumo_rss.road.model_cache import CACHE_ENV  # noqa: E402
from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.fcd import FcdReader, read_vehicle_info  # noqa: E402
from sumo_rss.sumo_home import sumo_home, sumo_tool  # noqa: E402

DRT = sumo_home() / "tools" / "game" / "DRT" / "osm.net.xml"
SEED = 42
LOAD = """
import sys, time
from pathlib import Path
from sumo_rss.road.junctions import JunctionModel
from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.signals import SignalStates
started = time.perf_counter()
network = RoadNetwork.from_file(Path(sys.argv[1]))
JunctionModel.from_file(network.path, network)
SignalStates(network.path)
print(time.perf_counter() - started)
"""


def _options(parser) -> None:
    parser.add_argument("--net", type=Path, default=DRT, help="the network (default: the eclipse-sumo DRT city)")
    parser.add_argument("--fcd", type=Path, help="audit this FCD (with the options below) instead of running SUMO")
    parser.add_argument("--vtypes", help="route/vType files of the FCD, comma-separated")
    parser.add_argument("--collisions", type=Path, help="SUMO's collision output of the FCD's run")
    parser.add_argument("--tls-states", type=Path, help="SUMO's signal states (SaveTLSStates) of the FCD's run")
    parser.add_argument("--seconds", type=float, default=300.0, help="simulated seconds of SUMO's run (default 300)")
    parser.add_argument("--period", type=float, default=0.4, help="random trips: one every PERIOD s (default 0.4)")
    parser.add_argument("--realnet", type=Path, help="audit the MoST run in this folder (bench/build_most.py's "
                        "most.net.xml, most.rou.xml, most.fcd.xml, most.collisions.xml, most.tls.xml) instead")
    parser.add_argument("--label", help="record as city_audit_LABEL (default: city_audit for the DRT run, "
                                        "city_audit_most for --realnet)")


def simulate(net: Path, folder: Path, seconds: float, period: float) -> dict:
    """Random trips on ``net`` (seed SEED) driven by SUMO for ``seconds``: the audit's input files."""
    env = {**os.environ, "SUMO_HOME": str(sumo_home())}
    routes = folder / "routes.rou.xml"
    subprocess.run([sys.executable, str(sumo_home() / "tools" / "randomTrips.py"), "-n", str(net), "-o",
                    str(folder / "trips.xml"), "-r", str(routes), "--seed", str(SEED), "-e", str(seconds), "-p",
                    str(period), "--validate", "--fringe-factor", "5"], check=True, capture_output=True, env=env)
    (folder / "tls.add.xml").write_text('<additional><timedEvent type="SaveTLSStates" dest="tls.xml"/></additional>')
    subprocess.run([str(sumo_tool("sumo")), "-n", str(net), "-r", str(routes), "-a", str(folder / "tls.add.xml"),
                    "--step-length", "0.1", "--lanechange.duration", "3", "--precision", "6", "--collision.action",
                    "warn", "--collision.check-junctions", "--collision-output", str(folder / "collisions.xml"),
                    "--fcd-output", str(folder / "fcd.xml"), "--begin", "0", "--end", str(seconds), "--seed",
                    str(SEED), "--no-step-log", "--no-warnings"], check=True, capture_output=True, cwd=folder, env=env)
    return {"fcd": folder / "fcd.xml", "vtypes": str(routes), "collisions": folder / "collisions.xml",
            "tls_states": folder / "tls.xml"}


def _child(args: list[str], cache: Path) -> tuple[str, float, float, float]:
    """Run ``args`` in its own process with the road model cache ``cache``: (its output, wall [s], CPU [s], peak
    resident memory [MB])."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        started = time.perf_counter()
        proc = subprocess.Popen(args, stdout=out, stderr=err, text=True, cwd=REPO,
                                env={**os.environ, CACHE_ENV: str(cache), "PYTHONPATH": str(REPO)})
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - started
        out.seek(0)
        err.seek(0)
        if os.waitstatus_to_exitcode(status) != 0:
            raise RuntimeError(f"{' '.join(args)} failed: {err.read()[-2000:]}")
        return out.read(), wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def reader_speed(fcd: Path, net: Path, vtypes: str | None) -> tuple[float, float]:
    """(MB/s of XML read into snapshots, the simulated seconds the FCD covers)."""
    network = RoadNetwork.from_file(net)
    vehicles = read_vehicle_info([Path(p) for p in vtypes.split(",")] if vtypes else None, net)
    started, times = time.perf_counter(), []
    for snapshot in FcdReader(fcd, network, vehicles):
        times.append(snapshot.time)
    step = times[-1] - times[-2] if len(times) > 1 else 0.0
    return _xml_bytes(fcd) / 1e6 / (time.perf_counter() - started), times[-1] - times[0] + step if times else 0.0


def _xml_bytes(fcd: Path) -> int:
    if fcd.suffix != ".gz":
        return fcd.stat().st_size
    with gzip.open(fcd, "rb") as f:
        return sum(len(block) for block in iter(lambda: f.read(1 << 20), b""))


def main() -> None:
    options = arguments(__doc__, "city_audit.py", _options)
    if options.realnet is not None:
        missing = [name for name in RUN_FILES if not (options.realnet / name).is_file()]
        if missing:
            raise SystemExit(f"{options.realnet}: no MoST run ({', '.join(missing)} missing; bench/build_most.py "
                             "writes it)")
        options.net, options.vtypes, options.fcd, options.collisions, options.tls_states = (
            options.realnet / name for name in RUN_FILES)
        options.vtypes = str(options.vtypes)
        options.label = options.label or "most"
    with tempfile.TemporaryDirectory(prefix="city_audit_") as tmp:
        folder = Path(tmp)
        cache = folder / "cache"
        os.environ[CACHE_ENV] = str(cache)  # this process's loads too: a user's cache is left alone
        if options.fcd is None:
            started = time.perf_counter()
            run = simulate(options.net, folder, options.seconds, options.period)
            sumo_wall = time.perf_counter() - started
        else:
            run = {"fcd": options.fcd, "vtypes": options.vtypes, "collisions": options.collisions,
                   "tls_states": options.tls_states}
            sumo_wall = None
        out, _, _, load_peak = _child([sys.executable, "-c", LOAD, str(options.net)], cache)
        cold = float(out)
        warm = float(_child([sys.executable, "-c", LOAD, str(options.net)], cache)[0])
        plain_mb_s, simulated = reader_speed(run["fcd"], options.net, run["vtypes"])
        packed = folder / "fcd.xml.gz"
        with open(run["fcd"], "rb") as src, gzip.open(packed, "wb", compresslevel=6) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        gzip_mb_s = reader_speed(packed, options.net, run["vtypes"])[0]
        audit = [sys.executable, "-m", "sumo_rss", "audit", str(run["fcd"]), "--net", str(options.net), "--out",
                 str(folder / "audit"), "--quiet"]
        for flag, value in (("--vtypes", run["vtypes"]), ("--collisions", run["collisions"]),
                            ("--tls-states", run["tls_states"])):
            if value:
                audit += [flag, str(value)]
        summary, wall, cpu, peak = _child(audit, folder / "cold_cache")
        network = RoadNetwork.from_file(options.net)
        fcd_mb = _xml_bytes(run["fcd"]) / 1e6  # before the folder (SUMO's run) is removed
    pair_steps = int(re.search(r"(\d+) pair-steps", summary).group(1))  # type: ignore[union-attr]
    figures = {"net": str(options.net), "edges": len(network.edge_ids), "lanes": len(network.lane_ids),
               "simulated_s": simulated, "fcd_mb": fcd_mb, "sumo_wall_s": sumo_wall,
               "network_load_cold_s": cold, "network_load_cached_s": warm, "network_load_peak_rss_mb": load_peak,
               "fcd_plain_mb_per_s": plain_mb_s, "fcd_gzip_mb_per_s": gzip_mb_s,
               "audit_wall_s": wall, "audit_cpu_s": cpu, "audit_peak_rss_mb": peak,
               "audit_rtf": simulated / wall, "audit_rtf_without_load": simulated / max(wall - cold, 1e-9),
               "pair_steps": pair_steps, "pair_steps_per_s": pair_steps / wall, "summary": summary.strip()}
    record("city_audit" + (f"_{options.label}" if options.label else ""), figures, options)
    print(json.dumps({k: v for k, v in figures.items() if k != "summary"}, indent=1))


if __name__ == "__main__":
    main()
