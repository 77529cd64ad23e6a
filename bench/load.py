"""Load test of a running service, loopback only: ``python bench/load.py`` prints figures (asserts nothing).

``--clients`` concurrent clients (default 200) post the demo U-turn (``GET /v1/demo``) to ``/v1/plan``
back to back for ``--duration`` seconds (default 10), then wait for the plans in flight and stop. A
separate process probes ``GET /healthz`` every ``--probe-interval`` seconds meanwhile, so that its
latency is the server's, not the load generator's event loop's. The clients are aiohttp's (a dev
dependency), the cheapest on CPU of the usual ones: the load generator shares the CPUs with the server.

Without ``--base-url`` the script starts its own server, ``python -m app`` on a free loopback port with
``KAPPA_WORKERS=--workers`` (other ``KAPPA_*`` variables of the environment pass through), and stops it
afterwards. A base URL whose host is not a loopback address is refused: this script loads a machine
with a few thousand requests and must not be pointed at anyone else's.

Printed: plans per second (answers 200 / wall time from the first request to the last answer),
p50/p95/p99 latency of the plans [ms], errors (no answer: connection refused or reset, timeout), the
count of answers other than 200 by status, and the /healthz latency during the load (p50/max [ms]).

Target (issue "a service people can run in production") on a 2-core machine: ≥ 60 plans/s, 0 errors,
200 concurrent clients accepted; /healthz < 50 ms while plans run. The load generator shares the CPU
with the server, so the figures are a lower bound of what the server does on its own.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import http.client
import ipaddress
import multiprocessing as mp
import os
import re
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path
from urllib.parse import urlsplit

import aiohttp
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: the planner's own wall time in an answer (``diagnostics.timing_ms.total``, near its end)
TOTAL_MS = re.compile(rb'"timing_ms":\{"total":([-0-9.eE+]+)')
#: longest wait for one answer [s]
REQUEST_TIMEOUT = 60.0
#: longest wait for a server of our own to answer /healthz [s]
STARTUP_TIMEOUT = 120.0


def require_loopback(url: str) -> None:
    """Exit unless every address ``url``'s host resolves to is a loopback address."""
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        sys.exit(f"not an http(s) URL: {url!r}")
    try:
        infos = socket.getaddrinfo(parts.hostname, parts.port or 80, proto=socket.IPPROTO_TCP)
    except socket.gaierror as exc:
        sys.exit(f"cannot resolve {parts.hostname!r}: {exc}")
    addresses = {info[4][0] for info in infos}
    remote = sorted(a for a in addresses if not ipaddress.ip_address(a.split("%")[0]).is_loopback)
    if remote:
        sys.exit(f"refusing to load {parts.hostname!r}: not a loopback address ({', '.join(remote)})")


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


@contextlib.contextmanager
def own_server(workers: int, plan_processes: int | None, log: Path) -> Iterator[tuple[str, int]]:
    """Run ``python -m app`` with ``workers`` workers (and ``plan_processes`` if given) on a free
    loopback port; yield its base URL and pid."""
    port = free_port()
    env = {**os.environ, "KAPPA_HOST": "127.0.0.1", "KAPPA_PORT": str(port), "KAPPA_WORKERS": str(workers)}
    if plan_processes is not None:
        env["KAPPA_PLAN_PROCESSES"] = str(plan_processes)
    with log.open("wb") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "app"], cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT
        )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while True:
            if proc.poll() is not None:
                sys.exit(f"the server exited with {proc.returncode}; see {log}")
            with contextlib.suppress(OSError), urllib.request.urlopen(f"{url}/healthz", timeout=1) as ok:
                if ok.status == 200:
                    break
            if time.monotonic() > deadline:
                sys.exit(f"the server did not answer /healthz within {STARTUP_TIMEOUT:.0f} s; see {log}")
            time.sleep(0.2)
        yield url, proc.pid
    finally:
        proc.send_signal(signal.SIGINT)  # the server's graceful shutdown, workers included
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def probe_health(url: str, interval: float, stop: mp.synchronize.Event, out: Connection) -> None:
    """In a process of its own: GET ``url``/healthz every ``interval`` s on one kept-alive connection
    (the standard library's, the least work on this side) until ``stop``; send (time [s since the
    epoch], latency [ms]) of each answer and the count of failures."""
    parts = urlsplit(url)
    latencies: list[tuple[float, float]] = []
    failures = 0
    host, port = parts.hostname or "127.0.0.1", parts.port or 80
    conn = http.client.HTTPConnection(host, port, timeout=REQUEST_TIMEOUT)
    while not stop.is_set():
        t0 = time.perf_counter()
        try:
            conn.request("GET", "/healthz")
            answer = conn.getresponse()
            answer.read()
            ok = answer.status == 200
        except (OSError, http.client.HTTPException):
            conn.close()
            ok = False
        if ok:
            latencies.append((time.time(), 1e3 * (time.perf_counter() - t0)))
        else:
            failures += 1
        stop.wait(interval)
    conn.close()
    out.send((latencies, failures))


def process_tree(root: int) -> dict[int, int]:
    """pid → depth below ``root`` (0) of ``root`` and its descendants (Linux ``/proc``; else ``{}``)."""
    tree, todo = {}, [(root, 0)]
    while todo:
        pid, depth = todo.pop()
        tree[pid] = depth
        for task in Path(f"/proc/{pid}/task").glob("*"):
            with contextlib.suppress(OSError):
                todo.extend((int(c), depth + 1) for c in (task / "children").read_text().split())
    return tree if Path(f"/proc/{root}").exists() else {}


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of ``pid`` so far [s] (0 when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class Tally:
    """What the clients saw."""

    latencies_ms: list[float] = field(default_factory=list)
    planner_ms: list[float] = field(default_factory=list)
    statuses: Counter[int] = field(default_factory=Counter)
    errors: Counter[str] = field(default_factory=Counter)
    first: float = float("inf")
    last: float = 0.0


async def client_loop(session: aiohttp.ClientSession, body: bytes, until: float, tally: Tally) -> None:
    """Post ``body`` to /v1/plan back to back until ``until`` (monotonic time)."""
    headers = {"content-type": "application/json"}
    while time.monotonic() < until:
        t0 = time.perf_counter()
        tally.first = min(tally.first, t0)
        try:
            async with session.post("/v1/plan", data=body, headers=headers) as r:
                content = await r.read()
        except (aiohttp.ClientError, TimeoutError) as exc:
            tally.errors[type(exc).__name__] += 1
            await asyncio.sleep(0.05)  # a refused connection must not spin
            continue
        t1 = time.perf_counter()
        tally.last = max(tally.last, t1)
        tally.statuses[r.status] += 1
        if r.status == 200:
            tally.latencies_ms.append(1e3 * (t1 - t0))
            total = TOTAL_MS.search(content, max(0, len(content) - 300))
            if total:
                tally.planner_ms.append(float(total.group(1)))


async def load(url: str, clients: int, duration: float) -> Tally:
    """``clients`` concurrent clients for ``duration`` s; the plans in flight at the end are awaited.

    aiohttp rather than httpx: measured here, it spends 0.3 ms of CPU per request where httpx spends
    5 ms, and this process shares the CPUs with the server.
    """
    connector = aiohttp.TCPConnector(limit=clients)
    timeout = aiohttp.ClientTimeout(total=REQUEST_TIMEOUT)
    async with aiohttp.ClientSession(url, connector=connector, timeout=timeout) as session:
        async with session.get("/v1/demo") as demo:
            demo.raise_for_status()
            body = await demo.read()
        async with session.post("/v1/plan", data=body, headers={"content-type": "application/json"}) as warm:
            warm.raise_for_status()
        tally = Tally()
        until = time.monotonic() + duration
        await asyncio.gather(*(client_loop(session, body, until, tally) for _ in range(clients)))
    return tally


def percentiles(values: list[float], qs: tuple[float, ...]) -> list[float]:
    """The ``qs`` percentiles of ``values`` (NaN when empty)."""
    if not values:
        return [float("nan")] * len(qs)
    return [float(v) for v in np.percentile(np.asarray(values), qs)]


def run(url: str, args: argparse.Namespace, server_pid: int | None = None) -> None:
    """Load ``url`` and print the figures (and the CPU time of ``server_pid``'s processes, if given)."""
    ctx = mp.get_context("spawn")
    stop = ctx.Event()
    receiver, sender = ctx.Pipe(duplex=False)
    prober = ctx.Process(target=probe_health, args=(url, args.probe_interval, stop, sender))
    prober.start()
    tree = process_tree(server_pid) if server_pid else {}
    cpu_before = {pid: cpu_seconds(pid) for pid in tree}
    self_before = resource.getrusage(resource.RUSAGE_SELF)
    started = time.time()
    try:
        tally = asyncio.run(load(url, args.clients, args.duration))
    finally:
        stop.set()
    self_after = resource.getrusage(resource.RUSAGE_SELF)
    cpu_used = {pid: cpu_seconds(pid) - before for pid, before in cpu_before.items()}
    probes, health_failures = receiver.recv()
    prober.join()
    health = [ms for _, ms in probes]
    slow = [(t - started, ms) for t, ms in probes if ms >= 50.0]

    ok = tally.statuses.get(200, 0)
    wall = max(tally.last - tally.first, 1e-9)
    p50, p95, p99 = percentiles(tally.latencies_ms, (50, 95, 99))
    h50, h95, hmax = percentiles(health, (50, 95, 100))
    m50, m99 = percentiles(tally.planner_ms, (50, 99))
    others = {s: n for s, n in sorted(tally.statuses.items()) if s != 200}
    own = f" (started here, KAPPA_WORKERS={args.workers}" if args.base_url is None else ""
    if own:
        own += f", KAPPA_PLAN_PROCESSES={args.plan_processes})" if args.plan_processes is not None else ")"
    print(f"server            {url}{own}")
    print(f"clients           {args.clients} for {args.duration:g} s on {os.cpu_count()} CPUs")
    print(f"plans/s           {ok / wall:.1f}  ({ok} answers 200 in {wall:.2f} s)")
    print(f"latency [ms]      p50 {p50:.1f}  p95 {p95:.1f}  p99 {p99:.1f}")
    print(f"planner [ms]      p50 {m50:.1f}  p99 {m99:.1f}  (diagnostics.timing_ms.total of the answers)")
    print(f"errors            {sum(tally.errors.values())} {dict(tally.errors) or ''}")
    print(f"non-200 answers   {sum(others.values())} {others or ''}")
    print(
        f"/healthz [ms]     p50 {h50:.1f}  p95 {h95:.1f}  max {hmax:.1f}  ({len(health)} probes, "
        f"{health_failures} failed; target < 50)"
    )
    if slow:
        when = ", ".join(f"{ms:.0f} ms at {t:.1f} s" for t, ms in slow[:8])
        print(f"/healthz ≥ 50 ms  {len(slow)}: {when}{' …' if len(slow) > 8 else ''} (s after the start)")
    if cpu_used and ok:
        # granian (python -m app) serves in children of the process it was started as, whatever the
        # number of workers; plan processes are one level further down
        http_depth = 1
        http = sum(c for pid, c in cpu_used.items() if tree[pid] == http_depth)
        plans = sum(c for pid, c in cpu_used.items() if tree[pid] > http_depth)
        print(
            f"CPU per plan [ms] HTTP processes {1e3 * http / ok:.1f}, plan processes {1e3 * plans / ok:.1f}, "
            f"this load generator {1e3 * cpu_delta(self_before, self_after) / ok:.1f}"
        )


def cpu_delta(before: resource.struct_rusage, after: resource.struct_rusage) -> float:
    """User + system CPU time between two ``getrusage`` answers [s]."""
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv: list[str] | None = None) -> int:
    """Parse the options, start a server if asked, run the load."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--base-url", help="a running server (loopback only); default: start one")
    parser.add_argument("--workers", type=int, default=1, help="KAPPA_WORKERS of the server started here")
    parser.add_argument(
        "--plan-processes", type=int, help="KAPPA_PLAN_PROCESSES of the server started here"
    )
    parser.add_argument("--clients", type=int, default=200, help="concurrent clients")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds of load")
    parser.add_argument("--probe-interval", type=float, default=0.1, help="seconds between /healthz probes")
    parser.add_argument("--server-log", type=Path, help="keep the log of the server started here there")
    args = parser.parse_args(argv)
    if not (1 <= args.clients <= 2000 and 0 < args.duration <= 600 and 1 <= args.workers <= 64):
        parser.error("keep it bounded: 1 ≤ clients ≤ 2000, 0 < duration ≤ 600 s, 1 ≤ workers ≤ 64")
    if args.base_url:
        url = args.base_url.rstrip("/")
        require_loopback(url)
        run(url, args)
        return 0
    with tempfile.TemporaryDirectory(prefix="kappa-load-") as tmp:
        log = args.server_log or Path(tmp) / "server.log"
        with own_server(args.workers, args.plan_processes, log) as (url, pid):
            run(url, args, pid)
        lines = log.read_text(encoding="utf-8", errors="replace").splitlines()
        print(f"server log        {len(lines)} lines ({log if args.server_log else 'removed'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
