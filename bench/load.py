"""Load test of a running service, loopback only: ``python bench/load.py`` prints figures (asserts nothing).

``--clients`` concurrent clients (default 200) post the demo U-turn (``GET /v1/demo``) to ``/v1/plan``
back to back for ``--duration`` seconds (default 10), then wait for the plans in flight and stop. A
separate process probes ``GET /healthz`` every ``--probe-interval`` seconds meanwhile, so that its
latency is the server's, not the load generator's event loop's. The clients are aiohttp's (a dev
dependency), the cheapest on CPU of the usual ones: the load generator shares the CPUs with the server.

Without ``--base-url`` the script starts its own servers: ``--replicas`` separate ``python -m app``
processes (default 1), each on a free loopback port with ``KAPPA_WORKERS=--workers`` (and
``KAPPA_PLAN_PROCESSES=--plan-processes`` if given; other ``KAPPA_*`` variables of the environment pass
through), each pinned to ``--cpus-per-replica`` CPUs of its own if given (as the kubelet's static CPU
manager pins a pod's whole CPUs), and stops them afterwards. ``--base-url`` may be given several times
(e.g. ``kubectl port-forward`` to several pods). Either way the clients are spread over the servers as a
Service spreads connections: client ``i`` keeps its connection to server ``i mod N``; the prober asks
each in turn. A base URL whose host is not a loopback address is refused: this script loads a machine
with a few thousand requests and must not be pointed at anyone else's.

Printed: plans per second (answers 200 / wall time from the first request to the last answer) in all and
per server, p50/p95/p99 latency of the plans [ms], errors (no answer: connection refused or reset,
timeout), the count of answers other than 200 by status, the /healthz latency during the load (p50/max
[ms]), the CPU time per plan of the servers and of the load generator, and the load average before and
after (other jobs on the machine change the figures).

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


def replica_cpus(index: int, per_replica: int | None) -> set[int] | None:
    """The CPUs replica ``index`` is pinned to: ``per_replica`` of those this process may use, the next
    ones for each replica (wrapping around); None: not pinned."""
    if per_replica is None:
        return None
    allowed = sorted(os.sched_getaffinity(0))
    return {allowed[(index * per_replica + k) % len(allowed)] for k in range(per_replica)}


@contextlib.contextmanager
def own_servers(
    replicas: int, workers: int, plan_processes: int | None, cpus_per_replica: int | None, logs: Path
) -> Iterator[list[tuple[str, int]]]:
    """Run ``replicas`` separate ``python -m app`` with ``workers`` workers (and ``plan_processes`` if
    given) on free loopback ports, each pinned to ``cpus_per_replica`` CPUs if given; yield their base
    URLs and pids once every one answers /healthz. Their logs: ``logs``/server-``i``.log."""
    procs: list[tuple[str, subprocess.Popen[bytes], Path]] = []
    try:
        for index in range(replicas):
            port = free_port()
            env = {**os.environ, "KAPPA_HOST": "127.0.0.1", "KAPPA_PORT": str(port)}
            env["KAPPA_WORKERS"] = str(workers)
            if plan_processes is not None:
                env["KAPPA_PLAN_PROCESSES"] = str(plan_processes)
            cpus = replica_cpus(index, cpus_per_replica)
            log = logs / f"server-{index}.log"
            with log.open("wb") as out:
                proc = subprocess.Popen(
                    [sys.executable, "-m", "app"],
                    cwd=ROOT,
                    env=env,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    # its workers and plan processes inherit the mask
                    preexec_fn=None if cpus is None else lambda cpus=cpus: os.sched_setaffinity(0, cpus),
                )
            procs.append((f"http://127.0.0.1:{port}", proc, log))
        deadline = time.monotonic() + STARTUP_TIMEOUT
        for url, proc, log in procs:
            while True:
                if proc.poll() is not None:
                    sys.exit(f"the server exited with {proc.returncode}; see {log}")
                with contextlib.suppress(OSError), urllib.request.urlopen(f"{url}/healthz", timeout=1) as ok:
                    if ok.status == 200:
                        break
                if time.monotonic() > deadline:
                    sys.exit(f"the server did not answer /healthz within {STARTUP_TIMEOUT:.0f} s; see {log}")
                time.sleep(0.2)
        yield [(url, proc.pid) for url, proc, _ in procs]
    finally:
        for _, proc, _ in procs:
            proc.send_signal(signal.SIGINT)  # the server's graceful shutdown, workers included
        for _, proc, _ in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def probe_health(urls: list[str], interval: float, stop: mp.synchronize.Event, out: Connection) -> None:
    """In a process of its own: GET /healthz of each of ``urls`` in turn, one every ``interval`` s, each on
    a kept-alive connection (the standard library's, the least work on this side) until ``stop``; send
    (time [s since the epoch], latency [ms]) of each answer and the count of failures."""
    latencies: list[tuple[float, float]] = []
    failures = 0
    conns = []
    for url in urls:
        parts = urlsplit(url)
        host, port = parts.hostname or "127.0.0.1", parts.port or 80
        conns.append(http.client.HTTPConnection(host, port, timeout=REQUEST_TIMEOUT))
    turn = 0
    while not stop.is_set():
        conn = conns[turn % len(conns)]
        turn += 1
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
    for conn in conns:
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
    per_server: Counter[int] = field(default_factory=Counter)  # answers 200 by the server's index
    first: float = float("inf")
    last: float = 0.0


async def client_loop(
    session: aiohttp.ClientSession, server: int, body: bytes, until: float, tally: Tally
) -> None:
    """Post ``body`` to /v1/plan of server number ``server`` back to back until ``until`` (monotonic time)."""
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
            tally.per_server[server] += 1
            tally.latencies_ms.append(1e3 * (t1 - t0))
            total = TOTAL_MS.search(content, max(0, len(content) - 300))
            if total:
                tally.planner_ms.append(float(total.group(1)))


async def load(urls: list[str], clients: int, duration: float) -> Tally:
    """``clients`` concurrent clients for ``duration`` s, client ``i`` on ``urls[i % len(urls)]``; the
    plans in flight at the end are awaited.

    aiohttp rather than httpx: measured here, it spends 0.3 ms of CPU per request where httpx spends
    5 ms, and this process shares the CPUs with the server.
    """
    timeout = aiohttp.ClientTimeout(total=REQUEST_TIMEOUT)
    async with contextlib.AsyncExitStack() as stack:
        sessions = []
        for index, url in enumerate(urls):
            share = len(range(index, clients, len(urls)))  # the clients this server gets
            connector = aiohttp.TCPConnector(limit=max(1, share))
            sessions.append(
                await stack.enter_async_context(
                    aiohttp.ClientSession(url, connector=connector, timeout=timeout)
                )
            )
        async with sessions[0].get("/v1/demo") as demo:
            demo.raise_for_status()
            body = await demo.read()
        for session in sessions:
            async with session.post(
                "/v1/plan", data=body, headers={"content-type": "application/json"}
            ) as warm:
                warm.raise_for_status()
        tally = Tally()
        until = time.monotonic() + duration
        await asyncio.gather(
            *(client_loop(sessions[i % len(urls)], i % len(urls), body, until, tally) for i in range(clients))
        )
    return tally


def percentiles(values: list[float], qs: tuple[float, ...]) -> list[float]:
    """The ``qs`` percentiles of ``values`` (NaN when empty)."""
    if not values:
        return [float("nan")] * len(qs)
    return [float(v) for v in np.percentile(np.asarray(values), qs)]


@dataclass
class Result:
    """The figures of one load run."""

    servers: list[str]
    ok: int  # answers 200
    wall_s: float  # from the first request to the last answer
    per_server: list[int]  # answers 200 by server
    latency_ms: list[float]  # p50, p95, p99 of the answers 200
    planner_ms: list[float]  # p50, p99 of diagnostics.timing_ms.total
    errors: dict[str, int]  # no answer, by exception
    others: dict[int, int]  # answers other than 200, by status
    health_ms: list[float]  # /healthz p50, p95, max
    health_probes: int
    health_failures: int
    slow_health: list[tuple[float, float]]  # (s after the start, ms) of the probes ≥ 50 ms
    cpu_ms: tuple[float, float, float] | None  # per plan: HTTP processes, plan processes, load generator
    server_cpus: float | None  # CPU time of the servers' processes / wall time: the CPUs they got
    load_before: tuple[float, float, float]  # os.getloadavg()
    load_after: tuple[float, float, float]

    @property
    def plans_per_s(self) -> float:
        return self.ok / self.wall_s


def run(urls: list[str], args: argparse.Namespace, server_pids: list[int] | None = None) -> Result:
    """Load ``urls`` as ``args`` say; the figures (with the CPU time of ``server_pids``' processes)."""
    load_before = os.getloadavg()
    ctx = mp.get_context("spawn")
    stop = ctx.Event()
    receiver, sender = ctx.Pipe(duplex=False)
    prober = ctx.Process(target=probe_health, args=(urls, args.probe_interval, stop, sender))
    prober.start()
    tree = {pid: depth for root in server_pids or [] for pid, depth in process_tree(root).items()}
    cpu_before = {pid: cpu_seconds(pid) for pid in tree}
    self_before = resource.getrusage(resource.RUSAGE_SELF)
    started = time.time()
    try:
        tally = asyncio.run(load(urls, args.clients, args.duration))
    finally:
        stop.set()
    self_after = resource.getrusage(resource.RUSAGE_SELF)
    cpu_used = {pid: cpu_seconds(pid) - before for pid, before in cpu_before.items()}
    probes, health_failures = receiver.recv()
    prober.join()
    health = [ms for _, ms in probes]

    ok = tally.statuses.get(200, 0)
    cpu_ms = None
    wall_s = max(tally.last - tally.first, 1e-9)
    server_cpus = sum(cpu_used.values()) / wall_s if cpu_used else None
    if cpu_used and ok:
        # granian (python -m app) serves in children of the process it was started as, whatever the
        # number of workers; plan processes are one level further down
        http_depth = 1
        served = sum(c for pid, c in cpu_used.items() if tree[pid] == http_depth)
        plans = sum(c for pid, c in cpu_used.items() if tree[pid] > http_depth)
        generator = cpu_delta(self_before, self_after)
        cpu_ms = (1e3 * served / ok, 1e3 * plans / ok, 1e3 * generator / ok)
    return Result(
        servers=urls,
        ok=ok,
        wall_s=wall_s,
        per_server=[tally.per_server[i] for i in range(len(urls))],
        latency_ms=percentiles(tally.latencies_ms, (50, 95, 99)),
        planner_ms=percentiles(tally.planner_ms, (50, 99)),
        errors=dict(tally.errors),
        others={s: n for s, n in sorted(tally.statuses.items()) if s != 200},
        health_ms=percentiles(health, (50, 95, 100)),
        health_probes=len(health),
        health_failures=health_failures,
        slow_health=[(t - started, ms) for t, ms in probes if ms >= 50.0],
        cpu_ms=cpu_ms,
        server_cpus=server_cpus,
        load_before=load_before,
        load_after=os.getloadavg(),
    )


def report(result: Result, args: argparse.Namespace) -> None:
    """Print ``result`` of a run with ``args``."""
    if not args.base_url:
        pinned = f", {args.cpus_per_replica} CPU(s) each" if args.cpus_per_replica else ", not pinned"
        processes = f", KAPPA_PLAN_PROCESSES={args.plan_processes}" if args.plan_processes is not None else ""
        started = f"{args.replicas} started here (KAPPA_WORKERS={args.workers}{processes}{pinned})"
        print(f"servers           {started}")
    for url, ok in zip(result.servers, result.per_server, strict=True):
        print(f"server            {url}: {ok / result.wall_s:.1f} plans/s")
    print(f"clients           {args.clients} for {args.duration:g} s on {os.cpu_count()} CPUs")
    print(f"plans/s           {result.plans_per_s:.1f}  ({result.ok} answers 200 in {result.wall_s:.2f} s)")
    p50, p95, p99 = result.latency_ms
    print(f"latency [ms]      p50 {p50:.1f}  p95 {p95:.1f}  p99 {p99:.1f}")
    m50, m99 = result.planner_ms
    print(f"planner [ms]      p50 {m50:.1f}  p99 {m99:.1f}  (diagnostics.timing_ms.total of the answers)")
    print(f"errors            {sum(result.errors.values())} {result.errors or ''}")
    print(f"non-200 answers   {sum(result.others.values())} {result.others or ''}")
    h50, h95, hmax = result.health_ms
    print(
        f"/healthz [ms]     p50 {h50:.1f}  p95 {h95:.1f}  max {hmax:.1f}  ({result.health_probes} probes, "
        f"{result.health_failures} failed; target < 50)"
    )
    if result.slow_health:
        slow = result.slow_health
        when = ", ".join(f"{ms:.0f} ms at {t:.1f} s" for t, ms in slow[:8])
        print(f"/healthz ≥ 50 ms  {len(slow)}: {when}{' …' if len(slow) > 8 else ''} (s after the start)")
    if result.cpu_ms:
        served, plans, generator = result.cpu_ms
        print(
            f"CPU per plan [ms] HTTP processes {served:.1f}, plan processes {plans:.1f}, "
            f"this load generator {generator:.1f}"
        )
    if result.server_cpus is not None:
        given = args.replicas * args.cpus_per_replica if args.cpus_per_replica else os.cpu_count()
        print(f"CPUs used         {result.server_cpus:.2f} by the servers (of {given} they may use)")
    before, after = (" ".join(f"{v:.2f}" for v in load) for load in (result.load_before, result.load_after))
    print(f"load average      {before} before, {after} after (1, 5, 15 min; other jobs slow the figures)")


def cpu_delta(before: resource.struct_rusage, after: resource.struct_rusage) -> float:
    """User + system CPU time between two ``getrusage`` answers [s]."""
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def parser() -> argparse.ArgumentParser:
    """The command line's options."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument(
        "--base-url",
        action="append",
        help="a running server (loopback only); repeat it to spread the clients over several; "
        "default: start --replicas servers here",
    )
    parser.add_argument("--replicas", type=int, default=1, help="servers started here, each a python -m app")
    parser.add_argument("--workers", type=int, default=1, help="KAPPA_WORKERS of each server started here")
    parser.add_argument("--plan-processes", type=int, help="KAPPA_PLAN_PROCESSES of each server started here")
    parser.add_argument(
        "--cpus-per-replica", type=int, help="pin each server started here to this many CPUs of its own"
    )
    parser.add_argument("--clients", type=int, default=200, help="concurrent clients, over all servers")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds of load")
    parser.add_argument("--probe-interval", type=float, default=0.1, help="seconds between /healthz probes")
    parser.add_argument(
        "--server-logs", type=Path, help="keep the logs of the servers started here in this folder"
    )
    return parser


def check_bounds(options: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse options beyond what this machine should be asked (``options.error`` exits)."""
    if not (1 <= args.clients <= 2000 and 0 < args.duration <= 600 and 1 <= args.workers <= 64):
        options.error("keep it bounded: 1 ≤ clients ≤ 2000, 0 < duration ≤ 600 s, 1 ≤ workers ≤ 64")
    if not 1 <= args.replicas <= 16 or args.replicas > args.clients:
        options.error("1 ≤ replicas ≤ 16, and no more replicas than clients")
    cpus = len(os.sched_getaffinity(0))
    if args.cpus_per_replica is not None and not 1 <= args.cpus_per_replica <= cpus:
        options.error(f"1 ≤ cpus-per-replica ≤ {cpus} (the CPUs this process may use)")


def main(argv: list[str] | None = None) -> int:
    """Parse the options, start the servers if asked, run the load, print the figures."""
    options = parser()
    args = options.parse_args(argv)
    check_bounds(options, args)
    if args.base_url:
        urls = [url.rstrip("/") for url in args.base_url]
        for url in urls:
            require_loopback(url)
        report(run(urls, args), args)
        return 0
    with tempfile.TemporaryDirectory(prefix="kappa-load-") as tmp:
        logs = args.server_logs or Path(tmp)
        logs.mkdir(parents=True, exist_ok=True)
        with own_servers(
            args.replicas, args.workers, args.plan_processes, args.cpus_per_replica, logs
        ) as servers:
            result = run([url for url, _ in servers], args, [pid for _, pid in servers])
        report(result, args)
        lines = sum(len(log.read_text(errors="replace").splitlines()) for log in logs.glob("server-*.log"))
        print(f"server logs       {lines} lines ({logs if args.server_logs else 'removed'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
