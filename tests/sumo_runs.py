"""Real SUMO runs of hand-commanded vehicles on a test network, written as SUMO writes them for an offline audit (FCD
with --precision 6, collision output, signal states), and their audit."""
from __future__ import annotations

import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import libsumo

from sumo_rss.road.network import RoadNetwork
from sumo_rss.rss.auditor import AuditResult, ParamResolver
from sumo_rss.rss.fcd import audit_fcd, read_vehicle_info
from sumo_rss.sumo_home import sumo_tool

DATA = Path(__file__).resolve().parent / "data"
STEP_S = 0.1  # [s]
CAR = '<vType id="car" length="4.5" width="1.8" minGap="2.5" accel="2.6" decel="4.5" sigma="0"/>'


def build_net(sources: Path, out: Path, *options: str) -> Path:
    """netconvert the plain-XML network ``sources``/<name>.nod.xml, .edg.xml (and .con.xml, .tll.xml if there)."""
    name = sources.name
    args = [str(sumo_tool("netconvert")), "-n", str(sources / f"{name}.nod.xml"), "-e", str(sources / f"{name}.edg.xml")]
    for kind, option in (("con", "-x"), ("tll", "-i")):
        if (sources / f"{name}.{kind}.xml").is_file():
            args += [option, str(sources / f"{name}.{kind}.xml")]
    subprocess.run([*args, *options, "-o", str(out)], check=True, capture_output=True)
    return out


@dataclass(frozen=True)
class SumoRun:
    net: Path
    routes: Path
    fcd: Path
    collisions: Path
    tls: Path

    def audit(self, **rules) -> AuditResult:
        """The offline audit of the run (ad_rss preset) with its collisions and signal states."""
        vehicles = read_vehicle_info(self.routes, self.net)
        tls = self.tls if self.tls.is_file() and self.tls.stat().st_size else None
        return audit_fcd(self.fcd, RoadNetwork.from_file(self.net), ParamResolver(vtype_dynamics=vehicles.dynamics),
                         vehicles=vehicles, collisions=self.collisions, tls_states=tls, **rules)


def run_sumo(net: Path, folder: Path, routes: str, seconds: float, setup: Callable[[], None],
             control: Callable[[float], None] | None = None) -> SumoRun:
    """Run SUMO on ``net`` with the route file text ``routes`` (vTypes and routes; ``CAR`` is a car), calling
    ``setup()`` once (libsumo commands adding the vehicles) and ``control(time)`` before every step."""
    route_file, additional = folder / "run.rou.xml", folder / "tls.add.xml"
    route_file.write_text(f"<routes>{routes}</routes>")
    run = SumoRun(net, route_file, folder / "fcd.xml", folder / "collisions.xml", folder / "tls.xml")
    additional.write_text(f'<additional><timedEvent type="SaveTLSStates" dest="{run.tls}"/></additional>')
    libsumo.start(["sumo", "-n", str(net), "-r", str(route_file), "-a", str(additional), "--step-length", str(STEP_S),
                   "--lanechange.duration", "3", "--precision", "6", "--collision.action", "warn",
                   "--collision.check-junctions", "--collision-output", str(run.collisions), "--fcd-output",
                   str(run.fcd), "--no-step-log", "true", "--no-warnings", "true"])
    try:
        setup()
        while libsumo.simulation.getTime() < seconds - 1e-9:
            if control is not None:
                control(libsumo.simulation.getTime())
            libsumo.simulationStep()
    finally:
        libsumo.close()
    return run


def hold_speed(vehicle: str, speed: float, lane_change: bool = False) -> None:
    """Drive ``vehicle`` at exactly ``speed`` [m/s] from now on, ignoring SUMO's own safety (and its lane changes)."""
    libsumo.vehicle.setSpeedMode(vehicle, 0)
    if not lane_change:
        libsumo.vehicle.setLaneChangeMode(vehicle, 0)
    libsumo.vehicle.setSpeed(vehicle, speed)
