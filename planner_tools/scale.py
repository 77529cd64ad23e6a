"""``kappa-planner evaluate``: many scenes' closed loops as Ray tasks, here or on a cluster.

Each scene (:func:`planner_tools.evaluate.find_scenes`) is one Ray task that runs
:func:`planner_tools.evaluate.run_scene` — the same preparation, closed loop and judging as
``bench/commonroad.py`` and ``kappa-planner commonroad`` — and returns its row. The task gets the scene's
file (and the CommonRoad XML beside a request JSON) as bytes, so a cluster's nodes need the package
installed but no shared file system.

* **Where.** ``address`` (else ``RAY_ADDRESS``): a running Ray cluster (``ray start --head`` on one machine,
  ``ray start --address=HEAD:6379`` on the others; every node needs ``kappa-planner[commonroad,scale]``
  installed, the same version). Without it a local Ray of ``workers`` processes (default: the CPUs Ray
  finds, a container's CPU quota included) is started and stopped.
* **Streaming.** At most as many tasks as there are workers (the cluster's CPUs) are in flight; rows come
  back as tasks finish, a progress bar (tqdm) counts them, and ``DIR/results.csv`` is rewritten after each
  (to a temporary file, then renamed): a run stopped half-way keeps what it finished.
* **Failures.** A scene that raises becomes a row with status ``error`` and the exception; a task whose
  worker dies (a crash, out of memory) likewise; a task still running ``timeout`` seconds after it was
  handed to a free worker is cancelled (its worker killed) and becomes a row with status ``timeout``.
* **Resuming.** Rows of ``DIR/results.csv`` with status ``done`` and the same vehicle and duration are kept
  and their scenes skipped; ``force`` runs every scene again. Rows of scenes not asked for stay.
* **Output.** ``DIR/results.csv`` (:data:`planner_tools.evaluate.COLUMNS`), ``DIR/summary.md`` (the run's
  settings and timing, the totals and the table), with ``gifs`` an animation per scene in
  ``DIR/gifs/``.
"""

from __future__ import annotations

import math
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner_tools.evaluate import (
    DEFAULTS,
    Outcome,
    SceneRun,
    Settings,
    commonroad_file,
    find_scenes,
    read_csv,
    run_scene,
    scene_ids,
    table,
    write_csv,
)
from planner_tools.extras import SCALE

#: default per-scene timeout [s]
TIMEOUT = 900.0
#: local Ray's object store [bytes]: rows and GIFs are small
OBJECT_STORE_BYTES = 200 * 1024 * 1024


@dataclass(frozen=True)
class SceneFile:
    """A scene as a Ray task receives it: its row name, its file's name and bytes, and the files a request
    JSON reads beside it (the CommonRoad XML, ``index.json``), as (name, bytes)."""

    name: str
    filename: str
    data: bytes
    beside: tuple[tuple[str, bytes], ...] = ()

    @classmethod
    def read(cls, path: Path, name: str) -> SceneFile:
        beside: list[Path] = []
        if path.name.lower().endswith(".json"):
            xml = commonroad_file(path)
            beside = [p for p in (xml, path.with_name("index.json")) if p is not None and p.is_file()]
        return cls(name, path.name, path.read_bytes(), tuple((p.name, p.read_bytes()) for p in beside))


def run_scene_file(scene: SceneFile, settings: Settings) -> SceneRun:
    """:func:`planner_tools.evaluate.run_scene` on a scene given as bytes (written to a temporary
    folder first; the run and its preparation are not kept)."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="kappa-scene-") as tmp:
        path = Path(tmp) / scene.filename
        path.write_bytes(scene.data)
        for filename, data in scene.beside:
            (Path(tmp) / filename).write_bytes(data)
        return run_scene(path, settings, name=scene.name)


def cpus() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Report:
    """What :func:`evaluate` did: every row (in the scenes' order, earlier rows of other scenes after
    them), the rows it ran now, how many it skipped, the Ray start-up time [s], the wall time of the
    scenes [s] (from the first task handed out to the last row back) and the workers."""

    outcomes: list[Outcome]
    ran: list[Outcome]
    skipped: int
    startup_s: float
    wall_s: float
    workers: int
    address: str | None


def evaluate(
    inputs: Sequence[str | Path],
    out: Path,
    settings: Settings = DEFAULTS,
    *,
    workers: int | None = None,
    address: str | None = None,
    timeout: float = TIMEOUT,
    force: bool = False,
    quiet: bool = False,
    on_row: Callable[[Outcome], None] | None = None,
) -> Report:
    """Run the scenes of ``inputs`` on Ray and write ``out/results.csv`` and ``out/summary.md`` (see the
    module docstring).

    Raises:
        MissingExtraError: Ray (the extra ``scale``) or tqdm (``tools``) is not installed.
        CommonRoadError: an input that is not a scene.
    """
    SCALE.require("kappa-planner evaluate")
    paths = find_scenes(inputs)
    names = scene_ids(paths)
    csv_path = out / "results.csv"
    earlier = {o.scene: o for o in read_csv(csv_path)}
    kept = {
        n: o
        for n, o in earlier.items()
        if not force
        and o.status == "done"
        and o.vehicle == settings.vehicle
        and math.isclose(o.duration_s, settings.duration, rel_tol=1e-3)  # the CSV keeps 4 digits
    }
    todo = [(n, p) for n, p in zip(names, paths, strict=True) if n not in kept]
    rows: dict[str, Outcome] = dict(earlier)
    (out / "gifs" if settings.gif else out).mkdir(parents=True, exist_ok=True)

    address = address or os.environ.get("RAY_ADDRESS") or None
    ran: list[Outcome] = []

    def record(outcome: Outcome, gif: bytes | None = None) -> None:
        rows[outcome.scene] = outcome
        ran.append(outcome)
        if gif is not None:
            (out / "gifs" / f"{outcome.scene.replace('/', '_')}.gif").write_bytes(gif)
        write_csv(_ordered(rows, names), csv_path)
        if on_row is not None:
            on_row(outcome)

    startup = wall = 0.0
    capacity = workers or cpus()
    if todo:
        startup, wall, capacity = _run_on_ray(
            todo, settings, record, workers=workers, address=address, timeout=timeout, quiet=quiet
        )
    outcomes = _ordered(rows, names)
    report = Report(outcomes, ran, len(paths) - len(todo), startup, wall, capacity, address)
    write_summary(report, settings, out / "summary.md", inputs, timeout)
    return report


def _run_on_ray(
    todo: Sequence[tuple[str, Path]],
    settings: Settings,
    record: Callable[..., None],
    *,
    workers: int | None,
    address: str | None,
    timeout: float,
    quiet: bool,
) -> tuple[float, float, int]:
    """Run ``todo`` (name, path) as Ray tasks, ``record`` each row as it comes back; returns the Ray
    start-up time [s], the scenes' wall time [s] and the workers."""
    import ray
    from tqdm import tqdm

    started = time.perf_counter()
    if address:
        ray.init(address=address, log_to_driver=False, logging_level="WARNING")
    else:
        ray.init(
            num_cpus=workers,  # None: Ray counts the CPUs, the cgroup's CPU quota included
            include_dashboard=False,
            log_to_driver=False,
            logging_level="WARNING",
            object_store_memory=OBJECT_STORE_BYTES,
        )
    startup = time.perf_counter() - started
    try:
        capacity = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=0)(run_scene_file)
        queue = list(todo)
        pending: dict[Any, tuple[str, float]] = {}
        first = time.perf_counter()
        hidden = quiet or not sys.stderr.isatty()
        with tqdm(total=len(todo), desc="scenes", unit="scene", disable=hidden) as bar:
            while queue or pending:
                while queue and len(pending) < capacity:
                    name, path = queue.pop(0)
                    try:
                        scene = SceneFile.read(path, name)
                    except OSError as exc:
                        record(Outcome.failed(name, settings, "error", f"cannot read {path}: {exc}", 0.0))
                        bar.update(1)
                        continue
                    pending[task.remote(scene, settings)] = (name, time.perf_counter())
                if not pending:
                    continue
                now = time.perf_counter()
                wait = min(max(s + timeout - now, 0.0) for _, s in pending.values())
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=min(wait, 5.0))
                for ref in ready:
                    name, since = pending.pop(ref)
                    try:
                        run: SceneRun = ray.get(ref)
                        record(run.outcome, run.gif)
                    except Exception as exc:  # the worker died, or Ray could not run the task
                        text = str(exc).strip().splitlines()
                        error = f"{type(exc).__name__}: {text[0] if text else ''}"
                        record(Outcome.failed(name, settings, "error", error, time.perf_counter() - since))
                    bar.update(1)
                now = time.perf_counter()
                for ref, (name, since) in list(pending.items()):
                    if now - since > timeout:
                        ray.cancel(ref, force=True)
                        del pending[ref]
                        error = f"ran past {timeout:g} s"
                        record(Outcome.failed(name, settings, "timeout", error, now - since))
                        bar.update(1)
        return startup, time.perf_counter() - first, capacity
    finally:
        ray.shutdown()


def _ordered(rows: dict[str, Outcome], names: Sequence[str]) -> list[Outcome]:
    """The rows of ``names`` in their order, then any others (earlier scenes not asked for now)."""
    ordered = [rows[n] for n in names if n in rows]
    return ordered + [o for n, o in rows.items() if n not in names]


def write_summary(
    report: Report, settings: Settings, out: Path, inputs: Sequence[str | Path], timeout: float
) -> Path:
    """``summary.md``: the command's settings, the machine, the timing, the totals and the table."""
    ran = report.ran
    busy = sum(o.wall_s or 0.0 for o in ran)
    simulated = sum(o.sim_time_s or 0.0 for o in ran)
    workers = f"{report.workers} worker{'' if report.workers == 1 else 's'}"
    where = f"Ray cluster at {report.address}, {workers}" if report.address else f"local Ray, {workers}"
    try:
        load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        load = "—"
    lines = [
        "# Evaluation",
        "",
        f"`kappa-planner evaluate {' '.join(map(str, inputs))} --vehicle {settings.vehicle} "
        f"--duration {settings.duration:g}`: {where}; per-scene timeout {timeout:g} s.",
        "",
        f"- scenes: {len(report.outcomes)} ({len(ran)} run now, {report.skipped} kept from an earlier run)",
        f"- Ray start-up: {report.startup_s:.1f} s; scenes' wall time: {report.wall_s:.1f} s "
        f"(first task handed out → last row back)",
        f"- scene time summed: {busy:.1f} s; simulated: {simulated:.1f} s; "
        + (
            f"throughput {len(ran) / report.wall_s * 60.0:.1f} scenes/min, "
            f"{simulated / report.wall_s / max(report.workers, 1):.2f} simulated s per wall s per worker"
            if ran and report.wall_s > 0
            else "nothing run now"
        ),
        f"- machine: {platform.node()}, {cpus()} CPUs, load average {load} (1 / 5 / 15 min) at the end; "
        f"Python {platform.python_version()}",
        "",
        table(report.outcomes),
        "",
    ]
    out.write_text("\n".join(lines))
    return out
