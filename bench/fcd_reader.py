"""The FCD reader alone (issue 47: "a streaming FCD reader at disk speed, >= 20 MB/s of plain XML"): `FcdReader`
over a whole FCD into snapshots, plain and gzipped (level 6), in this process, timed by CPU (the machine is shared:
wall time measures the other users too) and by wall. By default over SUMO's run of city_audit.py (the DRT city,
random trips, `--seconds`); with --fcd NET --net ... --vtypes ... over another run, e.g. Bologna's acosta:
`python bench/fcd_reader.py --fcd fcd.xml --net acosta_buslanes.net.xml --vtypes
acosta_vtypes.add.xml,acosta.rou.xml,acosta_busses.rou.xml --label acosta`.

Figures: MB of XML per CPU second and per wall second, plain and gzipped; steps and vehicle-steps read.
"""
from __future__ import annotations

import gzip
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _results import arguments, record  # noqa: E402
from city_audit import DRT, _xml_bytes, simulate  # noqa: E402

from sumo_rss.road.network import RoadNetwork  # noqa: E402
from sumo_rss.rss.fcd import FcdReader, read_vehicle_info  # noqa: E402


def _options(parser) -> None:
    parser.add_argument("--net", type=Path, default=DRT, help="the network (default: the eclipse-sumo DRT city)")
    parser.add_argument("--fcd", type=Path, help="read this FCD instead of running SUMO")
    parser.add_argument("--vtypes", help="route/vType files of the FCD, comma-separated")
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds of SUMO's run (default 60)")
    parser.add_argument("--label", help="record as fcd_reader_LABEL (default: fcd_reader for the DRT run)")


def read_all(fcd: Path, network: RoadNetwork, vtypes: str | None) -> dict:
    """MB/s of XML (per CPU and per wall second) of reading ``fcd`` into snapshots, and what was read."""
    vehicles = read_vehicle_info([Path(p) for p in vtypes.split(",")] if vtypes else None, network.path)
    network.frenet(np.zeros(1, dtype=int), np.zeros(1), np.zeros(1))  # numba's import, once a process: not timed
    cpu, wall = time.process_time(), time.perf_counter()
    steps = vehicle_steps = 0
    for snapshot in FcdReader(fcd, network, vehicles):
        steps, vehicle_steps = steps + 1, vehicle_steps + len(snapshot)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    mb = _xml_bytes(fcd) / 1e6
    return {"mb": mb, "mb_per_cpu_s": mb / cpu, "mb_per_wall_s": mb / wall, "steps": steps,
            "vehicle_steps": vehicle_steps}


def main() -> None:
    options = arguments(__doc__, "fcd_reader.py", _options)
    with tempfile.TemporaryDirectory(prefix="fcd_reader_") as tmp:
        folder = Path(tmp)
        if options.fcd is None:
            run = simulate(options.net, folder, options.seconds, 0.4)
            fcd, vtypes = run["fcd"], run["vtypes"]
        else:
            fcd, vtypes = options.fcd, options.vtypes
        network = RoadNetwork.from_file(options.net)
        plain = read_all(fcd, network, vtypes)
        packed = folder / "fcd.xml.gz"
        with open(fcd, "rb") as src, gzip.open(packed, "wb", compresslevel=6) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        packed_read = read_all(packed, network, vtypes)
    figures = {"net": str(options.net), "fcd_mb": plain["mb"], "steps": plain["steps"],
               "vehicle_steps": plain["vehicle_steps"], "plain_mb_per_cpu_s": plain["mb_per_cpu_s"],
               "plain_mb_per_wall_s": plain["mb_per_wall_s"], "gzip_mb_per_cpu_s": packed_read["mb_per_cpu_s"],
               "gzip_mb_per_wall_s": packed_read["mb_per_wall_s"]}
    record("fcd_reader" + (f"_{options.label}" if options.label else ""), figures, options)
    print(figures)


if __name__ == "__main__":
    main()
