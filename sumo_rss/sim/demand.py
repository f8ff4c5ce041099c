"""Write a scenario's traffic demand (vTypes, routes, flows and the ego) as a SUMO route file."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ..scenario import BACKGROUND_DISTRIBUTION, EGO_TYPE, EgoSpec, ScenarioSpec, VehicleTypeSpec


def _fmt(value: float) -> str:
    return f"{value:.6g}"


def _vtype_element(vt: VehicleTypeSpec, type_id: str, *, probability: float | None,
                   speed_dev: float | None = None, max_speed: float | None = None) -> ET.Element:
    attrs = {
        "id": type_id,
        "vClass": vt.vclass,
        "length": _fmt(vt.length),
        "width": _fmt(vt.width),
        "minGap": _fmt(vt.min_gap),
        "accel": _fmt(vt.accel),
        "decel": _fmt(vt.decel),
        "emergencyDecel": _fmt(vt.emergency_decel),
        "sigma": _fmt(vt.sigma),
        "tau": _fmt(vt.tau),
        "maxSpeed": _fmt(vt.max_speed if max_speed is None else max_speed),
        "speedFactor": _fmt(vt.speed_factor),
        "speedDev": _fmt(vt.speed_dev if speed_dev is None else speed_dev),
        "carFollowModel": vt.car_follow_model,
        "laneChangeModel": vt.lane_change_model,
    }
    if probability is not None:
        attrs["probability"] = _fmt(probability)
    for name, value in {**vt.car_follow_params, **vt.lane_change_params}.items():
        attrs[name] = _fmt(value)
    return ET.Element("vType", attrs)


def ego_vtype(ego: EgoSpec) -> ET.Element:
    """The ego's vType: its desired speed is ``min(desired_speed, lane speed limit)`` under SUMO control."""
    vt = ego.vehicle
    return _vtype_element(vt, EGO_TYPE, probability=None, speed_dev=0.0,
                          max_speed=min(vt.max_speed, ego.desired_speed))


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
            "begin": _fmt(flow.begin_s),
            "end": _fmt(spec.duration_s if flow.end_s is None else flow.end_s),
            "departLane": flow.depart_lane,
            "departSpeed": flow.depart_speed if isinstance(flow.depart_speed, str) else _fmt(flow.depart_speed),
        }
        if flow.veh_per_hour is not None:
            attrs["vehsPerHour"] = _fmt(flow.veh_per_hour)
        else:
            attrs["probability"] = _fmt(flow.probability)  # type: ignore[arg-type]
        timed.append((flow.begin_s, order, ET.Element("flow", attrs)))
    if spec.ego is not None:
        ego = spec.ego
        ET.SubElement(root, "route", {"id": f"route_{ego.id}", "edges": " ".join(ego.route)})
        timed.append((ego.depart_s, len(timed), ET.Element("vehicle", {
            "id": ego.id, "type": EGO_TYPE, "route": f"route_{ego.id}", "depart": _fmt(ego.depart_s),
            "departLane": ego.depart_lane, "departPos": _fmt(ego.depart_pos_m),
            "departSpeed": _fmt(ego.depart_speed)})))
    for _, _, elem in sorted(timed, key=lambda item: (item[0], item[1])):
        root.append(elem)
    ET.indent(root)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path
