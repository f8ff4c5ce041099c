"""Corrections to SUMO's FCD output of a session.

SUMO writes ``acceleration="0"`` and ``speedLat="0"`` for a vehicle placed by ``moveToXY`` (the ego driven by a
planner), whatever it did. The session derives both from the placed states for its snapshots; writing them
into the FCD makes an offline audit of the file see what the online audit saw.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from xml.sax.saxutils import quoteattr

_TIME = re.compile(r'<timestep time="([^"]+)"')
_ACCEL = re.compile(r' acceleration="[^"]*"')
_SPEED_LAT = re.compile(r' speedLat="[^"]*"')


def correct_placed_vehicle(fcd_file: Path, vehicle_id: str, derived: dict[float, tuple[float, float]]) -> None:
    """Rewrite ``vehicle_id``'s ``acceleration`` [m/s²] and ``speedLat`` [m/s] in ``fcd_file`` at the time steps
    [s] of ``derived`` (time → (acceleration, lateral speed)), in place and atomically. SUMO writes one vehicle
    element per line, each after the line of its time step."""
    prefix = f"<vehicle id={quoteattr(vehicle_id)} "
    partial = fcd_file.with_name(fcd_file.name + ".partial")
    with fcd_file.open(encoding="utf-8") as src, partial.open("w", encoding="utf-8") as dst:
        values = None
        for line in src:
            element = line.lstrip()
            if element.startswith("<timestep "):
                values = derived.get(round(float(_TIME.match(element).group(1)), 3))
            elif values is not None and element.startswith(prefix):
                line = _ACCEL.sub(f' acceleration="{values[0]:.6f}"', line, count=1)
                line = _SPEED_LAT.sub(f' speedLat="{values[1]:.6f}"', line, count=1)
            dst.write(line)
    os.replace(partial, fcd_file)
