"""A car's kinematics (planner.kinematics), its vehicle's fields (planner.problem.Vehicle) and its
footprint's extent from the rear axle (planner.collision.footprint_extent)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.collision import box_corners, footprint_extent
from planner.errors import InvalidInputError
from planner.kinematics import (
    body_centre,
    lateral_acceleration,
    lateral_curvature,
    planned_ego,
    planned_point,
    steering_angle,
    steering_rate_speed,
)
from planner.problem import Ego, Vehicle

CAR = Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_rate=0.5)
BASE = {"wheelbase": 2.7, "rear_axle_offset": 1.0}
POINT = Vehicle()


def test_a_cars_centre_turns_on_a_wider_circle_at_the_same_yaw_rate() -> None:
    # rear axle on a circle of radius R: the centre at √(R² + l_r²), both at the yaw rate v/R
    radius, v = 8.0, 5.0
    expected = (v / radius) ** 2 * math.hypot(radius, 1.35)
    assert float(lateral_acceleration(np.array(v), np.array(1 / radius), CAR)) == pytest.approx(expected)
    assert float(lateral_acceleration(np.array(v), np.array(-1 / radius), CAR)) == pytest.approx(expected)
    assert float(lateral_acceleration(np.array(v), np.array(1 / radius), POINT)) == v**2 / radius


@pytest.mark.parametrize("limit", [1e-6, 0.05, 0.3, 3.0, 1e6])
def test_lateral_curvature_inverts_the_lateral_acceleration(limit: float) -> None:
    kappa = float(lateral_curvature(limit, CAR))
    assert kappa * math.sqrt(1.0 + (1.35 * kappa) ** 2) == pytest.approx(limit, rel=1e-12)
    assert kappa < limit
    assert float(lateral_curvature(limit, POINT)) == limit


def test_steering_angle_and_the_steering_rates_speed_limit() -> None:
    assert float(steering_angle(np.array(0.1), CAR)) == pytest.approx(math.atan(0.27))
    with pytest.raises(ValueError, match="point model"):
        steering_angle(np.array(0.1), POINT)
    # a clothoid: κ = 0.01·σ; δ̇ = v·W/(1 + W²κ²)·0.01 ≤ 0.9·0.5 ⇔ v ≤ 0.45(1 + W²κ²)/(0.027)
    sigma = np.linspace(0.0, 20.0, 41)
    kappa = 0.01 * sigma
    limit = steering_rate_speed(sigma, kappa, CAR, 0.9)
    assert limit is not None
    low = np.minimum(kappa[:-1], kappa[1:]) ** 2
    per_step = 0.45 * (1.0 + 2.7**2 * low) / (2.7 * 0.01)
    np.testing.assert_allclose(limit, np.minimum(np.r_[np.inf, per_step], np.r_[per_step, np.inf]))
    # no rate limit, a point, a constant curvature: nothing bounds the speed
    assert steering_rate_speed(sigma, kappa, Vehicle(wheelbase=2.7, rear_axle_offset=1.35), 0.9) is None
    assert steering_rate_speed(sigma, kappa, POINT, 0.9) is None
    constant = steering_rate_speed(sigma, np.full_like(sigma, 0.1), CAR, 0.9)
    assert constant is not None and np.all(np.isinf(constant))


def test_the_planned_point_is_the_rear_axle_of_a_car_and_the_centre_of_a_point() -> None:
    ego = Ego(x=10.0, y=5.0, heading=0.5, speed=3.0, acceleration=0.2, curvature=0.1)
    rear = planned_ego(ego, CAR)
    assert (rear.x, rear.y) == pytest.approx((10.0 - 1.35 * math.cos(0.5), 5.0 - 1.35 * math.sin(0.5)))
    assert (rear.heading, rear.speed, rear.acceleration, rear.curvature) == (0.5, 3.0, 0.2, 0.1)
    assert planned_ego(ego, POINT) is ego
    x, y = body_centre(np.array([rear.x]), np.array([rear.y]), np.array([0.5]), CAR)
    assert (float(x[0]), float(y[0])) == pytest.approx((10.0, 5.0))
    px, py = planned_point(x, y, np.array([0.5]), CAR)
    assert (float(px[0]), float(py[0])) == pytest.approx((rear.x, rear.y))


@pytest.mark.parametrize("theta", [-1.2, -0.4, 0.0, 0.3, 1.0])
def test_the_footprint_extent_from_the_rear_axle_holds_its_corners(theta: float) -> None:
    # the footprint is the box centred l_r ahead of the rear axle (at the origin) along θ
    centre = 1.35 * np.array([math.cos(theta), math.sin(theta)])
    corners = box_corners(centre[0], centre[1], np.array(theta), CAR.length, CAR.width).reshape(4, 2)
    extent = footprint_extent(np.array(theta), CAR, 0.1)
    assert float(extent.front) == pytest.approx(corners[:, 0].max() + 0.1)
    assert float(extent.back) == pytest.approx(-corners[:, 0].min() + 0.1)
    assert float(extent.left) == pytest.approx(corners[:, 1].max() + 0.1)
    assert float(extent.right) == pytest.approx(-corners[:, 1].min() + 0.1)
    point = footprint_extent(np.array(theta), POINT, 0.1)
    assert float(point.front) == float(point.back) and float(point.left) == float(point.right)


def test_a_cars_limits_and_extents() -> None:
    assert CAR.is_car and not POINT.is_car
    assert (CAR.front_extent, CAR.rear_extent) == (2.25 + 1.35, 2.25 - 1.35)
    assert (POINT.front_extent, POINT.rear_extent, POINT.rear_offset) == (2.25, 2.25, 0.0)
    assert CAR.steering_limit == pytest.approx(math.atan(2.7 * 0.2)) and POINT.steering_limit is None
    assert CAR.curvature_limit == 0.2
    tight = Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_angle=0.3)
    assert tight.curvature_limit == pytest.approx(math.tan(0.3) / 2.7)
    assert Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_angle=1.2).curvature_limit == 0.2


@pytest.mark.parametrize(
    ("fields", "where"),
    [
        ({"rear_axle_offset": 1.0}, "vehicle.rear_axle_offset"),  # needs a wheelbase
        ({"max_steering_rate": 0.4}, "vehicle.max_steering_rate"),
        ({"wheelbase": 2.7}, "vehicle.rear_axle_offset"),  # required with one
        ({"wheelbase": 0.0, "rear_axle_offset": 1.0}, "vehicle.wheelbase"),
        ({"wheelbase": 2.7, "rear_axle_offset": 2.3}, "vehicle.rear_axle_offset"),  # beyond L/2
        ({"wheelbase": 2.7, "rear_axle_offset": -0.1}, "vehicle.rear_axle_offset"),
        ({**BASE, "max_steering_angle": 1.6}, "vehicle.max_steering_angle"),
        # a curvature limit tan(δ)/W below the smallest normal float
        ({**BASE, "wheelbase": 1e8, "max_steering_angle": 1e-301}, "vehicle.max_steering_angle"),
        ({**BASE, "max_steering_rate": 0.0}, "vehicle.max_steering_rate"),
        ({"wheelbase": math.inf, "rear_axle_offset": 1.0}, "vehicle.wheelbase"),
    ],
)
def test_a_car_is_refused_naming_the_field(fields: dict[str, float], where: str) -> None:
    with pytest.raises(InvalidInputError) as err:
        Vehicle(**fields)
    assert err.value.field == where
