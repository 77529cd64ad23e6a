"""Hostile and heavy traffic against the service, loopback only: ``python bench/abuse.py`` prints figures.

Reproduces every finding of issue 11 against a ``python -m app`` it starts on a free loopback port (a
few times: some attacks need other settings or kill the server), and prints per attack the answers'
status codes (or what became of the connections), the latency of ``GET /healthz`` meanwhile — each
probe on a new connection every 50 ms, from a process of its own, as a liveness probe would — and the
resident memory of the server's processes after it (the largest HTTP worker, the largest plan process).
The attacking process runs at niceness +10: on a shared 2-core machine its own CPU use (reading 16 MB
answers in Python) would otherwise delay the probe, which a remote attacker's would not.
Everything is bounded in count and time and stops by itself; nothing but 127.0.0.1 is contacted.

Targets (issue 11, 2 cores): /healthz p99 ≤ 100 ms and max ≤ 500 ms during every attack; no process
over ~500 MB after any single request; no 500 for any body (503 is the designed refusal: queue full,
budget gone, process died, stopping). The last column says whether an attack met them.

    python bench/abuse.py                 # every attack (about 5 minutes)
    python bench/abuse.py --only slow_headers,held_bodies
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import multiprocessing as mp
import os
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections import Counter
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from load import free_port, percentiles, process_tree

ROOT = Path(__file__).resolve().parents[1]
HOST = "127.0.0.1"
JSON = {"Content-Type": "application/json"}
#: longest wait for the server to be ready [s]
STARTUP_TIMEOUT = 120.0
#: the targets
HEALTH_P99_MS, HEALTH_MAX_MS, RSS_MB = 100.0, 500.0, 500.0


# --------------------------------------------------------------------------------------------------
# The server and its processes
# --------------------------------------------------------------------------------------------------


@dataclass
class Service:
    """A ``python -m app`` of our own on a free loopback port."""

    env: dict[str, str] = field(default_factory=dict)
    open_files: tuple[int, int] | None = None
    port: int = 0
    proc: subprocess.Popen[bytes] | None = None
    log: Path | None = None

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}"

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def start(self, log_dir: Path) -> None:
        self.port = free_port()
        env = {**os.environ, "KAPPA_HOST": HOST, "KAPPA_PORT": str(self.port), "KAPPA_LOG_LEVEL": "warning"}
        env.update(self.env)
        self.log = log_dir / f"server-{self.port}.log"
        limits = self.open_files

        def lower_limits() -> None:
            if limits is not None:
                resource.setrlimit(resource.RLIMIT_NOFILE, limits)

        with self.log.open("wb") as out:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "app"],
                cwd=ROOT,
                env=env,
                stdout=out,
                stderr=subprocess.STDOUT,
                preexec_fn=lower_limits,
            )
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while not self.ready():
            if self.proc.poll() is not None:
                sys.exit(f"the server exited with {self.proc.returncode}; see {self.log}")
            if time.monotonic() > deadline:
                sys.exit(f"the server was not ready within {STARTUP_TIMEOUT:.0f} s; see {self.log}")
            time.sleep(0.3)

    def ready(self) -> bool:
        with contextlib.suppress(OSError), urllib.request.urlopen(f"{self.url}/readyz", timeout=2) as r:
            return bool(r.status == 200)
        return False

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def roles(self) -> dict[str, list[int]]:
        """pid → role of the server's processes: ``supervisor`` (granian), ``worker`` (HTTP) and ``plan``."""
        tree = process_tree(self.pid)
        roles: dict[str, list[int]] = {"supervisor": [], "worker": [], "plan": []}
        for pid, depth in tree.items():
            cmd = _cmdline(pid)
            if depth == 0:
                roles["supervisor"].append(pid)
            elif "spawn_main" in cmd:
                roles["worker" if depth == 1 else "plan"].append(pid)
        return roles

    def rss_mb(self) -> dict[str, float]:
        """The largest resident memory of each role [MiB]."""
        return {role: max((_rss_mb(p) for p in pids), default=0.0) for role, pids in self.roles().items()}


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def _rss_mb(pid: int) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


# --------------------------------------------------------------------------------------------------
# /healthz, probed from a process of its own
# --------------------------------------------------------------------------------------------------


def probe_fresh(port: int, interval: float, started: Any, stop: Any, out: Connection) -> None:
    """GET /healthz on a new connection every ``interval`` s until ``stop`` (``started`` set once it
    runs); send the latencies [ms] and the count of failures (no answer within 5 s, or not 200)."""
    latencies: list[float] = []
    failures = 0
    request = f"GET /healthz HTTP/1.1\r\nHost: {HOST}\r\nConnection: close\r\n\r\n".encode()
    started.set()
    while not stop.is_set():
        t0 = time.perf_counter()
        try:
            with socket.create_connection((HOST, port), timeout=5) as sock:
                sock.sendall(request)
                answer = sock.recv(64)
            ok = answer.startswith(b"HTTP/1.1 200")
        except OSError:
            ok = False
        if ok:
            latencies.append(1e3 * (time.perf_counter() - t0))
        else:
            failures += 1
        stop.wait(interval)
    out.send((latencies, failures))


@contextlib.contextmanager
def probing(port: int) -> Iterator[dict[str, Any]]:
    """Probe /healthz while the block runs; the dict gets ``latencies`` and ``failures`` after it."""
    ctx = mp.get_context("spawn")
    started, stop = ctx.Event(), ctx.Event()
    receiver, sender = ctx.Pipe(duplex=False)
    prober = ctx.Process(target=probe_fresh, args=(port, 0.05, started, stop, sender), daemon=True)
    prober.start()
    started.wait(60)
    result: dict[str, Any] = {}
    try:
        yield result
    finally:
        stop.set()
        result["latencies"], result["failures"] = receiver.recv()
        prober.join()


# --------------------------------------------------------------------------------------------------
# A minimal HTTP/1.1 client (one connection per request, closed by the server)
# --------------------------------------------------------------------------------------------------


async def http(
    port: int,
    method: str,
    path: str,
    body: bytes = b"",
    headers: dict[str, str] | None = None,
    timeout: float = 60.0,
) -> tuple[int, dict[str, str], bytes]:
    """Status, headers and body of one request (status 0: no answer, the connection closed or timed
    out)."""
    head = [f"{method} {path} HTTP/1.1", f"Host: {HOST}", "Connection: close"]
    head += [f"{k}: {v}" for k, v in (headers or {}).items()]
    if body or method == "POST":
        head.append(f"Content-Length: {len(body)}")
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_connection(HOST, port), timeout)
    except (OSError, TimeoutError):
        return 0, {}, b""
    try:
        with contextlib.suppress(OSError):  # the server may answer (413, 503) before the body is sent
            writer.write(("\r\n".join(head) + "\r\n\r\n").encode() + body)
            await writer.drain()
        data = await asyncio.wait_for(reader.read(), timeout)
    except (OSError, TimeoutError):
        return 0, {}, b""
    finally:
        writer.close()
    return parse_answer(data)


def label(status: int, body: bytes) -> str:
    """An answer as the tables show it: its status, and its error code if it has one."""
    if not status:
        return "no answer"
    try:
        return f"{status} {json.loads(body)['error']['code']}"
    except (ValueError, KeyError, TypeError):
        return str(status)


def parse_answer(data: bytes) -> tuple[int, dict[str, str], bytes]:
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    try:
        status = int(lines[0].split(" ", 2)[1])
    except (IndexError, ValueError):
        return 0, {}, b""
    headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])}
    return status, headers, body


def demo(port: int) -> dict[str, Any]:
    with urllib.request.urlopen(f"http://{HOST}:{port}/v1/demo", timeout=30) as r:
        data: dict[str, Any] = json.load(r)
    return data


# --------------------------------------------------------------------------------------------------
# The bodies
# --------------------------------------------------------------------------------------------------


def type_error_body(port: int, obstacles: int, states: int) -> bytes:
    """A planning request whose every predicted state has four type errors (``""`` for each number)."""
    body = demo(port)
    state = {"t": "", "x": "", "y": "", "heading": ""}
    body["obstacles"] = [
        {"id": f"o{i}", "length": 1.0, "width": 1.0, "prediction": [state] * states} for i in range(obstacles)
    ]
    return json.dumps(body, separators=(",", ":")).encode()


def largest_request(port: int, budget_ms: float) -> bytes:
    """A planning request at the schema's limits: 20 000 reference points with a width each, 1000
    moving obstacles with 100 000 predicted states in all, 2000 candidates × 100 points."""
    from app import limits

    n = limits.MAX_REFERENCE_POINTS
    road = [[-1000.0 + 0.1 * i + 1e-9 * (i % 7), 0.0] for i in range(n)]
    per = limits.MAX_OBSTACLE_POINTS // limits.MAX_OBSTACLES
    obstacles = [
        {
            "id": f"car-{i:04d}-" + "x" * (limits.MAX_ID_LENGTH - 9),
            "length": 4.0,
            "width": 1.8,
            "prediction": [
                {"t": 0.1 * k, "x": -990.0 + 1.9 * i + 0.5 * k, "y": 6.0 + (i % 3), "heading": 0.0}
                for k in range(per)
            ],
        }
        for i in range(limits.MAX_OBSTACLES)
    ]
    body = {
        "reference_line": road,
        "lane": {"left_width": [3.5] * n, "right_width": [3.5] * n},
        "obstacles": obstacles,
        "ego": {"x": -995.0, "y": 0.0, "heading": 0.0, "speed": 10.0},
        "options": {"num_candidates": 2000, "num_points": 100, "time_budget_ms": budget_ms},
    }
    return json.dumps(body, separators=(",", ":")).encode()


HOSTILE_BODIES: list[bytes] = [
    b"",
    b"{",
    b"[]",
    b"null",
    b'"text"',
    b"[" * 100_000,
    b'{"reference_line": NaN}',
    b'{"reference_line": [[0, 0], [1e400, 0]], "points": [[0, 0]]}',
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]], "seed": 1' + b"0" * 5000 + b"}",
    b'{"reference_line": "' + b"a" * 1_000_000 + b'"}',
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[Infinity, 0]]}',
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]], "points": [[1, 1]]}',
    b'{"reference_line": [[0, 0], [0, 0]], "points": [[0, 0]]}',
    b'{"reference_line": [[0, 0], [10, 0], [5, 0]], "points": [[0, 0]]}',
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]], "frenet": [[0, 0]]}',
    b'{"reference_line": [[0, 0], [1, 0]], "frenet": [[1e7, 1e7]]}',
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[-1e7, 1e7]]}',
    b'{"\\ud800": 1}',
    b"\xff\xfe\x00\x00",
    b'{"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}' + b" " * 1000 + b"x",
    json.dumps(
        {"reference_line": [[i, (-1) ** i * 1e-9] for i in range(20_000)], "points": [[5, 1]]}
    ).encode(),
    json.dumps({"reference_line": [[i, 0] for i in range(20_001)], "points": [[5, 1]]}).encode(),
    json.dumps({"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]] * 10_001}).encode(),
    json.dumps({"reference_line": [[0, 0], [2e4, 0.0]], "points": [[1e7, -1e7]] * 10_000}).encode(),
    b'{"reference_line": [' + b",".join([b"[]"] * 2_000_000) + b"]}",
]


def hostile_plans_of(svc: Service) -> list[bytes]:
    """Planning requests that break the schema or the geometry in many ways."""
    base = demo(svc.port)
    variants: list[dict[str, Any]] = []
    for path, value in [
        (("ego", "heading"), 3.0),
        (("ego", "x"), 1e7),
        (("ego", "speed"), 200.0),
        (("ego", "speed"), -1.0),
        (("ego", "curvature"), 100.0),
        (("vehicle", "max_deceleration"), 0.01),
        (("vehicle", "max_curvature"), 1e-4),
        (("vehicle", "length"), 100.0),
        (("options", "dt"), 1.0),
        (("options", "horizon_time"), 0.02),
        (("options", "num_candidates"), 2000),
        (("options", "time_budget_ms"), 1.0),
        (("options", "seed"), -1),
        (("lane", "left_width"), 0.0),
        (("lane", "right_width"), [1.0, 2.0]),
        (("options", "generator"), "magic"),
    ]:
        body = json.loads(json.dumps(base))
        body[path[0]][path[1]] = value
        variants.append(body)
    for obstacles in (
        [{"id": "a", "polygon": [[0, 0], [1, 1], [2, 2]]}],
        [{"id": "a", "circle": {"center": [0, 0], "radius": 1}}] * 2,
        [
            {
                "id": "a",
                "prediction": [
                    {"t": 1, "x": 0, "y": 0, "heading": 0},
                    {"t": 0, "x": 0, "y": 0, "heading": 0},
                ],
            }
        ],
        [{"id": "a", "circle": {"center": [-15, 0], "radius": 50}}],
        [{"id": "x" * 201, "circle": {"center": [0, 0], "radius": 1}}],
        [{"id": "a", "polygon": [[1e7, 1e7], [-1e7, 1e7], [0, -1e7]]}],
    ):
        variants.append({**base, "obstacles": obstacles})
    return [json.dumps(v).encode() for v in variants]


# --------------------------------------------------------------------------------------------------
# The attacks: each returns what the answers (or connections) were
# --------------------------------------------------------------------------------------------------

Outcome = Counter[str]


async def _gather_codes(calls: list[Awaitable[tuple[int, dict[str, str], bytes]]]) -> Outcome:
    codes: Outcome = Counter()
    for status, _, body in await asyncio.gather(*calls):
        codes[label(status, body)] += 1
    return codes


def type_error_bodies(svc: Service) -> tuple[bytes, bytes]:
    return type_error_body(svc.port, 1000, 440), type_error_body(svc.port, 1000, 75)


async def type_errors(svc: Service, bodies: tuple[bytes, bytes]) -> Outcome:
    """1 000 obstacles × 440 states of "" (15 MiB, ~1.7 M type errors), once, then four at once; and
    1 000 × 75 (below the structural bound: parsed, one error per obstacle)."""
    big, below = bodies
    codes = await _gather_codes([http(svc.port, "POST", "/v1/plan", big, JSON)])
    codes += await _gather_codes([http(svc.port, "POST", "/v1/plan", big, JSON) for _ in range(4)])
    codes += await _gather_codes([http(svc.port, "POST", "/v1/plan", below, JSON) for _ in range(4)])
    return codes


def empty_lists_body(svc: Service) -> bytes:
    return b'{"reference_line":[' + b",".join([b"[]"] * 5_000_000) + b'],"points":[[0,0]]}'


async def empty_lists(svc: Service, body: bytes) -> Outcome:
    """5 M empty lists in one body (15 MiB), five at once (the fifth passes the bodies' memory budget)."""
    calls = [http(svc.port, "POST", "/v1/frenet", body, JSON) for _ in range(5)]
    return await _gather_codes(calls)


async def _flood(
    svc: Service, path: str, body: bytes, clients: int, seconds: float
) -> tuple[Outcome, list[float]]:
    codes: Outcome = Counter()
    latencies: list[float] = []
    until = time.monotonic() + seconds

    async def client() -> None:
        while time.monotonic() < until:
            t0 = time.perf_counter()
            status, _, answer = await http(svc.port, "POST", path, body, JSON)
            latencies.append(1e3 * (time.perf_counter() - t0))
            codes[label(status, answer)] += 1
            if status == 503:
                await asyncio.sleep(0.2)  # a client that honours Retry-After a little

    await asyncio.gather(*(client() for _ in range(clients)))
    return codes, latencies


def candidates_body(svc: Service) -> bytes:
    body = demo(svc.port)
    body["options"].update(num_candidates=2000, num_points=100)
    return json.dumps(body).encode()


async def candidates_flood(svc: Service, body: bytes) -> Outcome:
    """40 clients posting /v1/candidates at the schema's limit (2 000 × 100 points) for 15 s."""
    codes, _ = await _flood(svc, "/v1/candidates", body, 40, 15.0)
    return codes


def coordinates_bodies(svc: Service) -> tuple[bytes, bytes]:
    road = [[0.1 * i, 0.0] for i in range(20_000)]
    frenet = json.dumps({"reference_line": road, "points": [[0.2 * i, 1.0] for i in range(10_000)]}).encode()
    cartesian = json.dumps(
        {"reference_line": road, "frenet": [[0.2 * i, 1.0] for i in range(10_000)]}
    ).encode()
    return frenet, cartesian


async def coordinates_flood(svc: Service, bodies: tuple[bytes, bytes]) -> Outcome:
    """40 clients posting /v1/frenet and /v1/cartesian at their limits (20 000 + 10 000 points), 10 s."""
    frenet, cartesian = bodies
    (a, _), (b, _) = await asyncio.gather(
        _flood(svc, "/v1/frenet", frenet, 20, 10.0), _flood(svc, "/v1/cartesian", cartesian, 20, 10.0)
    )
    return a + b


def budget_body(svc: Service) -> bytes:
    body = demo(svc.port)
    body["options"]["time_budget_ms"] = 1000.0
    return json.dumps(body).encode()


async def deadline(svc: Service, body: bytes) -> Outcome:
    """100 clients posting the demo with a 1 s budget for 10 s: every answer within the budget (plus
    the time to send it) or a 503; the slowest answers are reported."""
    codes, latencies = await _flood(svc, "/v1/plan", body, 100, 10.0)
    p50, p99, top = percentiles(latencies, (50, 99, 100))
    codes[f"answer ms p50 {p50:.0f} p99 {p99:.0f} max {top:.0f}"] += 1
    return codes


def largest_bodies(svc: Service) -> list[tuple[float, bytes]]:
    return [(budget, largest_request(svc.port, budget)) for budget in (60_000.0, 1000.0)]


async def largest(svc: Service, bodies: list[tuple[float, bytes]]) -> Outcome:
    """The largest valid request (every limit of the schema at once), with a 60 s and a 1 s budget."""
    from app.limits import MAX_BODY_BYTES

    codes: Outcome = Counter()
    for budget, body in bodies:
        t0 = time.perf_counter()
        status, _, answer = await http(svc.port, "POST", "/v1/plan", body, JSON, timeout=120)
        took = time.perf_counter() - t0
        what = answer[:80].decode(errors="replace") if status != 200 else json.loads(answer)["status"]
        codes[
            f"{status} ({len(body) / 2**20:.1f} MiB of {MAX_BODY_BYTES / 2**20:.0f}, {budget:.0f} ms budget: "
            f"{what}, {took:.1f} s)"
        ] += 1
    return codes


async def slow_headers(svc: Service, _: None) -> Outcome:
    """3 000 connections each sending a header line a second (held for up to 15 s)."""
    return await _hold(svc, 3000, 15.0, b"GET /healthz HTTP/1.1\r\nHost: x\r\n", b"X-Slow: 1\r\n")


async def idle_connections(svc: Service, _: None) -> Outcome:
    """1 100 connections that send nothing, the server started with a soft open-files limit of 1 024
    (the hard one as this machine has it)."""
    return await _hold(svc, 1100, 15.0, b"", b"")


async def _hold(svc: Service, count: int, seconds: float, first: bytes, drip: bytes) -> Outcome:
    codes: Outcome = Counter()
    t0 = time.monotonic()

    async def one() -> None:
        try:
            reader, writer = await asyncio.open_connection(HOST, svc.port)
        except OSError:
            codes["refused"] += 1
            return
        try:
            if first:
                writer.write(first)
            while time.monotonic() - t0 < seconds:
                with contextlib.suppress(TimeoutError):
                    data = await asyncio.wait_for(reader.read(1024), 1.0)
                    codes[f"closed by the server after {5 * round((time.monotonic() - t0) / 5)} s"] += 1
                    if data:
                        codes[f"answer {parse_answer(data)[0]}"] += 1
                    return
                if drip:
                    writer.write(drip)
                    await writer.drain()
            codes[f"still open after {seconds:.0f} s"] += 1
        except OSError:
            codes["reset"] += 1
        finally:
            writer.close()

    await asyncio.gather(*(one() for _ in range(count)))
    return codes


async def header_stream(svc: Service, _: None) -> Outcome:
    """One connection streaming unfinished header lines of 1 KiB as fast as it can (up to 300 MB)."""
    codes: Outcome = Counter()
    reader, writer = await asyncio.open_connection(HOST, svc.port)
    writer.write(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
    line = b"X-Filler: " + b"a" * 1014 + b"\r\n"
    sent = 0
    try:
        while sent < 300 * 2**20:
            writer.write(line * 64)
            await writer.drain()
            sent += 64 * len(line)
            with contextlib.suppress(TimeoutError):
                data = await asyncio.wait_for(reader.read(1024), 0.001)
                codes[f"answer {parse_answer(data)[0] or 'none'} after {sent // 1024} KiB"] += 1
                break
    except OSError:
        codes[f"closed by the server after {sent // 1024} KiB"] += 1
    finally:
        writer.close()
    return codes


async def held_bodies(svc: Service, _: None) -> Outcome:
    """100 requests declaring a 16 MiB body and sending all of it but the last byte, then waiting."""
    from app.limits import MAX_BODY_BYTES

    codes: Outcome = Counter()
    size = MAX_BODY_BYTES

    async def one() -> None:
        reader, writer = await asyncio.open_connection(HOST, svc.port)
        head = (
            "POST /v1/plan HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
            f"Content-Length: {size}\r\n\r\n"
        )
        writer.write(head.encode())
        chunk = b" " * 65536
        sent = 0
        try:
            while sent < size - 1:
                with contextlib.suppress(TimeoutError):
                    data = await asyncio.wait_for(reader.read(4096), 0.0001)
                    codes[f"answer {parse_answer(data)[0]} after {sent // 2**20} MiB sent"] += 1
                    return
                part = chunk[: min(len(chunk), size - 1 - sent)]
                try:
                    writer.write(part)
                    await writer.drain()
                except OSError:  # the server answered and closed while this was sending
                    data = await asyncio.wait_for(reader.read(4096), 5)
                    status = parse_answer(data)[0]
                    codes[f"answer {status} after {sent // 2**20} MiB sent" if status else "reset"] += 1
                    return
                sent += len(part)
            data = await asyncio.wait_for(reader.read(4096), 30)
            codes[f"answer {parse_answer(data)[0] or 'none'} with the body held"] += 1
        except (OSError, TimeoutError):
            codes["reset by the server (its answer lost)"] += 1
        finally:
            writer.close()

    await asyncio.gather(*(one() for _ in range(100)))
    return codes


async def hostile(svc: Service, plans: list[bytes]) -> Outcome:
    """Hostile bodies to every computing endpoint, and hostile planning requests, two at a time (one
    per plan process: each is parsed rather than refused for want of a process)."""
    gate = asyncio.Semaphore(2)

    async def gated(call: Awaitable[tuple[int, dict[str, str], bytes]]) -> tuple[int, dict[str, str], bytes]:
        async with gate:
            return await call

    calls = [
        http(svc.port, "POST", path, body, JSON)
        for body in HOSTILE_BODIES
        for path in ("/v1/plan", "/v1/candidates", "/v1/frenet", "/v1/cartesian")
    ]
    calls += [http(svc.port, "POST", p, b, JSON) for b in plans for p in ("/v1/plan", "/v1/candidates")]
    codes: Outcome = Counter()
    for status, _, body in await asyncio.gather(*(gated(c) for c in calls)):
        codes[label(status, body)] += 1
        if status >= 400 and status != 431 and not _error_shape(body):
            codes[f"{status} not in the error shape"] += 1
    return codes


def _error_shape(body: bytes) -> bool:
    try:
        error = json.loads(body)["error"]
    except (ValueError, KeyError, TypeError):
        return False
    return isinstance(error, dict) and {"code", "message", "details"} <= set(error)


def demo_body(svc: Service) -> bytes:
    return json.dumps(demo(svc.port)).encode()


async def protocol(svc: Service, body: bytes) -> Outcome:
    """The HTTP layer: a broken request line, an oversize head, a form, text, multipart, gzip, a
    duplicate key, an unknown path; each answer and whether it is in the error shape."""
    cases: list[tuple[str, Awaitable[tuple[int, dict[str, str], bytes]]]] = [
        ("broken request line", _raw(svc.port, b"GARBAGE\r\n\r\n")),
        (
            "a head of 70 KB (limit 64 KiB)",
            http(svc.port, "GET", "/healthz", headers={"X-Big": "a" * 70_000}),
        ),
        ("a head of 200 KB", http(svc.port, "GET", "/healthz", headers={"X-Big": "a" * 200_000})),
        (
            "form",
            http(svc.port, "POST", "/v1/plan", body, {"Content-Type": "application/x-www-form-urlencoded"}),
        ),
        ("text/plain", http(svc.port, "POST", "/v1/plan", body, {"Content-Type": "text/plain"})),
        (
            "multipart",
            http(svc.port, "POST", "/v1/plan", body, {"Content-Type": "multipart/form-data; boundary=x"}),
        ),
        ("no content type", http(svc.port, "POST", "/v1/plan", body)),
        ("gzip", http(svc.port, "POST", "/v1/plan", body, {**JSON, "Content-Encoding": "gzip"})),
        ("duplicate key", http(svc.port, "POST", "/v1/plan", body[:-1] + b', "ego": {}}', JSON)),
        ("unknown path", http(svc.port, "GET", "/v1/nowhere")),
        ("wrong method", http(svc.port, "DELETE", "/v1/plan")),
    ]
    codes: Outcome = Counter()
    answers = await asyncio.gather(*(call for _, call in cases))
    for (name, _), (status, _, answer) in zip(cases, answers, strict=True):
        shape = "error shape" if _error_shape(answer) else "no JSON body (the server's own)"
        codes[f"{name}: {status}, {shape}"] += 1
    return codes


async def _raw(port: int, data: bytes) -> tuple[int, dict[str, str], bytes]:
    reader, writer = await asyncio.open_connection(HOST, port)
    writer.write(data)
    await writer.drain()
    try:
        answer = await asyncio.wait_for(reader.read(), 10)
    except TimeoutError:
        answer = b""
    writer.close()
    return parse_answer(answer)


async def access(svc: Service, _: None) -> Outcome:
    """Keys and rate limit on (KAPPA_API_KEYS=k-1,k-2, KAPPA_RATE_LIMIT=5, burst 5): no key, a wrong
    key, a good key 20 times at once, /healthz and /readyz without a key, a CORS preflight from another
    origin, and the docs page's scripts."""
    port = svc.port
    codes: Outcome = Counter()
    key = {"Authorization": "Bearer k-2"}
    for name, call in [
        ("no key", http(port, "GET", "/v1/demo")),
        ("wrong key", http(port, "GET", "/v1/demo", headers={"Authorization": "Bearer nope"})),
        ("/healthz, no key", http(port, "GET", "/healthz")),
        ("/readyz, no key", http(port, "GET", "/readyz")),
        ("/metrics, no key", http(port, "GET", "/metrics")),
    ]:
        status, headers, _ = await call
        codes[f"{name}: {status}"] += 1
    answers = await asyncio.gather(*(http(port, "GET", "/v1/demo", headers=key) for _ in range(20)))
    for status, headers, _ in answers:
        codes[
            f"key, 20 at once: {status}" + (f" Retry-After {headers['retry-after']}" if status == 429 else "")
        ] += 1
    status, headers, _ = await http(
        port,
        "OPTIONS",
        "/v1/plan",
        headers={"Origin": "https://evil.example", "Access-Control-Request-Method": "POST"},
    )
    allowed = headers.get("access-control-allow-origin")
    codes[f"CORS preflight from another origin: {status}, allow-origin {allowed}"] += 1
    status, headers, page = await http(port, "GET", "/docs")
    external = page.count(b'src="http') + page.count(b'href="http')
    csp = "yes" if "content-security-policy" in headers else "no"
    codes[f"/docs: {status}, {external} external scripts or styles, CSP {csp}"] += 1
    return codes


def heavy_body(svc: Service) -> bytes:
    return largest_request(svc.port, 60_000.0)


async def kill_plan_process(svc: Service, body: bytes) -> Outcome:
    """Four heavy plans in flight, one plan process SIGKILLed: only its plan fails (503, retryable)."""
    tasks = [
        asyncio.ensure_future(http(svc.port, "POST", "/v1/plan", body, JSON, timeout=120)) for _ in range(4)
    ]
    await asyncio.sleep(4.0)
    victims = svc.roles()["plan"]
    if victims:
        os.kill(victims[0], signal.SIGKILL)
    codes: Outcome = Counter()
    for status, _, answer in await asyncio.gather(*tasks):
        code = json.loads(answer)["error"]["code"] if status != 200 and _error_shape(answer) else ""
        codes[f"{status} {code}".strip()] += 1
    for _ in range(100):
        if svc.ready():
            codes["/readyz 200 again"] += 1
            break
        await asyncio.sleep(0.2)
    return codes


async def shutdown(svc: Service, body: bytes) -> Outcome:
    """SIGTERM with six heavy plans queued or running: how each is answered, how long the stop takes
    (KAPPA_SHUTDOWN_TIMEOUT 8 s; 4 s for shutdown_cut, which cuts running plans after 1 s), and
    whether any process is left."""
    tasks = [
        asyncio.ensure_future(http(svc.port, "POST", "/v1/plan", body, JSON, timeout=60)) for _ in range(6)
    ]
    await asyncio.sleep(1.0)  # two parsing or planning, four queued
    pids = [p for pids in svc.roles().values() for p in pids]
    t0 = time.monotonic()
    assert svc.proc is not None
    svc.proc.send_signal(signal.SIGTERM)
    codes: Outcome = Counter()
    while svc.proc.poll() is None and time.monotonic() - t0 < 30:
        await asyncio.sleep(0.05)
    codes[f"stopped {time.monotonic() - t0:.1f} s after SIGTERM, exit {svc.proc.returncode}"] += 1
    for status, _, answer in await asyncio.gather(*tasks):
        code = json.loads(answer)["error"]["code"] if status not in (0, 200) and _error_shape(answer) else ""
        codes[f"{status or 'no answer'} {code}".strip()] += 1
    await asyncio.sleep(1.0)
    codes[f"processes left: {sum(_alive(p) for p in pids)}"] += 1
    return codes


async def kill_supervisor(svc: Service, _: None) -> Outcome:
    """SIGKILL the supervisor: do the workers and plan processes go too?"""
    pids = [p for pids in svc.roles().values() for p in pids]
    os.kill(svc.pid, signal.SIGKILL)
    await asyncio.sleep(3.0)
    return Counter({f"of {len(pids)} processes, alive 3 s later: {sum(_alive(p) for p in pids)}": 1})


# --------------------------------------------------------------------------------------------------
# Running them
# --------------------------------------------------------------------------------------------------


@contextlib.contextmanager
def attacker_niced() -> Iterator[None]:
    """Run the attack at niceness +10 (the server and the /healthz probe, started before, keep theirs):
    on a shared machine the attacker would be elsewhere, so its own CPU use should not delay the probe."""
    before = os.getpriority(os.PRIO_PROCESS, 0)
    os.setpriority(os.PRIO_PROCESS, 0, before + 10)
    try:
        yield
    finally:
        with contextlib.suppress(PermissionError):  # lowering it back needs the right to
            os.setpriority(os.PRIO_PROCESS, 0, before)


@dataclass(frozen=True)
class Attack:
    name: str
    run: Callable[[Service, Any], Awaitable[Outcome]]
    #: what it sends, made before /healthz is probed (building a 15 MiB body is not the attack)
    prepare: Callable[[Service], Any] | None = None
    #: the server it needs: extra environment, and the open-files limit it starts with
    env: tuple[tuple[str, str], ...] = ()
    open_files: tuple[int, int] | None = None
    #: whether it ends the server (a fresh one for the next)
    ends_server: bool = False
    #: whether /healthz is measured against the targets during it
    probed: bool = True


ATTACKS = [
    Attack("type_errors", type_errors, type_error_bodies),
    Attack("empty_lists", empty_lists, empty_lists_body),
    Attack("candidates_flood", candidates_flood, candidates_body),
    Attack("coordinates_flood", coordinates_flood, coordinates_bodies),
    Attack("deadline", deadline, budget_body),
    Attack("largest", largest, largest_bodies),
    Attack("slow_headers", slow_headers),
    Attack("header_stream", header_stream),
    Attack("held_bodies", held_bodies),
    Attack("hostile", hostile, hostile_plans_of),
    Attack("protocol", protocol, demo_body),
    Attack("kill_plan_process", kill_plan_process, heavy_body),
    Attack(
        "idle_connections", idle_connections, open_files=(1024, resource.getrlimit(resource.RLIMIT_NOFILE)[1])
    ),
    Attack(
        "access",
        access,
        env=(("KAPPA_API_KEYS", "k-1,k-2"), ("KAPPA_RATE_LIMIT", "5"), ("KAPPA_RATE_BURST", "5")),
    ),
    Attack("shutdown", shutdown, heavy_body, ends_server=True, probed=False),
    Attack(
        "shutdown_cut",
        shutdown,
        heavy_body,
        env=(("KAPPA_SHUTDOWN_TIMEOUT", "4"),),
        ends_server=True,
        probed=False,
    ),
    Attack("kill_supervisor", kill_supervisor, ends_server=True, probed=False),
]


def run(attacks: list[Attack]) -> int:
    """Run ``attacks`` in order (a fresh server whenever the settings change or one ended it); print a
    table; 0."""
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # thousands of connections from here
    rows = []
    svc: Service | None = None
    print(f"load average {Path('/proc/loadavg').read_text().strip()} (other work on this machine)")
    with tempfile.TemporaryDirectory(prefix="kappa-abuse-") as tmp:
        try:
            for attack in attacks:
                wanted = Service(dict(attack.env), attack.open_files)
                if svc is None or (svc.env, svc.open_files) != (wanted.env, wanted.open_files):
                    if svc is not None:
                        svc.stop()
                    svc = wanted
                    svc.start(Path(tmp))
                print(f"-- {attack.name}: {(attack.run.__doc__ or '').splitlines()[0]}", flush=True)
                data = attack.prepare(svc) if attack.prepare is not None else None
                t0 = time.monotonic()
                with probing(svc.port) as health, attacker_niced():
                    codes = asyncio.run(attack.run(svc, data))
                took = time.monotonic() - t0
                rss = svc.rss_mb() if not attack.ends_server else {}
                if not attack.ends_server:
                    time.sleep(1.5)  # a process over the limit is replaced after its request
                    rss = svc.rss_mb()
                rows.append((attack, codes, health, rss, took))
                _print_row(*rows[-1])
                if attack.ends_server:
                    svc.stop()
                    svc = None
        finally:
            if svc is not None:
                svc.stop()
    print(f"\n== summary (load average {Path('/proc/loadavg').read_text().strip()})")
    for attack, codes, health, rss, took in rows:
        met = _met(attack, codes, health, rss)
        h50, h99, hmax = percentiles(health["latencies"], (50, 99, 100))
        worker, plans = rss.get("worker", 0.0), rss.get("plan", 0.0)
        print(
            f"{attack.name:18s} {took:5.1f} s  /healthz p50 {h50:5.1f} p99 {h99:6.1f} max {hmax:6.1f} ms "
            f"({health['failures']} failed)  RSS worker {worker:4.0f} plan {plans:4.0f} MiB  {met}"
        )
    return 0


def _print_row(
    attack: Attack, codes: Outcome, health: dict[str, Any], rss: dict[str, float], took: float
) -> None:
    for what, n in sorted(codes.items(), key=lambda kv: -kv[1]):
        print(f"   {n:6d} × {what}")
    h50, h99, hmax = percentiles(health["latencies"], (50, 99, 100))
    print(
        f"   /healthz p50 {h50:.1f} p99 {h99:.1f} max {hmax:.1f} ms ({len(health['latencies'])} probes, "
        f"{health['failures']} failed); RSS after [MiB]: "
        + ", ".join(f"{role} {mb:.0f}" for role, mb in rss.items())
        + f"; {took:.1f} s",
        flush=True,
    )


def _met(attack: Attack, codes: Outcome, health: dict[str, Any], rss: dict[str, float]) -> str:
    misses = []
    if attack.probed:
        h99, hmax = percentiles(health["latencies"], (99, 100))
        if not (h99 <= HEALTH_P99_MS and hmax <= HEALTH_MAX_MS and health["failures"] == 0):
            misses.append("/healthz")
    if any(mb > RSS_MB for mb in rss.values()):
        misses.append("memory")
    if any(what.startswith("500") for what in codes):
        misses.append("500")
    return "met" if not misses else "MISSED: " + ", ".join(misses)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--only", help="comma-separated attacks: " + ", ".join(a.name for a in ATTACKS))
    args = parser.parse_args(argv)
    attacks = ATTACKS
    if args.only:
        names = set(args.only.split(","))
        unknown = names - {a.name for a in ATTACKS}
        if unknown:
            parser.error(f"unknown attacks: {', '.join(sorted(unknown))}")
        attacks = [a for a in ATTACKS if a.name in names]
    return run(attacks)


if __name__ == "__main__":
    sys.exit(main())
