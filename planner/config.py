"""The planner's tunables: one frozen configuration, one group per stage.

:func:`planner.pipeline.plan` takes a :class:`PlannerConfig` (default :data:`DEFAULT_CONFIG`); every
number a stage decides with that is not part of the request lives here, with its unit.

Clearances. Two margins keep the vehicle away from things, each defined once:

* ``Options.lateral_margin`` [m] (part of the request): kept to the lane's edges and to the static
  obstacles by the lateral bounds (:func:`planner.bounds.lateral_bounds`, dropped to the lane's edges
  only where the lane leaves no room for it), by the candidates' lane bounds
  (:func:`planner.candidates.generate_candidates`) and by the hold path's check of the obstacles on
  the held offset (:func:`planner.lateral.hold_path`).
* :attr:`PlannerConfig.obstacle_margin` [m]: added around the footprint in the Frenet-box decisions
  that look at every candidate or every moving obstacle at once: candidate scoring
  (:func:`planner.selection.choose_candidate`), the space-time bound of the moving obstacles ahead and
  the follower bound (:mod:`planner.st_bounds`).

The trajectory checks (:mod:`planner.validation`) keep no margin: they judge the exact footprint.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class SelectionConfig:
    """Weights of a candidate's cost ``Σd²/n + w_bend·Σ|Δd′| + w_progress·(1 − progress/longest)``
    (plus ``collision_cost`` when it meets an obstacle box); the offset term has weight 1 [1/m²]."""

    #: weight of the summed change of slope ``Σ|Δd′|`` [-]
    bend_weight: float = 10.0
    #: weight of the share of the longest progress along the reference not reached [-]
    progress_weight: float = 20.0
    #: added to the cost of a candidate that meets an obstacle box (any free one is better) [-]
    collision_cost: float = 1e6


@dataclass(frozen=True)
class LateralConfig:
    """The lateral stage: knots and the piecewise-jerk QP on ``d(s)``."""

    #: knot spacing of the lateral QP [m]
    knot_spacing: float = 0.5
    #: most knots of the lateral QP
    max_knots: int = 240
    #: the reference may turn at most this much between two knots [rad]: a longer path is cut where
    #: ``max_knots`` knots that close end (it would otherwise chord across the road's curves)
    max_knot_turn: float = 0.25
    #: bounds handed to the QP are tightened by this, covering its tolerance [m]
    qp_slack: float = 0.01
    #: bound on the lateral profile's jerk ``|d‴|`` [1/m²]
    jerk: float = 0.5
    #: OSQP (ADMM) iterations of one lateral QP solve before the second backend takes the QP over: most
    #: solves converge within it, and what does not (a tight or empty corridor: thousands) an interior
    #: point method settles in tens (a count, not a time: the same request gets the same answer)
    max_iter: int = 200
    #: OSQP iterations of the optional straighter path's QP (:func:`planner.lateral.straight_allowance`;
    #: no second backend): on the closed loops of the CommonRoad scenes it converged within 75 where it
    #: converged exactly, and ran out of 200 where a real bend cannot be driven straighter (3–4 ms each)
    straight_max_iter: int = 100
    #: the candidate's slope is averaged over this window to give the heading error of the bounds [m]
    heading_window: float = 4.0
    #: share of ``max_curvature`` the QP's curvature bound allows [-]
    curvature_share: float = 0.9
    #: share of ``max_curvature`` allowed when the speed-dependent bound left the QP no solution [-]
    retry_curvature_share: float = 0.99
    #: ``1 − κd`` of the curvature bound's linearisation is taken at least this [-]
    min_stretch: float = 0.05
    #: the reference's curvature is averaged over this window [m] when asking whether a bend of the path
    #: is the road's (kept) or a jog of the fitted reference the path may drive straight through
    #: (:func:`planner.lateral.straight_allowance`)
    straight_window: float = 20.0
    #: a path curvature this much above the straight allowance [1/m] makes the lateral stage try the
    #: straighter path; a reference whose curvature stays within it does not jog
    straight_slack: float = 1e-3
    #: the reference jogs where, over ``straight_window``, its curvature's mean is below this share of its
    #: mean magnitude (curvatures of either sign cancelling out) [-]
    jog_share: float = 0.5


@dataclass(frozen=True)
class SpeedConfig:
    """The speed stage: the profile's grid, jerks, headways and the SQP's settings."""

    #: most steps of the speed profile
    steps: int = 80
    #: jerk bound of the speed profile [m/s³]
    jerk: float = 8.0
    #: jerk allowed when braking for a blocked road, when the comfortable jerk cannot slow down in
    #: time, and in the fallback [m/s³]
    emergency_jerk: float = 30.0
    #: a profile needing more slack than this [m/s or m] is re-planned with the emergency jerk; also the
    #: SQP's ``restore_violation`` (above it, the SQP restarts from a full stop)
    slack: float = 0.05
    #: a profile past a stop or a space-time bound by more than this [m] is replaced by full braking
    position_slack: float = 0.01
    #: the speed limit at a point also holds this far either side of it [m]
    limit_reach: float = 2.0
    #: time headway kept to a moving obstacle ahead: the vehicle may not be where it was this long ago [s]
    headway: float = 1.0
    #: time headway kept ahead of a vehicle coming from behind: the vehicle should be ahead of where that
    #: one will be this much later [s] (a soft bound, weaker than the stop and the obstacles ahead). Half
    #: the headway kept to the obstacles ahead: the gap behind is the follower's to keep, ours is not to
    #: brake into it, and the two headways together must fit between a leader and a follower.
    follower_headway: float = 0.5
    #: a moving obstacle that first meets the path at least this far off its heading [rad] crosses it (or
    #: comes towards it): the profile may pass in front of it, with ``headway`` to spare, where the
    #: fastest profile within the limits can (:func:`planner.st_bounds.crossings`); else it yields
    crossing_angle: float = 0.7853981633974483
    #: share of a car's ``max_steering_rate`` the speed limit along the path plans with [-]
    steering_rate_share: float = 0.9
    #: SQP iterations (QPs solved) of one speed profile
    sqp_iterations: int = 2
    #: the SQP has converged once the linearised speed limit agrees with the limit within this, wherever
    #: the speed is near it [m/s]
    sqp_tolerance: float = 1e-3
    #: residual tolerance of each QP of the SQP
    qp_residual: float = 1e-6


@dataclass(frozen=True)
class GoalConfig:
    """How the plan aims at a request's goal (:mod:`planner.goal_plan`)."""

    #: how far inside the region's ends along the path the plan aims to enter, leave and stop [m] (at most
    #: a quarter of the region's length along the path)
    margin: float = 0.5
    #: a speed range from 0 whose top is below this [m/s] asks to stop inside the region (driving through
    #: so slowly is no way to meet it); one reaching higher allows a stop but asks only for a speed in it
    stop_speed: float = 1.0
    #: share of ``max_deceleration`` a stop inside the region, or slowing into its speed range, plans with
    #: when it can (it brakes harder only where that is too late) [-]
    deceleration_share: float = 0.5
    #: a window that ends after the horizon asks the profile to be where the rest can be driven at this
    #: share of the speed cap by its end [-]
    beyond_horizon_share: float = 0.8
    #: the profile aims to be inside this long after the window opens and before it closes [s] (at most a
    #: quarter of the window)
    window_margin: float = 1.0
    #: weight of a candidate's mean squared distance [m²] to the region's offsets over the region [1/m²]
    candidate_weight: float = 10.0
    #: samples across the lane per knot when the region is mapped onto the reference
    lateral_samples: int = 33
    #: most knots along the reference the region is mapped at (at least 0.5 m apart)
    max_knots: int = 400


@dataclass(frozen=True)
class DecisionConfig:
    """The lane decision (:mod:`planner.decision`): when to leave the lane for the road, and for how long."""

    #: a moving obstacle ahead in the lane slower than this share of the target speed is passed [-] ...
    slow_share: float = 0.5
    #: ... when it is also at least this much slower [m/s]
    slow_margin: float = 2.0
    #: the ego is outside its lane (and comes back) when its footprint (a corner, or a point along a
    #: side: :func:`planner.collision.outline_points`) is this far beyond its edge,
    #: where the road reaches beyond it [m]
    outside_tolerance: float = 0.3
    #: the ramps into the borrowed road and back are this long at the speed driven there [s] ...
    ramp_time: float = 2.5
    #: ... and at least this many vehicle lengths: also how far before a block a vehicle waiting to
    #: borrow stops, the room it needs to swing out from a standstill [-] ...
    min_ramp_lengths: float = 2.5
    #: ... and as long as it takes to move across the road beyond the lane at this share of the
    #: lateral-acceleration limit [-]
    ramp_lateral_share: float = 0.35
    #: the nominal speed profile of the timing estimates accelerates at this share of the limit [-]
    nominal_acceleration_share: float = 0.5
    #: the nominal profile never counts slower than this [m/s]
    nominal_floor_speed: float = 1.0
    #: the latest the vehicle is in the borrowed space is the nominal time stretched by this [-] ...
    late_factor: float = 1.5
    #: ... and the window of the oncoming check is widened by this on either side [s]
    time_margin: float = 1.0
    #: step of the oncoming check [s] (at most twice the horizon)
    check_step: float = 0.2
    #: step of the slow vehicles' tracks [s]
    track_step: float = 0.5
    #: time headway kept to an overtaken vehicle before coming back in front of it [s]
    pass_headway: float = 1.0
    #: the borrowed space whose traffic the vehicle waits for reaches this far beyond the half width of
    #: the farthest offset it needs there [m]
    band_spare: float = 1.5
    #: a borrow round a block closer than a stop at half the deceleration may bend the path as sharply
    #: as braking at this share of the deceleration allows (full braking less its jerk-limited onset) [-]
    urgent_braking_share: float = 0.75


@dataclass(frozen=True)
class PlannerConfig:
    """Every tunable of :func:`planner.pipeline.plan` (see the module docstring for the clearances)."""

    #: share of the lateral-acceleration limit the plan works with (the speed profile's limit, the
    #: lateral QP's curvature bound and the ego's assumed curvature; the linearisation's tolerance) [-]
    limit_margin: float = 0.9
    #: margin around the footprint in candidate scoring and the space-time and follower bounds [m]
    obstacle_margin: float = 0.3
    #: gap kept behind a blocked point or a moving obstacle, beyond half the vehicle length [m]
    stop_gap: float = 1.0
    #: the ego's assumed curvature is limited by ``a_lat,max / v²`` for a speed of at least this [m/s]
    min_curvature_speed: float = 0.1
    #: an obstacle farther from the reference than the widest lane side and the vehicle's length by
    #: more than this cannot matter [m]
    corridor_spare: float = 1.0
    #: share of ``options.time_budget_ms`` kept for the fallback when the stages overrun (they stop at
    #: the rest) [-]
    budget_reserve: float = 0.1
    #: start a solve a stage may need next on a second thread before the stage knows whether it does
    #: (:mod:`planner.thread_solvers`: the elastic problem beside an infeasibility proof, the emergency
    #: jerk's speed profile beside the first with a vehicle from behind): the same answers, sooner where
    #: a second core is free, the unused solves' work spent; False: every solve in the plan's thread
    speculate: bool = True
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    lateral: LateralConfig = field(default_factory=LateralConfig)
    speed: SpeedConfig = field(default_factory=SpeedConfig)
    goal: GoalConfig = field(default_factory=GoalConfig)
    decision: DecisionConfig = field(default_factory=DecisionConfig)


DEFAULT_CONFIG = PlannerConfig()
