"""The pydantic models of the HTTP API, one module per resource: :mod:`~app.models.planning` (the
planning request of ``/v1/plan`` and ``/v1/candidates``), :mod:`~app.models.plan`,
:mod:`~app.models.candidates`, :mod:`~app.models.coordinates` (``/v1/frenet``, ``/v1/cartesian``),
:mod:`~app.models.health` and :mod:`~app.models.errors` (the one error shape); what they share in
:mod:`~app.models.common`. Their limits are in :mod:`app.limits`, the conversions to and from the
planner's dataclasses in :mod:`app.conversions`.
"""
