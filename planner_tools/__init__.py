"""Tools around the planner: a client of :mod:`planner` like the HTTP layer, never imported by it.

* :mod:`planner_tools.io` — planning requests as plain JSON data ⇄ ``PlanningProblem`` (no pydantic);
* :mod:`planner_tools.sim` — the closed-loop simulator (kinematic bicycle, tracker, metrics);
* :mod:`planner_tools.commonroad` — CommonRoad scenarios converted to planning requests;
* :mod:`planner_tools.records` — a run's ``metrics.json``, ``steps.csv`` and metrics table;
* :mod:`planner_tools.render` — drawings: key frames, GIF, the side-by-side figure, candidate fans;
* :mod:`planner_tools.cli` — the ``kappa-planner`` command line; :mod:`planner_tools.figures` —
  ``python -m planner_tools.figures``;
* :mod:`planner_tools.extras` — the optional extras ``tools`` and ``commonroad``, and the error that
  says how to install a missing one.

Drawing and progress bars need the extra ``tools`` (matplotlib, Pillow, tqdm); reading CommonRoad XML
needs the extra ``commonroad`` (commonroad-io). The rest needs only the service's dependencies.
"""
