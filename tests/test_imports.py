"""The project's import graph: no cycle; the core (``planner/``, ``solvers/``) imports neither the HTTP
layer, nor the tooling, nor their libraries; ``app/`` does not import the tooling; the service's runtime
dependencies are what ``app/``, ``planner/`` and ``solvers/`` import.

Every module is parsed with :mod:`ast` (nothing is imported): every ``import`` and ``from … import``
counts, at module level, in a function or under ``TYPE_CHECKING``, relative ones resolved against the
module's package. ``from pkg import name`` is an edge to ``pkg.name`` when that is a module of the
project, else to ``pkg``.
"""

from __future__ import annotations

import ast
import functools
import graphlib
import sys
import tomllib
from collections.abc import Collection, Iterable
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from planner_tools.extras import COMMONROAD, SCALE, TOOLS

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("app", "planner", "planner_tools", "solvers")
CORE = ("app", "planner", "solvers")
#: what planner/ and solvers/ must not import: the HTTP layer and its libraries, the tooling, its extras
NOT_IN_PLANNER = (
    "app",
    "planner_tools",
    "fastapi",
    "starlette",
    "pydantic",
    "pydantic_core",
    "pydantic_settings",
    "uvicorn",
    "granian",
    *TOOLS.modules,
    *COMMONROAD.modules,
    *SCALE.modules,
)
#: what app/ must not import: the tooling and its extras
NOT_IN_APP = ("planner_tools", *TOOLS.modules, *COMMONROAD.modules, *SCALE.modules)


def module_names(root: Path, packages: Iterable[str]) -> dict[str, Path]:
    """Dotted name → file of every module of ``packages`` under ``root`` (``pkg/__init__.py`` is ``pkg``)."""
    out: dict[str, Path] = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def imports_of(name: str, path: Path, modules: Collection[str]) -> set[str]:
    """Absolute names a module imports: ``from a import b`` names ``a.b`` if that is one of
    ``modules``, else ``a``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                source = ".".join([*parts[: len(parts) - node.level + 1], *filter(None, [node.module])])
            else:
                source = node.module or ""
            if source != "__future__":
                out.update(
                    f"{source}.{a.name}" if f"{source}.{a.name}" in modules else source for a in node.names
                )
    return out


def import_graph(modules: dict[str, Path]) -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """``(project graph, every import)``: module → the project modules it imports, and module → every
    absolute name it imports (libraries included)."""
    every = {name: imports_of(name, path, modules) for name, path in modules.items()}
    return {name: (names & modules.keys()) - {name} for name, names in every.items()}, every


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of the graph as ``[a, b, …, a]``, or ``None``."""
    try:
        graphlib.TopologicalSorter(graph).prepare()
    except graphlib.CycleError as exc:
        return list(exc.args[1])
    return None


def _matches(name: str, forbidden: Iterable[str]) -> bool:
    return any(name == f or name.startswith(f + ".") for f in forbidden)


MODULES = module_names(ROOT, PACKAGES)
GRAPH, IMPORTS = import_graph(MODULES)


def test_every_package_is_seen() -> None:
    for package in PACKAGES:
        assert package in MODULES and sum(m.startswith(package + ".") for m in MODULES) >= 3
    # an edge of each kind: `from module import name`, `from package import module`, in a function
    assert "planner.problem" in GRAPH["planner.pipeline"]
    assert "app.routes.plan" in GRAPH["app.routes"]
    assert "planner_tools.render" in GRAPH["planner_tools.cli"]  # imported inside the commands


def test_no_import_cycle() -> None:
    cycle = find_cycle(GRAPH)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


@pytest.mark.parametrize(
    ("package", "forbidden"), [("planner", NOT_IN_PLANNER), ("solvers", NOT_IN_PLANNER), ("app", NOT_IN_APP)]
)
def test_layers(package: str, forbidden: tuple[str, ...]) -> None:
    bad = sorted(
        f"{module} imports {name}"
        for module, names in IMPORTS.items()
        if module == package or module.startswith(package + ".")
        for name in names
        if _matches(name, forbidden)
    )
    assert not bad, f"{package}/ imports what it must not: {bad}"


def _third_party(names: Iterable[str], project: Iterable[str] = PACKAGES) -> set[str]:
    """Top-level names of ``names`` that are neither the standard library's nor ``project``'s."""
    tops = {name.split(".")[0] for name in names}
    return {t for t in tops if t and t not in sys.stdlib_module_names and t not in set(project)}


@functools.cache
def _top_level_modules() -> dict[str, set[str]]:
    """Installed distribution (canonical name) → the top-level modules it provides."""
    out: dict[str, set[str]] = {}
    for module, dists in metadata.packages_distributions().items():
        for d in dists:
            out.setdefault(canonicalize_name(d), set()).add(module)
    return out


def _provided(distributions: Iterable[str]) -> set[str]:
    """Top-level modules the installed ``distributions`` provide."""
    table = _top_level_modules()
    return {m for d in distributions for m in table.get(canonicalize_name(d), set())}


def _closure(requirements: Iterable[str]) -> set[str]:
    """The distributions ``requirements`` install, their own requirements included (markers evaluated
    here, with the extras asked for)."""
    seen: set[str] = set()
    todo = [Requirement(r) for r in requirements]
    while todo:
        req = todo.pop()
        name = canonicalize_name(req.name)
        if name in seen:
            continue
        seen.add(name)
        for text in metadata.requires(name) or []:
            sub = Requirement(text)
            if sub.marker is None or any(sub.marker.evaluate({"extra": e}) for e in (req.extras or {""})):
                todo.append(sub)
    return seen


def test_runtime_dependencies_are_what_the_service_imports() -> None:
    dependencies = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    used = _third_party(n for m, names in IMPORTS.items() if _matches(m, CORE) for n in names)
    unused = [d for d in dependencies if not _provided([Requirement(d).name]) & used]
    assert not unused, f"runtime dependencies that app/, planner/ and solvers/ never import: {unused}"
    missing = used - _provided(_closure(dependencies))
    assert not missing, f"imported by the service but installed by no runtime dependency: {missing}"


# --------------------------------------------------------------------------------------------------
# The checks themselves find what they should, on a project made up here
# --------------------------------------------------------------------------------------------------


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_a_cycle_through_relative_and_function_level_imports_is_found(tmp_path: Path) -> None:
    _write(
        tmp_path,
        {
            "core/__init__.py": "",
            "core/a.py": "from . import b\n",
            "core/b.py": "def f():\n    from .sub.c import g\n",
            "core/sub/__init__.py": "",
            "core/sub/c.py": "import numpy\nfrom ..a import thing\n",
            "tools/__init__.py": "",
            "tools/x.py": "from core.sub import c\nimport matplotlib.pyplot\n",
        },
    )
    graph, every = import_graph(module_names(tmp_path, ("core", "tools")))
    assert graph["core.sub.c"] == {"core.a"} and graph["tools.x"] == {"core.sub.c"}
    cycle = find_cycle(graph)
    assert cycle is not None and set(cycle) == {"core.a", "core.b", "core.sub.c"}
    assert cycle[0] == cycle[-1]
    assert _third_party(every["tools.x"], ("core", "tools")) == {"matplotlib"}
    (tmp_path / "core/sub/c.py").write_text("import numpy\n")
    assert find_cycle(import_graph(module_names(tmp_path, ("core", "tools")))[0]) is None
