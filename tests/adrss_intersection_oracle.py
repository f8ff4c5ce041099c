"""Intel's ad_rss (PyPI ``ad-rss`` 5.0.0) as a test oracle for the intersection check of rss.md §4/§5.

Test-only helper::

    from adrss_intersection_oracle import check_intersection, check_sequence, IntersectionStep

It drives the real ad_rss classes: ``RssSituationChecking().checkSituation`` on a hand-built
``RssSituationSnapshot`` holding one intersection ``RelativeConstellation`` (always constellation id 1,
ego id 0, object id 1), then ``RssResponseResolving().provideProperResponse`` on the result. Inputs are
in OUR conventions (rss.md §1): SI units, braking values as positive magnitudes, and any object with the
attributes of :class:`sumo_rss.rss.params.RssParams` (a ``SimpleNamespace`` will do); the dynamics are
filled by :func:`adrss_oracle._dynamics` (every field set).

Distances, per car, along its own path (ad_rss's bumper convention, RssSituationExtraction.cpp
``convertObjectsIntersection``):

- ``d_enter``: FRONT bumper to the START of the conflict area. ad_rss clamps it at 0 once the front is
  inside; here it may be negative (front bumper already past the start): the signed value is only used to
  derive the relative position (below), ad_rss itself receives ``max(0, d_enter)``.
- ``d_exit``: REAR bumper to the END of the conflict area, i.e. how far the car must drive until it has
  completely left (ad_rss: ``max(0, exit - rear)``); 0 once the car has left. ad_rss fails (RuntimeError
  here) if ``d_exit < max(0, d_enter)`` for either car.

Relative position ("who is in front", used by ad_rss's second condition). Unless ``relative`` is given,
it is derived as ad_rss's world-model path does (``calcluateRelativeLongitudinalPositionIntersection``):
each car occupies ``[d_enter, d_enter + length]`` on a virtual line whose origin is the start of the
conflict area; the ego is ``InFront`` if ``d_enter_ego + len_ego < d_enter_other`` (its rear bumper is
closer to / further past the start than the other's front bumper), distance
``d_enter_other - (d_enter_ego + len_ego)``; ``AtBack`` (other in front) symmetrically; else an
``Overlap*`` with distance 0. ``relative=("InFront", 3.0)`` overrides this (names of
``ad_rss.rss.core.LongitudinalRelativePosition``: InFront, OverlapFront, Overlap, OverlapBack, AtBack).

Speeds are m/s >= 0: a float (exact speed) or a ``(v_min, v_max)`` pair (ad_rss uses v_max for
"able to stop", arrival and the following car; v_min for the leading car and the latest exit).

History: ad_rss keeps the last *safe* intersection state per constellation between time steps, and the
proper response of an unsafe step depends on it (see docs/adrss_intersection_notes.md). Each
:func:`check_intersection` call uses a fresh checker (so no history, unless ``previous`` steps are
given); :func:`check_sequence` / :class:`IntersectionOracle` feed consecutive time indices to ONE
checker + resolver pair.

The verdict is the EGO's: ad_rss computes only the ego's response. For the other car's, swap the
roles (and "ego" <-> "other" priority); safe/unsafe and the rule are symmetric as long as both cars have
the same ``max_speed_on_accel`` (ad_rss uses the ego's cap for both arrival times).

Keep test inputs away from ad_physics' 1e-3 tolerances (distances, speeds, durations): "able to stop"
needs d_enter > D + λ + 1e-3 m, "in front" needs distance > d_min + 1e-3 m, "no time overlap" needs
t_arrive > t_exit + 1e-3 s; and a braking phase that would take <= 1e-3 s (e.g. d_exit = 0 while moving)
is timed by ad_rss as the far root, about 2·v/b later (docs/adrss_intersection_notes.md, quirks).

Side effect on import: ad_rss's log level is set to ``warn`` (the resolver logs every dangerous state at
``info`` level on stdout). Errors (invalid input) are still printed on stdout by ad_rss.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Literal, Optional, Protocol, Sequence, Tuple, Union

with warnings.catch_warnings():
    # Importing the boost.python bindings warns (on stderr) about a converter registered twice.
    warnings.simplefilter("ignore", RuntimeWarning)
    import ad_rss  # note: this appends site-packages/ad_rss to sys.path (ad_rss's own __init__)

from adrss_oracle import _dynamics, fill_unstructured

__all__ = [
    "IntersectionStep",
    "IntersectionVerdict",
    "IntersectionOracle",
    "check_intersection",
    "check_sequence",
    "time_window",
    "relative_position",
]

_P = ad_rss.physics
_W = ad_rss.rss.world
_C = ad_rss.rss.core
_S = ad_rss.rss.state

_C.setLogLevel("warn")

Priority = Literal["ego", "other", "same"]
SpeedLike = Union[float, Tuple[float, float]]

_CONSTELLATION_TYPE = {
    "ego": _W.ConstellationType.IntersectionEgoHasPriority,
    "other": _W.ConstellationType.IntersectionObjectHasPriority,
    "same": _W.ConstellationType.IntersectionSamePriority,
}
_LON_POS = dict(_C.LongitudinalRelativePosition.names)

#: ad_rss's ``Duration`` maximum (1e6 s): "never reaches / never leaves" in :func:`time_window`.
NEVER = float(_P.Duration.getMax().mDuration)


class Params(Protocol):
    """Our per-vehicle RSS parameters (positive magnitudes, SI)."""

    response_time: float
    lon_accel_max: float
    lon_brake_min: float
    lon_brake_min_correct: float
    lon_brake_max: float
    lat_accel_max: float
    lat_brake_min: float
    lat_fluctuation_margin: float
    min_lon_gap: float
    max_speed_on_accel: float


@dataclass(frozen=True)
class IntersectionStep:
    """One time step of an ego/other pair at an intersection (see the module docstring for conventions)."""

    v_ego: SpeedLike
    d_enter_ego: float
    d_exit_ego: float
    p_ego: Params
    v_other: SpeedLike
    d_enter_other: float
    d_exit_other: float
    p_other: Params
    priority: Priority
    len_ego: float = 5.0
    len_other: float = 5.0
    relative: Optional[Tuple[str, float]] = None


@dataclass(frozen=True)
class IntersectionVerdict:
    """ad_rss's verdict for one step, seen from the ego.

    ``safe``: the constellation's longitudinal state is safe (for intersections ad_rss's lateral state is
    always unsafe, so dangerous == not safe). ``state``: the ``RssStateEvaluator`` name of the LAST
    condition ad_rss evaluated (IntersectionOtherPriorityEgoAbleToStop / IntersectionEgoPriorityOtherAbleToStop /
    IntersectionEgoInFront / IntersectionOtherInFront / IntersectionOverlap); ``rule``: which condition
    made it safe, as ad_rss's internal ``IntersectionState`` name (NonPrioAbleToBreak /
    SafeLongitudinalDistance / NoTimeOverlap), None if unsafe. ``response``: the ego's proper longitudinal
    response from ``RssResponseResolving`` (None / BrakeMin; BrakeMinCorrect never occurs here);
    ``lateral_response``: worst of the left/right lateral responses (always "None" for intersections).
    ``current_distance`` / ``safe_distance``: ad_rss's RssStateInformation of ``state`` (both 0 for
    IntersectionOverlap). ``accel_range``: the ego's allowed longitudinal acceleration range in ad_rss's
    sign convention (negative = braking), e.g. (-8, -4) for BrakeMin with b_max 8, b_min 4.
    ``relative_position`` / ``relative_distance``: what was passed to ad_rss.
    """

    safe: bool
    state: str
    rule: Optional[str]
    response: str
    lateral_response: str
    current_distance: float
    safe_distance: float
    accel_range: Tuple[float, float]
    relative_position: str
    relative_distance: float
    time_index: int


def _speed_range(v: SpeedLike) -> Tuple[float, float]:
    if isinstance(v, tuple):
        lo, hi = float(v[0]), float(v[1])
    else:
        lo = hi = float(v)
    if not (0.0 <= lo <= hi):
        raise ValueError(f"speed range must satisfy 0 <= v_min <= v_max, got {v!r}")
    return lo, hi


def relative_position(d_enter_ego: float, len_ego: float, d_enter_other: float,
                      len_other: float) -> Tuple[str, float]:
    """ad_rss's intersection-centric relative position (RssSituationExtraction.cpp,
    ``calcluateRelativeLongitudinalPositionIntersection``), from signed front-bumper distances to the start
    of the conflict area and vehicle lengths. Returns (LongitudinalRelativePosition name, distance [m])."""
    e_min, e_max = float(d_enter_ego), float(d_enter_ego) + float(len_ego)
    o_min, o_max = float(d_enter_other), float(d_enter_other) + float(len_other)
    if e_max < o_min:
        return "InFront", o_min - e_max
    if o_max < e_min:
        return "AtBack", e_min - o_max
    if e_min < o_min and e_max < o_max:
        return "OverlapFront", 0.0
    if e_min > o_min and e_max > o_max:
        return "OverlapBack", 0.0
    return "Overlap", 0.0


def _object_state(p: Params, v: SpeedLike, d_enter: float, d_exit: float, prio: bool, ego: bool) -> object:
    lo, hi = _speed_range(v)
    s = _C.RelativeObjectState()
    s.object_type = _W.ObjectType.EgoVehicle if ego else _W.ObjectType.OtherVehicle
    s.dynamics = _dynamics(p)
    fill_unstructured(s.unstructured_object_state, lo, hi)  # validated although unused
    st = s.structured_object_state
    st.has_priority = bool(prio)
    st.is_in_correct_lane = True
    st.distance_to_enter_intersection = _P.Distance(max(0.0, float(d_enter)))
    st.distance_to_leave_intersection = _P.Distance(float(d_exit))
    st.velocity.speed_lon_min = _P.Speed(lo)
    st.velocity.speed_lon_max = _P.Speed(hi)
    st.velocity.speed_lat_min = _P.Speed(0.0)
    st.velocity.speed_lat_max = _P.Speed(0.0)
    return s


def _constellation(step: IntersectionStep) -> Tuple[object, str, float]:
    if step.priority not in _CONSTELLATION_TYPE:
        raise ValueError(f"priority must be 'ego', 'other' or 'same', got {step.priority!r}")
    if step.relative is None:
        pos, dist = relative_position(step.d_enter_ego, step.len_ego, step.d_enter_other, step.len_other)
    else:
        pos, dist = str(step.relative[0]), float(step.relative[1])
        if pos not in _LON_POS:
            raise ValueError(f"unknown LongitudinalRelativePosition {pos!r}")
    rc = _C.RelativeConstellation()
    rc.constellation_id = 1
    rc.ego_id = 0
    rc.object_id = 1
    rc.constellation_type = _CONSTELLATION_TYPE[step.priority]
    rc.ego_state = _object_state(step.p_ego, step.v_ego, step.d_enter_ego, step.d_exit_ego,
                                 step.priority == "ego", True)
    rc.other_state = _object_state(step.p_other, step.v_other, step.d_enter_other, step.d_exit_other,
                                   step.priority == "other", False)
    rp = rc.relative_position
    rp.longitudinal_position = _LON_POS[pos]
    rp.longitudinal_distance = _P.Distance(dist)
    # What ad_rss's own extraction sets for every intersection constellation.
    rp.lateral_position = _C.LateralRelativePosition.Overlap
    rp.lateral_distance = _P.Distance(0.0)
    return rc, pos, dist


_RULE = {
    "IntersectionOtherPriorityEgoAbleToStop": "NonPrioAbleToBreak",
    "IntersectionEgoPriorityOtherAbleToStop": "NonPrioAbleToBreak",
    "IntersectionEgoInFront": "SafeLongitudinalDistance",
    "IntersectionOtherInFront": "SafeLongitudinalDistance",
    "IntersectionOverlap": "NoTimeOverlap",
}


class IntersectionOracle:
    """One ad_rss ``RssSituationChecking`` + ``RssResponseResolving`` pair: feed steps in time order."""

    def __init__(self) -> None:
        self._checker = _C.RssSituationChecking()
        self._resolver = _C.RssResponseResolving()
        self._last_index = 0

    def step(self, step: IntersectionStep, time_index: Optional[int] = None) -> IntersectionVerdict:
        """Check one step; ``time_index`` defaults to the previous one + 1 (ad_rss rejects 0 and repeats)."""
        t = self._last_index + 1 if time_index is None else int(time_index)
        if t <= self._last_index or t < 1:
            raise ValueError(f"time_index must increase and be >= 1 (last {self._last_index}, got {t})")
        self._last_index = t
        rc, pos, dist = _constellation(step)
        snap = _C.RssSituationSnapshot()
        snap.time_index = t
        snap.default_ego_vehicle_rss_dynamics = _dynamics(step.p_ego)
        snap.constellations.append(rc)
        states = _S.RssStateSnapshot()
        if not self._checker.checkSituation(snap, states) or len(states.individual_responses) != 1:
            raise RuntimeError(f"ad_rss checkSituation failed for {step!r} (see ad_rss's log on stdout)")
        rss_state = states.individual_responses[0]
        lon = rss_state.longitudinal_state
        proper = _S.ProperResponse()
        if not self._resolver.provideProperResponse(states, proper):
            raise RuntimeError(f"ad_rss provideProperResponse failed for {step!r}")
        evaluator = lon.rss_state_information.evaluator.name
        safe = bool(lon.is_safe)
        # Both enums are ordered by severity (ad_rss's combineResponse compares the values).
        lat_name = max(proper.lateral_response_left, proper.lateral_response_right, key=int).name
        lon_name = proper.longitudinal_response.name
        if safe != bool(proper.is_safe):
            raise AssertionError("ad_rss state and resolver disagree on safety")
        rng = proper.acceleration_restrictions.longitudinal_range
        return IntersectionVerdict(
            safe=safe,
            state=evaluator,
            rule=_RULE[evaluator] if safe else None,
            response=lon_name,
            lateral_response=lat_name,
            current_distance=float(lon.rss_state_information.current_distance.mDistance),
            safe_distance=float(lon.rss_state_information.safe_distance.mDistance),
            accel_range=(float(rng.minimum.mAcceleration), float(rng.maximum.mAcceleration)),
            relative_position=pos,
            relative_distance=dist,
            time_index=t,
        )


def check_sequence(steps: Sequence[IntersectionStep], start_index: int = 1) -> list[IntersectionVerdict]:
    """Verdicts of consecutive steps (time indices start_index, start_index + 1, ...) of one pair."""
    oracle = IntersectionOracle()
    return [oracle.step(s, start_index + i) for i, s in enumerate(steps)]


def check_intersection(v_ego: SpeedLike, d_enter_ego: float, d_exit_ego: float, p_ego: Params,
                       v_other: SpeedLike, d_enter_other: float, d_exit_other: float, p_other: Params,
                       priority: Priority, time_index: Optional[int] = None,
                       previous: Optional[Sequence[IntersectionStep]] = None, *,
                       len_ego: float = 5.0, len_other: float = 5.0,
                       relative: Optional[Tuple[str, float]] = None) -> IntersectionVerdict:
    """ad_rss's verdict for one intersection step (fresh checker).

    ``previous``: earlier steps of the same pair, fed first (consecutive time indices) so that the
    response of an unsafe step can depend on the last safe state. ``time_index`` (default
    ``len(previous) + 1``) is the index of this step; it must exceed ``len(previous)``. Its value does not
    change the result.
    """
    prev = list(previous or [])
    t = len(prev) + 1 if time_index is None else int(time_index)
    if t <= len(prev):
        raise ValueError(f"time_index {t} leaves no room for {len(prev)} previous steps (indices start at 1)")
    step = IntersectionStep(v_ego, d_enter_ego, d_exit_ego, p_ego, v_other, d_enter_other, d_exit_other,
                            p_other, priority, len_ego, len_other, relative)
    return check_sequence(prev + [step], start_index=t - len(prev))[-1]


def time_window(v: SpeedLike, d_enter: float, d_exit: float, p: Params,
                v_cap: Optional[float] = None) -> Tuple[float, float]:
    """ad_rss's (earliest arrival, latest exit) times [s] of one car, as in
    ``RssIntersectionConstellationChecker::checkLateralIntersect`` (core::calculateTimeToCoverDistance):

    - arrival: from v_max, accelerate at a_acc (capped at ``v_cap``) during ρ, then brake at b_min;
      time to cover max(0, d_enter); NEVER (1e6 s) if it stops first.
    - exit: from v_min, brake at b_max from t = 0 (during and after ρ); time to cover d_exit; NEVER if it
      stops first.

    ``v_cap`` defaults to ``p.max_speed_on_accel``; note that ad_rss passes the EGO's cap for BOTH cars.
    """
    lo, hi = _speed_range(v)
    cap = float(p.max_speed_on_accel if v_cap is None else v_cap)
    rho = _P.Duration(float(p.response_time))
    t_in = _P.Duration(0.0)
    t_out = _P.Duration(0.0)
    ok = _C.calculateTimeToCoverDistance(_P.Speed(hi), _P.Speed(cap), rho, _P.Acceleration(float(p.lon_accel_max)),
                                         _P.Acceleration(-float(p.lon_brake_min)),
                                         _P.Distance(max(0.0, float(d_enter))), t_in)
    ok = ok and _C.calculateTimeToCoverDistance(_P.Speed(lo), _P.Speed(cap), rho,
                                                _P.Acceleration(-float(p.lon_brake_max)),
                                                _P.Acceleration(-float(p.lon_brake_max)),
                                                _P.Distance(float(d_exit)), t_out)
    if not ok:
        raise RuntimeError("ad_rss calculateTimeToCoverDistance failed")
    return float(t_in.mDuration), float(t_out.mDuration)

