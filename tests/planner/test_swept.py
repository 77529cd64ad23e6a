"""Collisions in continuous time: a thin obstacle between two samples is caught, static or moving, and
the continuous check never passes what the sampled check with a finer step rejects."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.collision import box_corners, prediction_at
from planner.problem import DynamicObstacle, Ego, Lane, PlanningProblem, Vehicle
from planner.reference import build_reference
from planner.roads import straight
from planner.swept import TOLERANCE, Contact, half_diagonal, moving_contacts, static_contacts
from planner.trajectory import Trajectory
from planner.validation import ViolationKind, trajectory_violations

ROBOT = Vehicle(length=0.5, width=0.5, max_speed=20.0)


def _poses(t: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> Trajectory:
    """A trajectory of poses (the other numbers do not matter to the collision checks)."""
    zeros = np.zeros_like(t)
    return Trajectory(t=t, x=x, y=y, heading=heading, curvature=zeros, v=zeros, a=zeros, s=x, d=y)


def _straight(speed: float = 10.0, dt: float = 0.1, steps: int = 40) -> Trajectory:
    t = np.arange(steps + 1) * dt
    return _poses(t, speed * t, np.zeros_like(t), np.zeros_like(t))


def _sampled(traj: Trajectory, vehicle: Vehicle, shape: shapely.Geometry) -> bool:
    """The check at the samples only (what the final checks did before)."""
    prints = shapely.polygons(box_corners(traj.x, traj.y, traj.heading, vehicle.length, vehicle.width))
    return bool(np.any(shapely.intersects(prints, shape)))


def _pole(x: float, y: float, diameter: float = 0.05) -> shapely.Geometry:
    return shapely.Point(x, y).buffer(0.5 * diameter, quad_segs=8)


def test_a_pole_between_two_samples_is_caught() -> None:
    # 1 m between samples, a 0.5 m robot: the footprints at the samples leave 0.5 m gaps
    traj = _straight()
    pole = _pole(10.5, 0.0)
    assert not _sampled(traj, ROBOT, pole)
    assert static_contacts(traj, ROBOT, [("pole", pole)]) == [Contact("pole", float(traj.t[10]), True)]
    # beside the path by more than the half width it is clear
    assert static_contacts(traj, ROBOT, [("pole", _pole(10.5, 0.3))]) == []


def test_a_sample_contact_keeps_its_time() -> None:
    traj = _straight()
    pole = _pole(12.0, 0.1)  # inside the footprint at t = 1.2 s
    assert static_contacts(traj, ROBOT, [("pole", pole)]) == [Contact("pole", float(traj.t[12]), False)]


def test_the_bulge_of_a_turn_is_covered() -> None:
    # a 4 m × 0.2 m bar turning on the spot by 90° in one step: its ends sweep a quarter circle of radius
    # ≈ 2 m that bulges out of the hull of the two footprints by about 0.59 m in the middle
    bar = Vehicle(length=4.0, width=0.2)
    traj = _poses(np.array([0.0, 0.1]), np.zeros(2), np.zeros(2), np.array([0.0, np.pi / 2]))
    r = half_diagonal(4.0, 0.2) - 0.02
    pole = _pole(r * np.cos(np.pi / 4), r * np.sin(np.pi / 4), diameter=0.01)
    hull = shapely.convex_hull(
        shapely.multipoints(box_corners(traj.x, traj.y, traj.heading, 4.0, 0.2).reshape(-1, 2))
    )
    assert not shapely.intersects(hull, pole)  # the hull alone would miss it
    assert [c.obstacle_id for c in static_contacts(traj, bar, [("pole", pole)])] == ["pole"]


def test_a_thin_obstacle_crossing_between_two_samples_is_caught() -> None:
    # a 5 cm box crossing the path at x = 30.5 m at 40 m/s: at 3.0 s 2 m to the left, at 3.1 s 2 m to
    # the right of the robot, which is there from 3.0 s to 3.1 s
    traj = _straight()
    t = np.array([0.0, 3.0, 3.1, 4.0])
    y = np.array([122.0, 2.0, -2.0, -38.0])
    crossing = DynamicObstacle(
        "crossing", 0.05, 0.05, np.column_stack((t, np.full(4, 30.5), y, np.full(4, -np.pi / 2)))
    )
    boxes = shapely.polygons(box_corners(*prediction_at(crossing, traj.t).T, crossing.length, crossing.width))
    prints = shapely.polygons(box_corners(traj.x, traj.y, traj.heading, ROBOT.length, ROBOT.width))
    assert not np.any(shapely.intersects(prints, boxes))  # the samples miss it
    assert moving_contacts(traj, ROBOT, [crossing]) == [Contact("crossing", float(traj.t[30]), True)]
    # the same crossing 0.2 s later passes behind the robot
    late = replace(crossing, prediction=crossing.prediction + np.array([0.2, 0.0, 0.0, 0.0]))
    assert moving_contacts(traj, ROBOT, [late]) == []


def test_the_final_checks_catch_a_pole_between_samples() -> None:
    ref = build_reference(straight(200.0, step=1.0))
    t = np.arange(41) * 0.1
    x = 10.0 + 10.0 * t
    traj = Trajectory(
        t=t, x=x, y=0 * t, heading=0 * t, curvature=0 * t, v=np.full(t.size, 10.0), a=0 * t, s=x, d=0 * t
    )
    problem = PlanningProblem(ref.points, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 10.0), (), ROBOT)
    assert trajectory_violations(ref, problem, traj, []) == []
    bad = trajectory_violations(ref, problem, traj, [("pole", _pole(25.5, 0.1))])
    assert [(v.kind, v.obstacle_id, v.t) for v in bad] == [
        (ViolationKind.HITS_OBSTACLE, "pole", pytest.approx(1.5))
    ]


# --------------------------------------------------------------------------------------------------------
# Property: never more lenient than the sampled check at a finer step


def _finer(traj: Trajectory, k: int) -> Trajectory:
    """The trajectory sampled ``k`` times as often, its poses moving linearly between the samples (the
    motion the continuous check assumes)."""
    t = np.linspace(traj.t[0], traj.t[-1], (traj.t.size - 1) * k + 1)
    return _poses(t, *(np.interp(t, traj.t, v) for v in (traj.x, traj.y, traj.heading)))


@st.composite
def scenes(
    draw: st.DrawFn,
) -> tuple[Trajectory, Vehicle, list[tuple[str, shapely.Geometry]], list[DynamicObstacle]]:
    """A trajectory of up to 12 random steps (up to 3 m and 1 rad each) and thin obstacles around it:
    static poles and moving boxes whose predictions have their own time steps."""
    n = draw(st.integers(2, 12))
    dt = draw(st.sampled_from([0.1, 0.25, 0.5]))
    floats = st.floats(-1.0, 1.0)
    step = np.array([draw(floats) for _ in range(2 * n)]).reshape(n, 2) * 3.0
    turn = np.array([draw(floats) for _ in range(n)])
    xy = np.vstack(([0.0, 0.0], np.cumsum(step[:-1], axis=0)))
    heading = np.concatenate(([0.0], np.cumsum(turn[:-1])))
    t = np.arange(n) * dt
    traj = _poses(t, xy[:, 0], xy[:, 1], heading)
    vehicle = Vehicle(length=draw(st.floats(0.2, 4.5)), width=draw(st.floats(0.1, 2.0)))
    lo, hi = xy.min(axis=0) - 3.0, xy.max(axis=0) + 3.0
    coordinate = st.tuples(st.floats(lo[0], hi[0]), st.floats(lo[1], hi[1]))
    poles = [
        (f"pole{i}", _pole(*draw(coordinate), diameter=draw(st.floats(0.01, 0.3))))
        for i in range(draw(st.integers(0, 6)))
    ]
    movers = []
    for i in range(draw(st.integers(0, 4))):
        m = draw(st.integers(1, 6))
        times = np.cumsum([draw(st.floats(0.05, 1.0)) for _ in range(m)]) - draw(st.floats(0.0, 1.0))
        states = [(*draw(coordinate), draw(st.floats(-4.0, 4.0))) for _ in range(m)]
        size = (draw(st.floats(0.02, 3.0)), draw(st.floats(0.02, 1.0)))
        movers.append(DynamicObstacle(f"mover{i}", *size, np.column_stack((times, np.array(states)))))
    return traj, vehicle, poles, movers


@settings(max_examples=300, deadline=None)
@given(scenes(), st.sampled_from([2, 5, 16]))
def test_never_passes_what_a_finer_sampled_check_rejects(
    scene: tuple[Trajectory, Vehicle, list[tuple[str, shapely.Geometry]], list[DynamicObstacle]], k: int
) -> None:
    traj, vehicle, poles, movers = scene
    fine = _finer(traj, k)
    prints = shapely.polygons(box_corners(fine.x, fine.y, fine.heading, vehicle.length, vehicle.width))
    caught = {c.obstacle_id for c in static_contacts(traj, vehicle, poles)}
    caught |= {c.obstacle_id for c in moving_contacts(traj, vehicle, movers)}
    for ob_id, shape in poles:
        if np.any(shapely.intersects(prints, shape)):
            assert ob_id in caught
    for ob in movers:
        boxes = shapely.polygons(box_corners(*prediction_at(ob, fine.t).T, ob.length, ob.width))
        if np.any(shapely.intersects(prints, boxes)):
            assert ob.id in caught


@settings(max_examples=150, deadline=None)
@given(scenes())
def test_a_contact_is_within_the_tolerance_at_a_fine_sampling(
    scene: tuple[Trajectory, Vehicle, list[tuple[str, shapely.Geometry]], list[DynamicObstacle]],
) -> None:
    """Conservative, not blind: where a contact is reported, the bodies come within the tolerance of
    each other at a fine sampling (plus how far they can move between its samples)."""
    traj, vehicle, poles, movers = scene
    k = 64
    fine = _finer(traj, k)
    prints = shapely.polygons(box_corners(fine.x, fine.y, fine.heading, vehicle.length, vehicle.width))
    radius = half_diagonal(vehicle.length, vehicle.width)
    travel = np.hypot(np.diff(traj.x), np.diff(traj.y)) + np.abs(np.diff(traj.heading)) * radius
    slack = TOLERANCE + float(np.max(travel)) / k
    shapes = dict(poles)
    for contact in static_contacts(traj, vehicle, poles):
        assert float(np.min(shapely.distance(prints, shapes[contact.obstacle_id]))) <= slack
    for contact in moving_contacts(traj, vehicle, movers):
        ob = next(o for o in movers if o.id == contact.obstacle_id)
        pose = prediction_at(ob, fine.t)
        boxes = shapely.polygons(box_corners(*pose.T, ob.length, ob.width))
        moved = np.abs(np.diff(pose, axis=0)) @ [1.0, 1.0, half_diagonal(ob.length, ob.width)]
        assert float(np.min(shapely.distance(prints, boxes))) <= slack + float(np.max(moved, initial=0.0))


def test_the_moving_obstacles_table_is_reused_only_for_the_same_obstacles() -> None:
    """A second trajectory against the same obstacles reuses their table; other obstacles (even equal
    in value but other objects, or in another order) get their own, and the contacts are the same as
    from a fresh table."""
    from planner import swept

    t = np.arange(41) * 0.1
    crossing = np.column_stack((t, np.full_like(t, 10.0), 5.0 - 5.0 * t, np.full_like(t, -np.pi / 2)))
    parked = np.column_stack((t, np.full_like(t, 30.0), np.zeros_like(t), np.zeros_like(t)))
    a = DynamicObstacle("crossing", 1.0, 1.0, crossing)
    b = DynamicObstacle("parked", 4.0, 2.0, parked)
    traj = _straight()
    first = moving_contacts(traj, ROBOT, [a, b])
    table = swept._LAST_MOVERS[1]
    assert moving_contacts(_straight(speed=5.0), ROBOT, [a, b]) is not None
    assert swept._LAST_MOVERS[1] is table  # the same objects: reused
    swapped = moving_contacts(traj, ROBOT, [b, a])
    assert swept._LAST_MOVERS[1] is not table
    assert swapped == first[::-1]
    copy = DynamicObstacle("crossing", 1.0, 1.0, crossing + np.array([0.0, 0.0, 100.0, 0.0]))
    # another object: its own table (it is far away; the parked box is still met)
    assert moving_contacts(traj, ROBOT, [copy, b]) == [c for c in first if c.obstacle_id == "parked"]
    assert moving_contacts(traj, ROBOT, [a, b]) == first
    assert [c.obstacle_id for c in first] == ["crossing", "parked"]
