"""Who owes what on a road (no junction) at the danger threshold: our ResponsibilityTracker against Intel's ad_rss
5.0.0 (test-only oracle), for every case of rss.md §5's rule with a known state before t_b.

Two cars on a straight multi-lane road, same direction or opposite directions. A state at step 0 and a state at
step 1 (independent random draws; step 1 is always dangerous: lon and lat unsafe). Step 0 is ``lon`` (only
longitudinally safe), ``lat`` (only laterally safe) or ``both`` (both safe).

ad_rss: ``RssSituationChecking().checkSituation`` + ``RssResponseResolving().provideProperResponse`` on hand-built
``RelativeConstellation``s, one checker per ego (ad_rss computes the ego's response only): car a as ego (object b)
and car b as ego (object a), each checker fed step 0 and step 1 with the same constellation id and increasing
time indices, so that its 'state before the danger threshold' history is used. Relative positions are computed
as ad_rss's own extraction does (metric ranges of the bodies; ad_rss's lateral axis is + = right, so y = −d and
lateral speeds are negated).

Ours: PairSituations built from the same numbers (a_is_rear by centre position as situations.classify does,
lon_safe/lat_safe by sumo_rss.rss.formulas), fed to ResponsibilityTracker at t = 0 and 0.1 s; owed_by(car) at 0.1.

Mapping, per car (what it owes at step 1):
- longitudinal: ad_rss longitudinal_response BrakeMin → "brake" (ours: must_brake, b_min), BrakeMinCorrect →
  "brake-correct" (ours: must_brake & brake_correct). ad_rss never gives a front car a longitudinal response (its
  acceleration range is always bounded below by brake_max, in every state, safe or not); so a same-direction car
  with response None that is in front (InFront/OverlapFront from its own view) while the other car's response is
  BrakeMin is mapped to "front" (ours: front_limited, 'must not brake harder than b_max'). Otherwise "".
- lateral: ad_rss lateral_response_left or _right == BrakeMin ↔ ours owed_lat.

Opposite direction: b_corr = b_min for both cars, because ad_rss brakes the object car at b_min even when it is in
its correct lane while we (rss.md §2) use b_corr for both; with equal values the verdicts agree, the response
type (BrakeMinCorrect) still shows.

Left out, where the two differ on purpose or the spec is silent (docs/rss.md): a pair first seen already
dangerous (rss.md §5's rule: longitudinal unless the cars overlap longitudinally, else lateral; ad_rss 5.0:
longitudinal only for same-direction cars that overlap laterally, else both), and a step 1 where one car's length
lies wholly beside the other's (ad_rss: 'Overlap', no car in front, both brake; ours: the car whose centre is
ahead is the front car). Going from longitudinally safe to such a position takes more than one 0.1 s step.
"""
from __future__ import annotations

import warnings
from collections import defaultdict
from dataclasses import dataclass

import numpy as np
import pytest

with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    import ad_rss

from adrss_oracle import _dynamics, fill_unstructured
from sumo_rss.rss.formulas import is_safe_distance, lat_safe_distance, lon_safe_distance_opposite, \
    lon_safe_distance_same_dir
from sumo_rss.rss.params import RssParamArrays, RssParams
from sumo_rss.rss.responsibility import ResponsibilityTracker
from sumo_rss.rss.step_input import StepInput
from sumo_rss.rss.situations import PairSituations

_P, _W, _C, _S = ad_rss.physics, ad_rss.rss.world, ad_rss.rss.core, ad_rss.rss.state
_C.setLogLevel("warn")
_LON = dict(_C.LongitudinalRelativePosition.names)
_LAT = dict(_C.LateralRelativePosition.names)

CASES_PER_CLASS = 300
CATEGORIES = ("lon", "lat", "both")
MARGIN = 5e-3  # [m] every gap at least this far from its d_min + 1 mm, and from ad_rss's 1e-3 tie tolerances


@dataclass(frozen=True)
class Car:
    s: float  # centre along the road (a's driving direction) [m]
    d: float  # centre across the road, + = left of a's driving direction [m]
    length: float
    width: float
    v_lon: float  # speed along its own driving direction, >= 0 [m/s]
    v_lat: float  # lateral speed, + = left (of a's driving direction) [m/s]
    p: RssParams


# ------------------------------------------------------------------------------------------------ ad_rss side
def _relative_position(ego: tuple[float, float], other: tuple[float, float], names: tuple[str, str, str, str]
                       ) -> tuple[str, float]:
    """ad_rss's relative position of two metric ranges on one axis, ``names`` = (ego beyond the other, ego short of
    it, overlapping with the ego further on, overlapping with the ego further back), and the distance between
    them (0 when they overlap; 'Overlap' when one range holds the other)."""
    if ego[0] > other[1]:
        return names[0], ego[0] - other[1]
    if other[0] > ego[1]:
        return names[1], other[0] - ego[1]
    if ego[0] > other[0] and ego[1] > other[1]:
        return names[2], 0.0
    if ego[0] < other[0] and ego[1] < other[1]:
        return names[3], 0.0
    return "Overlap", 0.0


_LON_NAMES = ("InFront", "AtBack", "OverlapFront", "OverlapBack")
_LAT_NAMES = ("AtRight", "AtLeft", "OverlapRight", "OverlapLeft")  # ad_rss's lateral axis: + = right


def _frame(car: Car, mirrored: bool) -> tuple[tuple[float, float], tuple[float, float], float]:
    """(longitudinal range, lateral range (+ right), lateral speed (+ right)) in an ego's frame: a's direction, or
    the opposite direction (``mirrored``, b's frame in an opposite pair)."""
    x = -car.s if mirrored else car.s
    y = car.d if mirrored else -car.d
    u = car.v_lat if mirrored else -car.v_lat
    return ((x - car.length / 2, x + car.length / 2), (y - car.width / 2, y + car.width / 2), u)


def _object_state(car: Car, u: float, ego: bool) -> object:
    s = _C.RelativeObjectState()
    s.object_type = _W.ObjectType.EgoVehicle if ego else _W.ObjectType.OtherVehicle
    s.dynamics = _dynamics(car.p)
    fill_unstructured(s.unstructured_object_state, car.v_lon, car.v_lon)
    st = s.structured_object_state
    st.has_priority = False
    st.is_in_correct_lane = True
    st.distance_to_enter_intersection = _P.Distance(0.0)
    st.distance_to_leave_intersection = _P.Distance(1000.0)
    v = st.velocity
    v.speed_lon_min = v.speed_lon_max = _P.Speed(car.v_lon)
    v.speed_lat_min = v.speed_lat_max = _P.Speed(u)
    return s


def _constellation(ego: Car, other: Car, ids: tuple[int, int], opposite: bool, mirrored: bool):
    lon_e, lat_e, u_e = _frame(ego, mirrored)
    lon_o, lat_o, u_o = _frame(other, mirrored)
    rc = _C.RelativeConstellation()
    rc.constellation_id = 1
    rc.ego_id, rc.object_id = ids
    rc.constellation_type = _W.ConstellationType.OppositeDirection if opposite else _W.ConstellationType.SameDirection
    rc.ego_state = _object_state(ego, u_e, True)
    rc.other_state = _object_state(other, u_o, False)
    lon_pos, lon_dist = _relative_position(lon_e, lon_o, _LON_NAMES)
    lat_pos, lat_dist = _relative_position(lat_e, lat_o, _LAT_NAMES)
    rp = rc.relative_position
    rp.longitudinal_position, rp.longitudinal_distance = _LON[lon_pos], _P.Distance(lon_dist)
    rp.lateral_position, rp.lateral_distance = _LAT[lat_pos], _P.Distance(lat_dist)
    return rc, lon_pos, lat_pos


@dataclass(frozen=True)
class AdVerdict:
    lon_safe: bool
    lat_safe: bool
    lon_response: str  # None / BrakeMinCorrect / BrakeMin
    lat_response: str  # worst of left/right: None / BrakeMin
    lon_pos: str
    lat_pos: str


class _Ego:
    """One ad_rss checker + resolver with one ego: feed its steps in time order."""

    def __init__(self) -> None:
        self.checker, self.resolver, self.t = _C.RssSituationChecking(), _C.RssResponseResolving(), 0

    def step(self, ego: Car, other: Car, ids, opposite: bool, mirrored: bool) -> AdVerdict:
        self.t += 1
        rc, lon_pos, lat_pos = _constellation(ego, other, ids, opposite, mirrored)
        snap = _C.RssSituationSnapshot()
        snap.time_index = self.t
        snap.default_ego_vehicle_rss_dynamics = _dynamics(ego.p)
        snap.constellations.append(rc)
        states = _S.RssStateSnapshot()
        assert self.checker.checkSituation(snap, states) and len(states.individual_responses) == 1
        proper = _S.ProperResponse()
        assert self.resolver.provideProperResponse(states, proper)
        st = states.individual_responses[0]
        lat = max(proper.lateral_response_left, proper.lateral_response_right, key=int).name
        return AdVerdict(bool(st.longitudinal_state.is_safe),
                         bool(st.lateral_state_left.is_safe and st.lateral_state_right.is_safe),
                         proper.longitudinal_response.name, lat, lon_pos, lat_pos)


def ad_rss_steps(steps: list[tuple[Car, Car]], opposite: bool) -> tuple[list[AdVerdict], list[AdVerdict]]:
    """ad_rss's verdicts of every step with car a as ego and with car b as ego."""
    ego_a, ego_b = _Ego(), _Ego()
    va = [ego_a.step(a, b, (0, 1), opposite, False) for a, b in steps]
    vb = [ego_b.step(b, a, (1, 0), opposite, opposite) for a, b in steps]
    return va, vb


def ad_rss_owed(va: AdVerdict, vb: AdVerdict, opposite: bool) -> tuple[tuple[str, str], tuple[bool, bool]]:
    """Per car (a, b): longitudinal duty ('brake', 'brake-correct', 'front', '') and lateral duty."""
    name = {"BrakeMin": "brake", "BrakeMinCorrect": "brake-correct", "None": ""}
    lon = [name[va.lon_response], name[vb.lon_response]]
    for me, other, v in ((0, 1, va), (1, 0, vb)):
        if not opposite and lon[me] == "" and v.lon_pos in ("InFront", "OverlapFront") and lon[other] == "brake":
            lon[me] = "front"
    return (lon[0], lon[1]), (va.lat_response == "BrakeMin", vb.lat_response == "BrakeMin")


# ------------------------------------------------------------------------------------------------- our side
def pair_situation(a: Car, b: Car, opposite: bool) -> PairSituations:
    lon_gap = abs(b.s - a.s) - (a.length + b.length) / 2
    lat_gap = abs(b.d - a.d) - (a.width + b.width) / 2
    a_left = a.d > b.d
    left, right = (a, b) if a_left else (b, a)
    lat_d_min = float(lat_safe_distance(left.v_lat, right.v_lat, left.p, right.p))
    if opposite:
        a_rear = True  # opposite pairs: "a is the reference car"
        lon_d_min = float(lon_safe_distance_opposite(a.v_lon, b.v_lon, a.p, b.p, both_correct=True))
    else:
        a_rear = a.s < b.s
        rear, front = (a, b) if a_rear else (b, a)
        lon_d_min = float(lon_safe_distance_same_dir(rear.v_lon, front.v_lon, rear.p, front.p))
    arr = lambda x, dtype=float: np.array([x], dtype=dtype)  # noqa: E731
    return PairSituations(a=arr(0, int), b=arr(1, int), kind=arr(1 if opposite else 0, int),
                          a_is_rear=arr(a_rear, bool), a_is_left=arr(a_left, bool), lon_gap=arr(lon_gap),
                          lat_gap=arr(lat_gap), v_lon_a=arr(a.v_lon), v_lon_b=arr(b.v_lon), v_lat_a=arr(a.v_lat),
                          v_lat_b=arr(b.v_lat), lon_d_min=arr(lon_d_min), lat_d_min=arr(lat_d_min),
                          lon_safe=is_safe_distance(arr(lon_gap), arr(lon_d_min)),
                          lat_safe=is_safe_distance(arr(lat_gap), arr(lat_d_min)))


def our_owed(step0: tuple[Car, Car], step1: tuple[Car, Car], opposite: bool):
    a, b = step1
    tracker = ResponsibilityTracker()
    common = dict(keys=np.array([1], dtype=np.int64), ids=np.array(["a", "b"], dtype=object),
                  uids=np.array([0, 1], dtype=np.int64), vclass=np.array(["background"] * 2, dtype=object),
                  accel=np.zeros(2), speed=np.zeros(2), params=RssParamArrays.stack([a.p, b.p]))
    for t, (x, y) in ((0.0, step0), (0.1, step1)):
        tracker.step(StepInput(time=t, situations=pair_situation(x, y, opposite), new_vehicle=np.zeros(2, dtype=bool),
                               **common))
    lon, lat = [], []
    for vid in ("a", "b"):
        owed = tracker.owed_by(vid)
        assert len(owed) == 1, "step 1 is dangerous: one open episode"
        brake, correct, front = bool(owed.must_brake[0]), bool(owed.brake_correct[0]), bool(owed.front_limited[0])
        lon.append(("brake-correct" if correct else "brake") if brake else "front" if front else "")
        lat.append(bool(owed.owed_lat[0]))
    return tuple(lon), tuple(lat)


# ------------------------------------------------------------------------------------------------ generation
def _params(rng: np.random.Generator, opposite: bool) -> RssParams:
    b_min = rng.uniform(3.0, 6.0)
    return RssParams(response_time=rng.uniform(0.3, 2.0), lon_accel_max=rng.uniform(0.5, 4.0), lon_brake_min=b_min,
                     lon_brake_min_correct=b_min if opposite else b_min * rng.uniform(0.6, 1.0),
                     lon_brake_max=b_min + rng.uniform(0, 5), lat_accel_max=rng.uniform(0.1, 1.0),
                     lat_brake_min=rng.uniform(0.5, 2.0), lat_fluctuation_margin=rng.uniform(0.0, 0.5),
                     min_lon_gap=float(rng.choice([0.0, 1.0])))


def _place(rng, p_a: RssParams, p_b: RssParams, dims, opposite: bool, lon_safe: bool,
           lat_safe: bool) -> tuple[Car, Car] | None:
    """Cars a (at s = 0, d = 0) and b with the wanted verdicts, or None when a tie is too close."""
    (la, wa), (lb, wb) = dims
    va, vb = rng.uniform(0.0, 30.0, 2)
    ua, ub = rng.uniform(-1.5, 1.5, 2)
    b_ahead = True if opposite else bool(rng.random() < 0.5)
    b_left = bool(rng.random() < 0.5)
    a = Car(0.0, 0.0, la, wa, va, ua, p_a)
    probe = pair_situation(a, Car(100.0 if b_ahead else -100.0, 10.0 if b_left else -10.0, lb, wb, vb, ub, p_b),
                           opposite)
    lon_d, lat_d = float(probe.lon_d_min[0]), float(probe.lat_d_min[0])
    lon_lo, lat_lo = -(la + lb) / 2 + 0.05, -(wa + wb) / 2 + 0.05
    lon_gap = lon_d + 1e-3 + rng.uniform(MARGIN, 25.0) if lon_safe else rng.uniform(lon_lo, lon_d + 1e-3 - MARGIN)
    lat_gap = lat_d + 1e-3 + rng.uniform(MARGIN, 3.0) if lat_safe else rng.uniform(lat_lo, lat_d + 1e-3 - MARGIN)
    s_b = (lon_gap + (la + lb) / 2) * (1 if b_ahead else -1)
    d_b = (lat_gap + (wa + wb) / 2) * (1 if b_left else -1)
    b = Car(float(s_b), float(d_b), lb, wb, vb, ub, p_b)
    # ad_rss's metric-range comparisons have a 1e-3 tolerance: keep every edge pair apart.
    edges_lon = [abs(x - y) for x in (-la / 2, la / 2) for y in (s_b - lb / 2, s_b + lb / 2)]
    edges_lat = [abs(x - y) for x in (-wa / 2, wa / 2) for y in (d_b - wb / 2, d_b + wb / 2)]
    if min(edges_lon + edges_lat) < MARGIN:
        return None
    return a, b


def generate(direction: str, category: str, seed: int, n: int):
    rng = np.random.default_rng(seed)
    opposite = direction == "opposite"
    out = []
    while len(out) < n:
        p_a, p_b = _params(rng, opposite), _params(rng, opposite)
        dims = [(float(rng.choice([4.5, 4.5, 12.0])), float(rng.choice([1.8, 1.8, 2.5]))) for _ in range(2)]
        step1 = _place(rng, p_a, p_b, dims, opposite, False, False)
        step0 = _place(rng, p_a, p_b, dims, opposite, category in ("lon", "both"), category in ("lat", "both"))
        if step0 is None or step1 is None:
            continue
        out.append((step0, step1))
    return out


def compare(direction: str, category: str, seed: int, n: int):
    """(number compared, mismatches as a list of dicts)."""
    opposite = direction == "opposite"
    mismatches, verdict_mismatches, compared = [], 0, 0
    for step0, step1 in generate(direction, category, seed, n):
        steps = [step0, step1]
        va, vb = ad_rss_steps(steps, opposite)
        # The verdicts must agree before the duties can be compared (inputs keep away from every tolerance).
        for (a, b), v, w in zip(steps, va, vb):
            sit = pair_situation(a, b, opposite)
            ours = (bool(sit.lon_safe[0]), bool(sit.lat_safe[0]))
            if ours != (v.lon_safe, v.lat_safe) or ours != (w.lon_safe, w.lat_safe):
                verdict_mismatches += 1
        if "Overlap" in (va[-1].lon_pos, vb[-1].lon_pos):  # one car's length wholly beside the other's: left out
            continue
        compared += 1
        theirs = ad_rss_owed(va[-1], vb[-1], opposite)
        ours = our_owed(step0, step1, opposite)
        if theirs != ours:
            a, b = step1
            sit = pair_situation(a, b, opposite)
            mismatches.append(dict(
                direction=direction, category=category, ad_rss=theirs, ours=ours,
                lon_overlap=bool(sit.lon_gap[0] < 0), lat_overlap=bool(sit.lat_gap[0] < 0),
                lon_pos=(va[-1].lon_pos, vb[-1].lon_pos), lat_pos=(va[-1].lat_pos, vb[-1].lat_pos),
                step0=step0, step1=step1, gaps=(float(sit.lon_gap[0]), float(sit.lat_gap[0]))))
    assert verdict_mismatches == 0, verdict_mismatches
    return compared, mismatches


def mismatch_classes(mismatches):
    classes = defaultdict(list)
    for m in mismatches:
        key = (m["direction"], m["category"], m["lon_overlap"], m["lat_overlap"], m["ad_rss"], m["ours"])
        classes[key].append(m)
    return classes


@pytest.mark.parametrize("direction", ["same", "opposite"])
@pytest.mark.parametrize("category", CATEGORIES)
def test_owed_response_on_a_road_matches_ad_rss(direction, category):
    seed = 1000 * ("same", "opposite").index(direction) + CATEGORIES.index(category)
    n, mismatches = compare(direction, category, seed, CASES_PER_CLASS)
    assert n >= 0.8 * CASES_PER_CLASS  # few are left out (a car's length wholly beside the other's)
    classes = mismatch_classes(mismatches)
    summary = {k: len(v) for k, v in classes.items()}
    assert not mismatches, f"{len(mismatches)} of {n} differ: {summary}"
