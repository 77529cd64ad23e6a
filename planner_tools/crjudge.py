"""A closed-loop run judged the way CommonRoad users judge one, against the scenario's XML.

:class:`CommonRoadScene` holds a CommonRoad scenario and its planning problem and gives

* what the request carries (:meth:`~CommonRoadScene.goal_request`, :meth:`~CommonRoadScene.speed_limit`):
  - **goal** — the planning problem's goal region as the request's ``goal``: ``position`` the union of
    its states' positions (a single circle stays a circle; shapes that do not join become their convex
    hull; a polygon of more than :data:`GOAL_MAX_POINTS` points is simplified), ``time`` the hull of
    their time-step intervals in seconds from the plan's start (``(k − k₀)·dt``), ``speed`` the hull of
    their velocity intervals (clipped at 0); a goal with no state has none. In closed loop each cycle's
    request carries it with the times shifted to that cycle's now (:func:`planner_tools.sim.problem_at`).
  - **speed limit** — the lowest ``MAX_SPEED`` (or ``MAX_SPEED_ZONE_START``) sign on the lanelets the
    reference line drives along from the ego on (:meth:`~CommonRoadScene.route_lanelets`; signs matched
    by name, so every country's sign table counts: commonroad-io's ``TrafficSignInterpreter`` knows only
    some countries' tables), else the default of
    the road type (:data:`ROAD_TYPE_SPEED`: urban 50 km/h, country 100 km/h, highway 130 km/h) of those
    lanelets (:data:`LANELET_ROAD_TYPE`; the lowest when they differ), else of the scenario's tags
    (:data:`TAG_ROAD_TYPE`), else urban. The request's ``options.speed_limit`` is the larger of it and
    the request's target speed (the contract asks ``speed_limit ≥ target_speed``; the target stays what
    the converter made it).
* the judgement of a driven motion (:meth:`~CommonRoadScene.judge`), on its states at the scenario's time
  steps (``driven_states``: the footprint's centre, the body's yaw, the speed, the steering angle):
  - **goal** — commonroad-io's ``GoalRegion.is_reached`` on each state (position, orientation, velocity,
    time step, as ``PlanningProblem.goal_reached`` does), reached at the first state it accepts; a goal
    given by time only (a survival scenario) is reached by surviving its whole window: at the window's
    last time step (``is_reached`` accepts every state inside the window, the initial state too when the
    window starts at 0, which would make surviving nothing a success).
  - **collisions** — commonroad-drivability-checker's collision checker (``pycrcc``): every obstacle of
    the scenario as a collision object (a dynamic one time-variant over its recorded occupancies, a static
    one as its shape), the ego's driven footprints (``length × width`` boxes at each time step) as a
    time-variant object. (The checker's own scenario converter, ``create_collision_checker``, needs
    commonroad-io's pre-2026 shape classes, so the objects are built here from the same occupancies.)
  - **rear-end** — a collision counts as *rear-end (hit from behind by traffic that does not react)* when,
    at its first colliding time step: the obstacle is dynamic (recorded traffic, which does not react to
    the ego); the overlap of the two footprints has its centroid behind the ego's centre along the ego's
    yaw (the rear half of the ego); the obstacle heads within :data:`REAR_END_HEADING` of the ego's yaw;
    and it closes in: its velocity along the ego's yaw exceeds the ego's speed (heading and speed from the
    recorded state, or for a set-based prediction, which has none, from its occupancy's centre one time
    step either side). Any other collision is a collision the ego had a part in.
  - **off-road** — time steps whose footprint is not inside the road, the union of the scenario's
    lanelets (shapely, :data:`ROAD_TOLERANCE`); the drivability checker's road-boundary construction
    needs commonroad-io's pre-2026 shapes as well.
  - **feasibility** — :func:`planner_tools.commonroad.feasible_transitions` (the drivability checker's
    kinematic single-track check of vehicle type 2) on each transition between consecutive states.

Needs the optional extra ``commonroad``. Units: metres [m], seconds [s], radians [rad], [m/s].
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from planner_tools.commonroad import (
    driven_states,
    feasible_transitions,
    read_scenario,
)

#: km/h → m/s
KMH = 1.0 / 3.6
#: the default speed limit of a road type [m/s] where no sign says one
ROAD_TYPE_SPEED: dict[str, float] = {"urban": 50.0 * KMH, "country": 100.0 * KMH, "highway": 130.0 * KMH}
#: CommonRoad lanelet types (``LaneletType`` values) → road type; types not listed say nothing
LANELET_ROAD_TYPE: dict[str, str] = {
    **dict.fromkeys(
        ("urban", "intersection", "crosswalk", "busLane", "busStop", "bicycleLane", "sidewalk",
         "driveWay", "parking", "restricted"),
        "urban",
    ),
    "country": "country",
    **dict.fromkeys(
        ("highway", "interstate", "mainCarriageWay", "accessRamp", "exitRamp", "shoulder"), "highway"
    ),
}  # fmt: skip
#: CommonRoad scenario tags (``Tag`` values) → road type, when the lanelets have no known type
TAG_ROAD_TYPE: dict[str, str] = {
    "urban": "urban",
    "intersection": "urban",
    "rural": "country",
    "highway": "highway",
    "interstate": "highway",
}
#: traffic sign elements (by their name in every country's table) that set a speed limit
SPEED_SIGNS = ("MAX_SPEED", "MAX_SPEED_ZONE_START")
#: the lanelets of the route are looked up under the reference every this [m]
ROUTE_SAMPLING = 2.0
#: a lanelet is on the route where its direction is within this of the reference's [rad]
ROUTE_HEADING = math.pi / 4.0
#: … and its centre line passes within this of the reference [m]
ROUTE_OFFSET = 1.5
#: most points of a goal polygon in a request
GOAL_MAX_POINTS = 200
#: a rear-end collision's obstacle heads within this of the ego's yaw [rad]
REAR_END_HEADING = math.pi / 4.0
#: the road is the union of the lanelets grown by this, which closes seams between them [m]
ROAD_TOLERANCE = 0.05


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


@dataclass(frozen=True)
class SpeedLimit:
    """A speed limit [m/s] and where it comes from (``sign``, ``road type urban``, …)."""

    value: float
    source: str


@dataclass(frozen=True)
class Verdict:
    """CommonRoad's judgement of a driven motion (see the module docstring).

    Attributes:
        has_goal: whether the planning problem has a goal state at all.
        goal_reached, goal_time: whether and when [s from the start] a state reached it.
        collided: ids of the obstacles the ego collides with (drivability checker), in order of contact.
        rear_end: those of them that are rear-end collisions.
        first_collision_time: [s] or None.
        off_road_steps: time steps whose footprint leaves the road; ``first_off_road_time`` [s] or None.
        feasible: per transition between consecutive judged states, whether it is feasible.
        states: how many time steps were judged; ``dt`` the scenario's time step [s].
    """

    has_goal: bool
    goal_reached: bool
    goal_time: float | None
    collided: tuple[str, ...]
    rear_end: tuple[str, ...]
    first_collision_time: float | None
    off_road_steps: int
    first_off_road_time: float | None
    feasible: tuple[bool, ...]
    states: int
    dt: float

    @property
    def collision(self) -> bool:
        return bool(self.collided)

    @property
    def all_feasible(self) -> bool:
        return all(self.feasible)


# --------------------------------------------------------------------------------------------------
# pycrcc collision objects from commonroad-io 2026 occupancies
# --------------------------------------------------------------------------------------------------


def _shape(occupancy: Any) -> Any:
    """The pycrcc shape of a commonroad-io occupancy (rectangle, circle, polygon or a group)."""
    from commonroad_dc import pycrcc

    if hasattr(occupancy, "occupancies"):  # a group
        group = pycrcc.ShapeGroup()
        for part in occupancy.occupancies:
            shape = _shape(part)
            for piece in shape.unpack() if isinstance(shape, pycrcc.ShapeGroup) else [shape]:
                group.add_shape(piece)
        return group
    if hasattr(occupancy, "rect_center"):
        c = occupancy.rect_center
        return pycrcc.RectOBB(
            0.5 * occupancy.length, 0.5 * occupancy.width, float(occupancy.orientation), c.x, c.y
        )
    if hasattr(occupancy, "circle_center"):
        c = occupancy.circle_center
        return pycrcc.Circle(float(occupancy.radius), c.x, c.y)
    geom = occupancy.shapely_object
    polygons = list(getattr(geom, "geoms", [geom]))
    group = pycrcc.ShapeGroup()
    for poly in polygons:
        ring = np.asarray(poly.exterior.coords)[:-1]
        group.add_shape(pycrcc.Polygon(ring.tolist(), []))
    return group.unpack()[0] if group.size() == 1 else group


@dataclass(frozen=True)
class _Obstacle:
    id: str
    dynamic: bool
    collision_object: Any
    obstacle: Any


def _obstacles(scenario: Any, first: int, last: int) -> list[_Obstacle]:
    """Every obstacle of ``scenario`` as a pycrcc object over the time steps ``first..last``."""
    from commonroad_dc import pycrcc

    out: list[_Obstacle] = []
    for ob in scenario.static_obstacles:
        occupancy = ob.occupancy_at_time(ob.initial_state.time_step)
        out.append(_Obstacle(str(ob.obstacle_id), False, _shape(occupancy), ob))
    for ob in scenario.dynamic_obstacles:
        start = max(int(ob.initial_state.time_step), first)
        steps = []
        for k in range(start, last + 1):
            occupancy = ob.occupancy_at_time(k)
            if occupancy is None:
                break
            steps.append(_shape(occupancy))
        if not steps:
            continue
        tvo = pycrcc.TimeVariantCollisionObject(start)
        for shape in steps:
            tvo.append_obstacle(shape)
        out.append(_Obstacle(str(ob.obstacle_id), True, tvo, ob))
    return out


def _ego_boxes(states: Sequence[Any], length: float, width: float) -> list[Any]:
    from commonroad_dc import pycrcc

    return [
        pycrcc.RectOBB(0.5 * length, 0.5 * width, float(st.orientation), *map(float, st.position))
        for st in states
    ]


# --------------------------------------------------------------------------------------------------
# The scene
# --------------------------------------------------------------------------------------------------


class CommonRoadScene:
    """A CommonRoad scenario and one of its planning problems (see the module docstring)."""

    def __init__(self, scenario: Any, problem: Any, name: str = "") -> None:
        self.scenario = scenario
        self.problem = problem
        self.name = name or str(scenario.scenario_id)
        self.dt = float(scenario.dt)
        step = problem.initial_state.time_step
        self.t0 = int(step.start if hasattr(step, "start") else step)

    @classmethod
    def from_file(cls, path: str | Path, planning_problem_id: int | None = None) -> CommonRoadScene:
        """The scene of a CommonRoad XML file (plain or ``*.xml.gz``)."""
        from planner_tools.commonroad import scenario_name

        scenario, problem = read_scenario(path, planning_problem_id)
        return cls(scenario, problem, scenario_name(path))

    # -- what the request carries ------------------------------------------------------------------

    @property
    def has_goal(self) -> bool:
        return bool(self.problem.goal.state_list)

    @property
    def time_only(self) -> bool:
        """Whether the goal is a time window only (CommonRoad's survival scenarios)."""
        states = self.problem.goal.state_list
        return bool(states) and all(set(st.used_attributes) <= {"time_step"} for st in states)

    def _reached(self, state: Any) -> bool:
        """``GoalRegion.is_reached`` on a state with a time step; a goal by time only is reached at its
        window's last time step, by surviving the whole window."""
        goal = self.problem.goal
        if not goal.state_list or not goal.is_reached(state):
            return False
        if self.time_only:
            window = self._intervals(st.time_step for st in goal.state_list)
            return int(state.time_step) >= max(b for _, b in window)
        return True

    def goal_window(self) -> tuple[float, float] | None:
        """The hull of the goal states' time windows [s from the start], or None without a goal."""
        spans = self._intervals(st.time_step for st in self.problem.goal.state_list)
        if not spans:
            return None
        return (
            (min(a for a, _ in spans) - self.t0) * self.dt,
            (max(b for _, b in spans) - self.t0) * self.dt,
        )

    def goal_request(self) -> dict[str, Any] | None:
        """The request's ``goal`` (JSON data; see the module docstring), or None without a goal."""
        states = self.problem.goal.state_list
        if not states:
            return None
        out: dict[str, Any] = {}
        position = self._goal_position([st.position for st in states if st.has_value("position")])
        if position is not None:
            out["position"] = position
        window = self.goal_window()
        if window is not None:
            out["time"] = [round(window[0], 4), round(window[1], 4)]
        speeds = self._intervals(st.velocity for st in states if st.has_value("velocity"))
        if speeds and len(speeds) == len(states):  # a state without a speed range allows any speed
            low = max(min(a for a, _ in speeds), 0.0)
            high = max(b for _, b in speeds)
            if high >= 0.0:
                out["speed"] = [round(low, 4), round(high, 4)]
        return out

    @staticmethod
    def _intervals(values: Iterable[Any]) -> list[tuple[float, float]]:
        """CommonRoad intervals (or exact values) as ``(low, high)``, the missing ones left out."""
        out = []
        for value in values:
            if value is None:
                continue
            if hasattr(value, "start") and hasattr(value, "end"):
                out.append((float(value.start), float(value.end)))
            else:
                out.append((float(value), float(value)))
        return out

    @staticmethod
    def _goal_position(occupancies: list[Any]) -> dict[str, Any] | None:
        if not occupancies:
            return None
        if len(occupancies) == 1 and hasattr(occupancies[0], "circle_center"):
            c = occupancies[0].circle_center
            return {
                "circle": {"center": [round(c.x, 3), round(c.y, 3)], "radius": float(occupancies[0].radius)}
            }
        parts: list[Any] = []
        for occ in occupancies:
            if hasattr(occ, "circle_center"):  # commonroad-io 2026.1's shapely disc has radius/2
                parts.append(occ.circle_center.buffer(float(occ.radius)))
            elif hasattr(occ, "occupancies"):
                parts.extend(o.shapely_object for o in occ.occupancies)
            else:
                parts.append(occ.shapely_object)
        union = shapely.union_all([shapely.make_valid(p) for p in parts]).buffer(0)
        polygon = union if union.geom_type == "Polygon" else union.convex_hull
        tolerance = 0.01
        while len(polygon.exterior.coords) - 1 > GOAL_MAX_POINTS:
            polygon = polygon.simplify(tolerance)
            tolerance *= 2.0
        ring = np.asarray(polygon.exterior.coords)[:-1]
        return {"polygon": [[round(x, 3), round(y, 3)] for x, y in ring.tolist()]}

    def route_lanelets(self, reference_line: Any, ego_xy: Sequence[float]) -> list[int]:
        """Ids of the lanelets the reference line (n, 2) drives along, from the point nearest the ego on,
        in the order met: every :data:`ROUTE_SAMPLING` of it, of the lanelets under the point whose
        direction there agrees with the reference's (within :data:`ROUTE_HEADING`), the one whose centre
        line is nearest (within :data:`ROUTE_OFFSET`), so that a lanelet crossing or merging at a junction
        is not taken for the route."""
        from planner_tools.commonroad import arc_length, resample

        ref = np.asarray(reference_line, dtype=float)
        pts, _ = resample(ref, ROUTE_SAMPLING)
        start = int(np.argmin(np.hypot(*(pts - np.asarray(ego_xy, dtype=float)).T)))
        pts = pts[max(min(start, pts.shape[0] - 2), 0) :]
        heading = np.arctan2(*np.gradient(pts, arc_length(pts), axis=0).T[::-1])
        network = self.scenario.lanelet_network
        centre: dict[int, Any] = {}
        out: list[int] = []
        for i, found in enumerate(network.find_lanelet_by_position(list(pts))):
            best: tuple[float, int] | None = None
            for lid in found:
                lanelet = network.find_lanelet_by_id(lid)
                try:
                    along = float(lanelet.orientation_by_position(pts[i]))
                except Exception:  # beyond the lanelet's centre line
                    continue
                if abs(_wrap(along - float(heading[i]))) > ROUTE_HEADING:
                    continue
                line = centre.setdefault(lid, shapely.LineString(lanelet.center_vertices))
                offset = float(line.distance(shapely.Point(pts[i])))
                if offset <= ROUTE_OFFSET and (best is None or offset < best[0]):
                    best = (offset, int(lid))
            if best is not None and best[1] not in out:
                out.append(best[1])
        return out

    def speed_limit(self, lanelet_ids: Iterable[int]) -> SpeedLimit:
        """The speed limit of the lanelets (see the module docstring)."""
        network = self.scenario.lanelet_network
        lanelets = [network.find_lanelet_by_id(i) for i in lanelet_ids]
        signed: list[float] = []
        for la in lanelets:
            for sign_id in la.traffic_signs:
                sign = network.find_traffic_sign_by_id(sign_id)
                for element in sign.traffic_sign_elements:
                    if element.traffic_sign_element_id.name in SPEED_SIGNS and element.additional_values:
                        signed.append(float(element.additional_values[0]))
        if signed:
            return SpeedLimit(min(signed), "sign")
        types = {
            LANELET_ROAD_TYPE[t.value]
            for la in lanelets
            for t in la.lanelet_type
            if t.value in LANELET_ROAD_TYPE
        }
        source = "lanelet type"
        if not types:
            types = {TAG_ROAD_TYPE[t.value] for t in (self.scenario.tags or ()) if t.value in TAG_ROAD_TYPE}
            source = "scenario tag"
        if not types:
            types, source = {"urban"}, "default"
        road = min(types, key=ROAD_TYPE_SPEED.__getitem__)
        return SpeedLimit(ROAD_TYPE_SPEED[road], f"{source}: {road}")

    # -- judging -------------------------------------------------------------------------------------

    def _step_of(self, t: float) -> int | None:
        """The scenario time step at ``t`` [s from the start], or None between two."""
        k = t / self.dt
        return self.t0 + round(k) if abs(k - round(k)) < 1e-6 else None

    def goal_check(self) -> Callable[[Any], bool]:
        """A check of a simulated vehicle state (:class:`planner_tools.sim.VehicleState`) by
        ``GoalRegion.is_reached``, false between time steps and without a goal; for
        :class:`planner_tools.sim.Goal`'s ``check``."""
        from commonroad.scenario.state import KSState

        def check(state: Any) -> bool:
            step = self._step_of(state.t)
            if step is None or not self.has_goal:
                return False
            ks = KSState(
                time_step=step,
                position=np.array([state.x, state.y]),
                steering_angle=float(state.steering),
                velocity=float(state.speed),
                orientation=float(state.yaw),
            )
            return self._reached(ks)

        return check

    def _obstacles_to(self, last: int) -> list[_Obstacle]:
        """The scenario's obstacles as collision objects over the time steps ``t0..last`` at least
        (built once, again only for a longer span)."""
        built = getattr(self, "_built", None)
        if built is None or built[0] < last:
            built = (last, _obstacles(self.scenario, self.t0, last))
            self._built = built
        return built[1]

    def collision_check(self, duration: float, length: float, width: float) -> Callable[[Any], bool]:
        """A check of a simulated vehicle state (:class:`planner_tools.sim.VehicleState`) by the
        drivability checker: whether the ``length × width`` footprint [m] at its pose collides with an
        obstacle at its time step (false between time steps); for the simulator's ``collision``, over
        ``duration`` [s] from the start."""
        from commonroad_dc import pycrcc

        checker = pycrcc.CollisionChecker()
        for ob in self._obstacles_to(self.t0 + math.ceil(duration / self.dt + 1e-9)):
            checker.add_collision_object(ob.collision_object)

        def check(state: Any) -> bool:
            step = self._step_of(state.t)
            if step is None:
                return False
            box = pycrcc.TimeVariantCollisionObject(step)
            box.append_obstacle(
                pycrcc.RectOBB(0.5 * length, 0.5 * width, float(state.yaw), float(state.x), float(state.y))
            )
            return bool(checker.collide(box))

        return check

    def judge(self, motion: Any, length: float, width: float, *, feasibility: bool = True) -> Verdict:
        """Judge the driven ``motion`` (:class:`planner_tools.sim.Motion`) of a ``length × width``
        footprint [m] (see the module docstring)."""
        from commonroad_dc import pycrcc

        states = driven_states(motion, self.dt, self.t0)
        reached = next((k for k, st in enumerate(states) if self._reached(st)), None)

        boxes = _ego_boxes(states, length, width)
        ego = pycrcc.TimeVariantCollisionObject(self.t0)
        for box in boxes:
            ego.append_obstacle(box)
        last = self.t0 + len(states) - 1
        hits: list[tuple[int, _Obstacle]] = []
        for ob in self._obstacles_to(last):
            if ob.collision_object.collide(ego):
                first = self._first_contact(ob, boxes)
                hits.append((0 if first is None else first, ob))
        hits.sort(key=lambda h: h[0])
        rear = tuple(ob.id for k, ob in hits if ob.dynamic and self._rear_end(states[k], ob, length, width))

        road = self._road()
        prints = shapely.polygons(
            [_box_corners(st.position, float(st.orientation), length, width) for st in states]
        )
        off = ~np.asarray(shapely.covered_by(prints, road), dtype=bool)
        off_steps = np.flatnonzero(off)
        feasible = tuple(feasible_transitions(states, self.dt)) if feasibility else ()
        return Verdict(
            has_goal=self.has_goal,
            goal_reached=reached is not None,
            goal_time=None if reached is None else reached * self.dt,
            collided=tuple(ob.id for _, ob in hits),
            rear_end=rear,
            first_collision_time=hits[0][0] * self.dt if hits else None,
            off_road_steps=int(off_steps.size),
            first_off_road_time=float(off_steps[0] * self.dt) if off_steps.size else None,
            feasible=feasible,
            states=len(states),
            dt=self.dt,
        )

    def _first_contact(self, ob: _Obstacle, boxes: Sequence[Any]) -> int | None:
        """Index of the first of the ego's ``boxes`` (one per time step from ``t0``) touching ``ob``."""
        for k, box in enumerate(boxes):
            other = ob.collision_object.obstacle_at_time(self.t0 + k) if ob.dynamic else ob.collision_object
            if other is not None and box.collide(other):
                return k
        return None

    def _road(self) -> Any:
        road = getattr(self, "_road_geometry", None)
        if road is None:
            lanelets = self.scenario.lanelet_network.lanelets
            road = shapely.union_all([shapely.make_valid(la.polygon.shapely_object) for la in lanelets])
            road = road.buffer(ROAD_TOLERANCE)
            shapely.prepare(road)
            self._road_geometry = road
        return road

    def _rear_end(self, ego: Any, ob: _Obstacle, length: float, width: float) -> bool:
        """Whether the ego's first contact with the dynamic obstacle ``ob`` at the ego's state ``ego`` is
        a rear-end collision (see the module docstring)."""
        step = int(ego.time_step)
        occupancy = ob.obstacle.occupancy_at_time(step)
        motion = self._obstacle_motion(ob.obstacle, step)
        if occupancy is None or motion is None:
            return False
        heading, speed = motion
        yaw = float(ego.orientation)
        box = shapely.Polygon(_box_corners(ego.position, yaw, length, width))
        overlap = box.intersection(shapely.make_valid(occupancy.shapely_object))
        point = overlap.centroid if not overlap.is_empty else occupancy.center
        along = (point.x - ego.position[0]) * math.cos(yaw) + (point.y - ego.position[1]) * math.sin(yaw)
        dpsi = _wrap(heading - yaw)
        closing = speed * math.cos(dpsi) - float(ego.velocity)
        return along < 0.0 and abs(dpsi) <= REAR_END_HEADING and closing > 0.0

    def _obstacle_motion(self, obstacle: Any, step: int) -> tuple[float, float] | None:
        """``(heading [rad], speed [m/s])`` of a dynamic obstacle at ``step``: its recorded state's, else
        (a set-based prediction has no states) from its occupancy's centre one step either side; None
        when it does not move and has no recorded heading."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # commonroad-io warns that set-based predictions have no state
            state = obstacle.state_at_time(step)
        heading = getattr(state, "orientation", None) if state is not None else None
        speed = getattr(state, "velocity", None) if state is not None else None
        if heading is not None and speed is not None:
            return _wrap(float(heading)), float(speed)
        around = [(k, obstacle.occupancy_at_time(k)) for k in (step - 1, step, step + 1)]
        known = [(k, o.center) for k, o in around if o is not None]
        if len(known) < 2:
            return None
        (k0, a), (k1, b) = known[0], known[-1]
        dx, dy = b.x - a.x, b.y - a.y
        moved = math.hypot(dx, dy)
        if moved < 1e-9:
            return None if heading is None else (_wrap(float(heading)), 0.0)
        return math.atan2(dy, dx), moved / ((k1 - k0) * self.dt)


def _box_corners(position: Any, yaw: float, length: float, width: float) -> list[list[float]]:
    """Corners of a ``length × width`` box centred at ``position`` turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = float(position[0]), float(position[1])
    out = []
    for a, b in ((0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5), (0.5, -0.5)):
        dx, dy = a * length, b * width
        out.append([x + dx * c - dy * s, y + dx * s + dy * c])
    return out
