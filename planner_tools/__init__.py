"""Tools around the planner: a client of :mod:`planner` like the HTTP layer, never imported by it.

* :mod:`planner_tools.io` — planning requests as plain JSON data ⇄ ``PlanningProblem`` (no pydantic);
* :mod:`planner_tools.sim` — the closed-loop simulator (kinematic bicycle, tracker, metrics);
* :mod:`planner_tools.commonroad` — CommonRoad scenarios converted to planning requests;
* :mod:`planner_tools.cli` — the ``kappa-planner`` command line; :mod:`planner_tools.figures` —
  ``python -m planner_tools.figures``.
"""
