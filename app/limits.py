"""The ranges the HTTP API accepts, each declared once; the request models use them on their fields,
so each shows in the OpenAPI schema.

They are the service's contract: what one request may ask for, so that every accepted request plans
in bounded time and answers in bounded size. They lie inside the planner's own sanity caps
(:mod:`planner.problem`, which guard the arithmetic against overflow for any caller of the library)
and are named differently where the planner has a cap on the same quantity (the names of the
planner's in parentheses):

* lane width, obstacle size, vehicle length and width, wheelbase: :data:`MAX_LANE_WIDTH`,
  :data:`MAX_OBSTACLE_SIZE`, :data:`MAX_VEHICLE_LENGTH`, :data:`MAX_VEHICLE_WIDTH`,
  :data:`MAX_WHEELBASE` (``MAX_SIZE``);
* speeds: :data:`MAX_VEHICLE_SPEED` (``MAX_EGO_SPEED``);
* accelerations: :data:`MAX_VEHICLE_ACCELERATION` (``MAX_ACCELERATION``),
  :data:`MIN_VEHICLE_ACCELERATION` (``SMALLEST_LIMIT``);
* curvatures: :data:`MAX_VEHICLE_CURVATURE` (``MAX_EGO_CURVATURE``), :data:`MIN_VEHICLE_CURVATURE`
  (``SMALLEST_LIMIT``);
* horizon and step: :data:`MAX_PLAN_HORIZON` (``MAX_HORIZON_TIME``), :data:`MIN_TRAJECTORY_STEP`
  (``MIN_DT``);
* candidate points: :data:`MAX_POINTS_PER_CANDIDATE` (``MAX_NUM_POINTS``),
  :data:`MAX_TOTAL_CANDIDATE_POINTS` (``MAX_CANDIDATE_POINTS``).

``tests/app/test_limits.py`` checks that each lies inside the planner's.

Units: metres [m], seconds [s], radians [rad], milliseconds [ms] where the name says so.
"""

from __future__ import annotations

# -- geometry ----------------------------------------------------------------------------------

#: largest absolute coordinate [m]
MAX_COORDINATE = 1e7
#: reference line points
MIN_REFERENCE_POINTS, MAX_REFERENCE_POINTS = 2, 20_000
#: longest reference line (sum of its chords) [m]
MAX_REFERENCE_LENGTH = 20_000.0
#: points of one /v1/frenet or /v1/cartesian request
MAX_QUERY_POINTS = 10_000
#: largest lane width either side of the reference [m]
MAX_LANE_WIDTH = 1000.0
#: largest |heading| of the ego or of a predicted state [rad] (not wrapped: any turn count is accepted)
MAX_HEADING = 1000.0

# -- obstacles ---------------------------------------------------------------------------------

#: obstacles per request
MAX_OBSTACLES = 1000
#: longest obstacle id [characters]
MAX_ID_LENGTH = 200
#: vertices of a polygon
MIN_POLYGON_POINTS, MAX_POLYGON_POINTS = 3, 1000
#: smallest polygon area [m²]; below it the polygon is degenerate
MIN_POLYGON_AREA = 1e-6
#: states of one prediction
MAX_PREDICTION_STATES = 2000
#: largest |t| of a predicted state [s]
MAX_PREDICTION_TIME = 1e6
#: obstacle dimensions (circle radius, box length and width) [m]
MIN_OBSTACLE_SIZE, MAX_OBSTACLE_SIZE = 1e-3, 1000.0
#: polygon vertices and predicted states over all obstacles of a request: with the other limits, the
#: largest valid request, as compact JSON, fits in the default body limit (:data:`MAX_BODY_BYTES`)
MAX_OBSTACLE_POINTS = 100_000
#: longest total outline of a request's obstacles (polygon perimeters, circle circumferences, box
#: perimeters) [m]: a bound on the work one request can ask for (the planner cuts long outlines to the road)
MAX_OBSTACLE_OUTLINE = 20_000.0

# -- the body ---------------------------------------------------------------------------------

#: default largest request body [bytes] (setting ``KAPPA_MAX_BODY_BYTES``): the largest valid request
#: written as compact JSON with every number at full precision fits (``tests/app/test_limits.py``)
MAX_BODY_BYTES = 16 * 1024 * 1024

# -- ego and vehicle ---------------------------------------------------------------------------

#: largest speed of the ego, speed limit of the vehicle and target speed [m/s]
MAX_VEHICLE_SPEED = 200.0
#: largest |acceleration| of the ego and largest acceleration limit of the vehicle [m/s²]
MAX_VEHICLE_ACCELERATION = 100.0
#: largest |curvature| of the ego and largest curvature limit of the vehicle [1/m]
MAX_VEHICLE_CURVATURE = 100.0
#: smallest acceleration limits [m/s²] and curvature limit [1/m] of the vehicle: a vehicle that cannot
#: brake harder than 1 cm/s² or turn tighter than a 10 km radius is no vehicle, and below these the
#: planner's braking distances and curvature bounds overflow
MIN_VEHICLE_ACCELERATION, MIN_VEHICLE_CURVATURE = 0.01, 1e-4
#: largest vehicle length and width [m]
MAX_VEHICLE_LENGTH, MAX_VEHICLE_WIDTH = 100.0, 20.0
#: largest wheelbase of a car [m] (its length's limit)
MAX_WHEELBASE = MAX_VEHICLE_LENGTH
#: limits of a car's steering angle limit [rad]: from 0.001 rad (0.06°: a turning radius of 2.7 km for a
#: 2.7 m wheelbase) to about 86°, short of the 90° at which tan δ diverges
MIN_STEERING_ANGLE, MAX_STEERING_ANGLE = 1e-3, 1.5
#: limits of a car's steering rate limit [rad/s]: below 0.001 rad/s (0.06°/s) no car can steer at all
MIN_STEERING_RATE, MAX_STEERING_RATE = 1e-3, 100.0

# -- options -----------------------------------------------------------------------------------

#: longest planning horizon [s]
MAX_PLAN_HORIZON = 20.0
#: trajectory sampling step [s]
MIN_TRAJECTORY_STEP, MAX_TRAJECTORY_STEP = 0.02, 1.0
#: most candidate paths of one request
MAX_CANDIDATES = 2000
#: points of one candidate path
MIN_POINTS_PER_CANDIDATE, MAX_POINTS_PER_CANDIDATE = 10, 1000
#: most points over all candidates (num_candidates × num_points) of one request: the size of the
#: candidates' answer
MAX_TOTAL_CANDIDATE_POINTS = 200_000
#: largest seed of the candidates (an unsigned 32-bit integer)
MAX_SEED = 2**32 - 1
#: limits of a plan's compute budget [ms], of a request and of the server's default
MIN_TIME_BUDGET_MS, MAX_TIME_BUDGET_MS = 1.0, 60_000.0
