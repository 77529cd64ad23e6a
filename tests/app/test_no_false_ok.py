"""No false ``ok``: whatever vehicle (point model or car) and ego a request describes (within the API's
limits), an ``ok`` or
``stopped`` answer passes every check of the independent checker in ``tests/regression/checks.py``
(positions against the reported ``(s, d)``, heading against the direction of motion, curvature against
the heading's change, the vehicle's limits, the lane, the obstacles), and a ``fallback`` brakes.

The checker is written from the answer's JSON, not with the planner's own checks; the requests come
through the HTTP layer like a client's.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, example, given, note, settings
from hypothesis import strategies as st

from app.limits import (
    MAX_VEHICLE_ACCELERATION,
    MAX_VEHICLE_CURVATURE,
    MAX_VEHICLE_SPEED,
    MIN_VEHICLE_ACCELERATION,
    MIN_VEHICLE_CURVATURE,
)
from planner.roads import straight, u_turn
from tests.regression.checks import STATUSES, error_problems, plan_problems


def _log_uniform(low: float, high: float) -> st.SearchStrategy[float]:
    return st.floats(math.log(low), math.log(high)).map(math.exp)


def _road(points: np.ndarray, index: int, width: float) -> dict[str, Any]:
    """A request on ``points`` with the ego at point ``index``, heading along the road."""
    here, ahead = points[index], points[index + 1]
    heading = float(np.arctan2(ahead[1] - here[1], ahead[0] - here[0]))
    return {
        "reference_line": points.tolist(),
        "lane": {"left_width": width, "right_width": width},
        "obstacles": [],
        "ego": {"x": float(here[0]), "y": float(here[1]), "heading": heading},
    }


ROADS = {
    "straight": _road(straight(150.0, step=1.0), 5, 1.75),
    "u_turn_8m": _road(u_turn(radius=8.0, leg=30.0, step=0.5), 10, 2.0),
    "hairpin_4m": _road(u_turn(radius=4.0, leg=25.0, step=0.5), 10, 3.0),
}

vehicles = st.fixed_dictionaries(
    {
        "max_speed": _log_uniform(0.5, MAX_VEHICLE_SPEED),
        "max_acceleration": _log_uniform(MIN_VEHICLE_ACCELERATION, MAX_VEHICLE_ACCELERATION),
        "max_deceleration": _log_uniform(MIN_VEHICLE_ACCELERATION, MAX_VEHICLE_ACCELERATION),
        "max_lateral_acceleration": _log_uniform(MIN_VEHICLE_ACCELERATION, MAX_VEHICLE_ACCELERATION),
        "max_curvature": _log_uniform(MIN_VEHICLE_CURVATURE, min(MAX_VEHICLE_CURVATURE, 2.0)),
    }
)
#: a car (wheelbase, rear axle behind the centre) or the point model (no wheelbase)
cars = st.one_of(
    st.just({}),
    st.builds(
        lambda wheelbase, share: {"wheelbase": wheelbase, "rear_axle_offset": share * 2.25},
        st.floats(1.0, 4.0),
        st.floats(0.0, 1.0),
    ),
)
egos = st.fixed_dictionaries(
    {
        "speed": st.one_of(st.just(0.0), _log_uniform(0.1, MAX_VEHICLE_SPEED)),
        "acceleration": st.floats(-20.0, 20.0),
    }
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    road=st.sampled_from(sorted(ROADS)),
    vehicle=vehicles,
    car=cars,
    ego=egos,
    target=st.none() | st.floats(0.0, 60.0),
)
@example(  # found by hypothesis: 168 m/s into a hairpin with 1 m/s² of lateral acceleration
    road="hairpin_4m",
    vehicle={
        "max_speed": 1.0,
        "max_acceleration": 1.0,
        "max_deceleration": 22.75989509352673,
        "max_lateral_acceleration": 1.0,
        "max_curvature": 1.0,
    },
    car={},
    ego={"speed": 168.17414165184545, "acceleration": 0.0},
    target=None,
)
def test_every_answer_to_an_extreme_vehicle_passes_the_independent_checks(
    client: TestClient,
    road: str,
    vehicle: dict[str, float],
    car: dict[str, float],
    ego: dict[str, float],
    target: float | None,
) -> None:
    request = copy.deepcopy(ROADS[road])
    request["vehicle"] = {**vehicle, **car}
    request["ego"].update(ego)
    request["options"] = {"time_budget_ms": 60_000.0, **({} if target is None else {"target_speed": target})}
    note(f"request options/vehicle/ego: {request['options']} {vehicle} {request['ego']}")
    answer = client.post("/v1/plan", json=request)
    if answer.status_code == 422:  # the request contradicts itself: refused, naming the field
        assert error_problems(answer.json()) == []
        return
    assert answer.status_code == 200, answer.text
    assert plan_problems(request, answer.json(), STATUSES) == []


def test_the_two_false_oks_of_the_issue_are_fallbacks(client: TestClient, demo: dict[str, Any]) -> None:
    """The demo at 20 m/s with a brake of 0.01 m/s² (it cannot stop before the road's end, nor take the
    U-turn), and an 8 m U-turn entered at 200 m/s: both impossible, both braking fallbacks."""
    demo["ego"]["speed"] = 20.0
    demo["vehicle"]["max_deceleration"] = 0.01
    fast = copy.deepcopy(ROADS["u_turn_8m"])
    fast["ego"]["speed"] = 200.0
    fast["vehicle"] = {"max_speed": 200.0}
    answer = client.post("/v1/plan", json=demo).json()
    assert answer["status"] == "fallback", answer["message"]
    assert plan_problems(demo, answer, ["fallback"]) == []
    answer = client.post("/v1/plan", json=fast).json()
    assert answer["status"] == "fallback", answer["message"]
    assert "lateral acceleration" in answer["message"]  # what makes it impossible


@pytest.mark.parametrize(("measured", "status"), [(-0.5, "ok"), (4.0, "fallback")])
def test_an_ego_faster_than_its_max_speed_brakes_at_once(
    client: TestClient, measured: float, status: str
) -> None:
    """Measured at 18 m/s in a vehicle whose max_speed is 7 m/s: the plan brakes at once (its acceleration
    falls at the emergency jerk to full braking). Measured braking lightly (−0.5 m/s²) that is an ``ok``
    (it was a fallback: the speed check asked it to lose speed sooner than the jerk-limited ramp can);
    measured speeding up (+4 m/s²) the ramp takes it past its own speed first, beyond the limit: a braking
    fallback. Either passes the independent checks."""
    request = copy.deepcopy(ROADS["straight"])
    request["vehicle"] = {"max_speed": 7.0, "max_acceleration": 5.0, "max_deceleration": 8.0}
    request["ego"].update(speed=18.0, acceleration=measured)
    answer = client.post("/v1/plan", json=request).json()
    assert answer["status"] == status, answer["message"]
    assert plan_problems(request, answer, [status]) == []
    accelerations = [p["a"] for p in answer["trajectory"]]
    assert accelerations[0] == pytest.approx(measured) and min(accelerations[:6]) <= -7.9


@pytest.mark.parametrize("car", [{}, {"wheelbase": 2.7, "rear_axle_offset": 1.35}])
@pytest.mark.parametrize("speed", [0.0, 3.0, 8.0])
@pytest.mark.parametrize("y", [1.5, 3.0, 6.0])
def test_an_ego_that_starts_outside_its_lane_returns_into_it(
    client: TestClient, car: dict[str, float], speed: float, y: float
) -> None:
    """An ego 0.65–5.15 m outside its lane (no road given) on an empty straight road drives back into it:
    ``ok``, passing the independent checks, its footprint inside the lane beyond the return length. The
    bounds closed linearly over one vehicle length, which a path that starts straight cannot follow, and
    the checks wanted the footprint back within that length: every answer was a fallback standing still
    outside the lane."""
    request = copy.deepcopy(ROADS["straight"])
    request["vehicle"] = dict(car)
    request["ego"].update(x=20.0, y=y, speed=speed)
    answer = client.post("/v1/plan", json=request).json()
    assert answer["status"] == "ok", answer["message"]
    assert plan_problems(request, answer, ["ok"]) == []
    assert abs(answer["trajectory"][-1]["d"]) < 0.3 and answer["trajectory"][-1]["v"] > 5.0
