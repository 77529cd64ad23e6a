"""The optional extras the tooling needs, and a clear error naming the ``pip install`` when one is missing.

``tools`` (matplotlib, Pillow, tqdm) draws and shows progress: every ``kappa-planner`` command and
``python -m planner_tools.figures`` need it. ``commonroad`` (commonroad-io,
commonroad-drivability-checker) reads CommonRoad XML, writes solutions and judges runs (goal, collisions,
feasibility). ``scale`` (Ray) runs ``kappa-planner evaluate``'s scenes in parallel, here or on a cluster.
The service (``app/``, ``planner/``, ``solvers/``) needs neither; ``pyproject.toml`` declares both
under ``[project.optional-dependencies]`` with these distributions.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass


class MissingExtraError(Exception):
    """An optional extra the tool needs is not installed; the message says how to install it."""


@dataclass(frozen=True)
class Extra:
    """An optional extra of ``kappa-planner``.

    Attributes:
        name: the extra's name in ``pyproject.toml`` (``pip install 'kappa-planner[name]'``).
        modules: each top-level module it provides → the distribution that provides it.
    """

    name: str
    modules: Mapping[str, str]

    @property
    def hint(self) -> str:
        return f"install the optional extra: pip install 'kappa-planner[{self.name}]'"

    def missing(self) -> list[str]:
        """The distributions of the extra whose module does not import."""
        out = []
        for module, distribution in self.modules.items():
            try:
                importlib.import_module(module)
            except ImportError:
                out.append(distribution)
        return out

    def require(self, purpose: str) -> None:
        """Raise :class:`MissingExtraError` (``"{purpose} needs X: install …"``) unless all of it imports."""
        missing = self.missing()
        if missing:
            raise MissingExtraError(f"{purpose} needs {', '.join(missing)}: {self.hint}")


TOOLS = Extra("tools", {"matplotlib": "matplotlib", "PIL": "Pillow", "tqdm": "tqdm"})
COMMONROAD = Extra(
    "commonroad", {"commonroad": "commonroad-io", "commonroad_dc": "commonroad-drivability-checker"}
)
SCALE = Extra("scale", {"ray": "ray"})
