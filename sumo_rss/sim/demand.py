"""Write a scenario's traffic demand (vTypes, routes, flows and the ego) as a SUMO route file."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ..files import atomic_path, make_folder
from ..scenario import BACKGROUND_DISTRIBUTION, EGO_TYPE, EgoSpec, ScenarioSpec, VehicleTypeSpec


def sumo_number(value: float) -> str:
    """``value`` as SUMO reads it back exactly (the shortest round-trip text; "30", not "30.0"): six significant
    digits wrote a departure at 12345.65 s as 12345.6."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _vtype_element(vt: VehicleTypeSpec, type_id: str, *, probability: float | None,
                   speed_dev: float | None = None, max_speed: float | None = None) -> ET.Element:
    attrs = {
        "id": type_id,
        "vClass": vt.vclass,
        "length": sumo_number(vt.length),
        "width": sumo_number(vt.width),
        "minGap": sumo_number(vt.min_gap),
        "accel": sumo_number(vt.accel),
        "decel": sumo_number(vt.decel),
        "emergencyDecel": sumo_number(vt.emergency_decel),
        "sigma": sumo_number(vt.sigma),
        "tau": sumo_number(vt.tau),
        "maxSpeed": sumo_number(vt.max_speed if max_speed is None else max_speed),
        "speedFactor": sumo_number(vt.speed_factor),
        "speedDev": sumo_number(vt.speed_dev if speed_dev is None else speed_dev),
        "carFollowModel": vt.car_follow_model,
        "laneChangeModel": vt.lane_change_model,
    }
    if probability is not None:
        attrs["probability"] = sumo_number(probability)
    for name, value in {**vt.car_follow_params, **vt.lane_change_params}.items():
        attrs[name] = sumo_number(value)
    return ET.Element("vType", attrs)


def ego_vtype(ego: EgoSpec) -> ET.Element:
    """The ego's vType: its desired speed is ``min(desired_speed, speed_factor x lane speed limit)`` under SUMO
    control, and SUMO never teleports it (``timeToTeleport`` -1): a planner-driven ego that waited longer than the
    scenario's ``time_to_teleport_s`` was taken off the road and put back at 33 m/s (+-330 m/s² in its
    snapshots)."""
    vt = ego.vehicle
    element = _vtype_element(vt, EGO_TYPE, probability=None, speed_dev=0.0,
                             max_speed=min(vt.max_speed, ego.desired_speed))
    element.set("timeToTeleport", "-1")
    return element


def write_route_file(spec: ScenarioSpec, path: Path) -> Path:
    """Write ``path`` (a ``.rou.xml``) for ``spec``; elements are ordered by departure as SUMO requires."""
    root = ET.Element("routes")
    dist = ET.SubElement(root, "vTypeDistribution", {"id": BACKGROUND_DISTRIBUTION})
    for vt in spec.demand.vtypes:
        dist.append(_vtype_element(vt, vt.id, probability=vt.probability))
    if spec.ego is not None:
        root.append(ego_vtype(spec.ego))

    timed: list[tuple[float, int, ET.Element]] = []
    for order, flow in enumerate(spec.demand.flows):
        ET.SubElement(root, "route", {"id": f"route_{flow.id}", "edges": " ".join(flow.route)})
        attrs = {
            "id": flow.id,
            "type": flow.vtype or BACKGROUND_DISTRIBUTION,
            "route": f"route_{flow.id}",
            "begin": sumo_number(flow.begin_s),
            "end": sumo_number(spec.duration_s if flow.end_s is None else flow.end_s),
            "departLane": flow.depart_lane,
            "departSpeed": flow.depart_speed if isinstance(flow.depart_speed, str) else sumo_number(flow.depart_speed),
        }
        if flow.veh_per_hour is not None:
            attrs["vehsPerHour"] = sumo_number(flow.veh_per_hour)
        else:
            attrs["probability"] = sumo_number(flow.probability)  # type: ignore[arg-type]
        timed.append((flow.begin_s, order, ET.Element("flow", attrs)))
    if spec.ego is not None:
        ego = spec.ego
        ET.SubElement(root, "route", {"id": f"route_{ego.id}", "edges": " ".join(ego.route)})
        timed.append((ego.depart_s, len(timed), ET.Element("vehicle", {
            "id": ego.id, "type": EGO_TYPE, "route": f"route_{ego.id}", "depart": sumo_number(ego.depart_s),
            "departLane": ego.depart_lane, "departPos": sumo_number(ego.depart_pos_m),
            "departSpeed": sumo_number(ego.depart_speed)})))
    for _, _, elem in sorted(timed, key=lambda item: (item[0], item[1])):
        root.append(elem)
    ET.indent(root)
    make_folder(path.parent)
    with atomic_path(path) as tmp:
        ET.ElementTree(root).write(tmp, encoding="UTF-8", xml_declaration=True)
    return path
