"""Run a Dockerfile's image without a Docker engine: replay its build in a fresh virtual environment,
start its exact command with its environment, probe it with its own HEALTHCHECK, run a test command
against it, stop it.

    python .ci/dockerfile_replay.py --port-env KAPPA_PORT --host-env KAPPA_HOST \\
        -- python -m pytest tests/regression --base-url {url}

What is read from the Dockerfile (parsed with the ``dockerfile`` package, BuildKit's own parser) rather
than repeated here, so that a change there is what runs here:

* the build stage the final stage copies from: its ``ENV``, ``ARG``, ``WORKDIR``, ``COPY`` (from the
  build context filtered by ``.dockerignore``, as ``docker build`` sends it) and ``RUN`` steps, run in
  a scratch directory with ``$VIRTUAL_ENV`` pointing to a fresh virtual environment there;
* the final stage: ``ENV`` (the server's whole environment, with ``$PATH`` and ``$VIRTUAL_ENV`` mapped
  as above), ``WORKDIR`` (an empty directory: no sources next to the server), ``CMD``/``ENTRYPOINT``,
  ``HEALTHCHECK``, ``EXPOSE`` and ``USER``.

Not replayed, and why: the final stage's ``RUN`` steps (they make the system user; checked instead:
``USER`` is present and not root) and the base image itself (the interpreter is this one; its
version is compared with the image tag). The port is overridden with a free one and the host with
127.0.0.1 (nothing listens beyond this machine). An instruction the replay does not know fails the run.

Exit status: 0 when everything passed; else 1 with the reason and the server's log.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import dockerfile
from docker.utils.build import exclude_paths

DEFAULT_SHELL = ["/bin/sh", "-c"]
#: variables passed from this environment to the server on top of the image's (see env/README:
#: OpenBLAS needs them on some processors here)
PASS_THROUGH = ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "TMPDIR")


class ReplayError(Exception):
    """The Dockerfile cannot be replayed, or what it runs failed."""


def say(message: str) -> None:
    print(message, flush=True)


# --------------------------------------------------------------------------------------------------
# Dockerfile words: quotes, escapes and $VAR / ${VAR} / ${VAR:-word} / ${VAR:+word} as Docker does
# --------------------------------------------------------------------------------------------------

_VAR = re.compile(
    r"\$(?:\{(?P<braced>[A-Za-z_]\w*)(?:(?P<op>:?[-+])(?P<word>[^}]*))?\}|(?P<plain>[A-Za-z_]\w*))"
)


def expand(word: str, env: dict[str, str]) -> str:
    """``word`` with its quotes removed and its variables substituted from ``env``."""
    out: list[str] = []
    quote: str | None = None
    i = 0
    while i < len(word):
        c = word[i]
        if quote == "'":
            if c == "'":
                quote = None
            else:
                out.append(c)
            i += 1
        elif c == "\\" and i + 1 < len(word):
            if quote == '"' and word[i + 1] not in '$"\\`':
                out.append(c)
                i += 1
            else:
                out.append(word[i + 1])
                i += 2
        elif c in "'\"" and quote is None:
            quote = c
            i += 1
        elif c == '"' and quote == '"':
            quote = None
            i += 1
        elif c == "$" and (m := _VAR.match(word, i)):
            name = m.group("braced") or m.group("plain")
            value, op = env.get(name, ""), m.group("op")
            if op:
                alt = expand(m.group("word"), env)
                value = {
                    ":-": value or alt,
                    "-": value if name in env else alt,
                    ":+": alt if value else "",
                    "+": alt if name in env else "",
                }[op]
            out.append(value)
            i = m.end()
        else:
            out.append(c)
            i += 1
    if quote:
        raise ReplayError(f"unterminated quote in {word!r}")
    return "".join(out)


def env_pairs(cmd: dockerfile.Command, env: dict[str, str]) -> list[tuple[str, str]]:
    """The ``(name, value)`` pairs of an ENV or ARG instruction, values expanded in ``env`` as it was
    before the instruction (Docker substitutes the same value throughout one instruction)."""
    values = cmd.value
    if cmd.cmd == "ARG":
        pairs = [tuple(v.split("=", 1)) if "=" in v else (v, None) for v in values]
        return [(k, expand(v, env)) for k, v in pairs if v is not None]
    if len(values) % 2:
        raise ReplayError(f"line {cmd.start_line}: cannot read {cmd.original!r}")
    return [(values[i], expand(values[i + 1], env)) for i in range(0, len(values), 2)]


def flags(cmd: dockerfile.Command) -> dict[str, str]:
    out = {}
    for f in cmd.flags:
        name, _, value = f.removeprefix("--").partition("=")
        out[name] = value
    return out


def seconds(duration: str) -> float:
    """A Docker duration (``30s``, ``1m30s``, ``500ms``) in seconds."""
    units = {"h": 3600.0, "m": 60.0, "s": 1.0, "ms": 1e-3, "us": 1e-6}
    parts = re.findall(r"(\d+(?:\.\d+)?)(ms|us|h|m|s)", duration)
    if not parts or "".join(n + u for n, u in parts) != duration:
        raise ReplayError(f"cannot read the duration {duration!r}")
    return sum(float(n) * units[u] for n, u in parts)


def argv_of(cmd: dockerfile.Command, values: tuple[str, ...], shell: list[str]) -> list[str]:
    """Exec form as is; shell form run by ``shell``."""
    if cmd.json:
        return list(values)
    return [*shell, " ".join(values)]


# --------------------------------------------------------------------------------------------------
# Stages
# --------------------------------------------------------------------------------------------------


@dataclass
class Stage:
    image: str
    name: str | None
    commands: list[dockerfile.Command] = field(default_factory=list)


def stages(path: Path) -> tuple[list[Stage], dict[str, str]]:
    """The stages of the Dockerfile and the global ARGs (before the first FROM)."""
    out: list[Stage] = []
    global_args: dict[str, str] = {}
    for cmd in dockerfile.parse_file(str(path)):
        if cmd.heredocs:
            raise ReplayError(f"line {cmd.start_line}: heredocs are not replayed")
        if cmd.cmd == "FROM":
            words = cmd.value
            name = words[2] if len(words) == 3 and words[1].upper() == "AS" else None
            out.append(Stage(expand(words[0], global_args), name))
        elif not out:
            if cmd.cmd != "ARG":
                raise ReplayError(f"line {cmd.start_line}: {cmd.cmd} before FROM")
            global_args.update(env_pairs(cmd, global_args))
        else:
            out[-1].commands.append(cmd)
    if not out:
        raise ReplayError("no FROM in the Dockerfile")
    return out, global_args


def build_environment() -> dict[str, str]:
    """What a build stage starts from: this machine's environment (its pip and network settings stand
    for the build host's), less what would point into another Python."""
    drop = {"VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTHONUSERBASE"}
    return {k: v for k, v in os.environ.items() if k not in drop}


def run_environment(home: Path) -> dict[str, str]:
    """What the final stage starts from, as in a python image: PATH (this machine's stands for the
    image's), LANG, HOME; nothing else from here but the pass-through variables."""
    env = {"PATH": os.environ["PATH"], "LANG": "C.UTF-8", "HOME": str(home)}
    env.update({k: os.environ[k] for k in PASS_THROUGH if k in os.environ})
    return env


@dataclass
class Replay:
    context: Path
    scratch: Path
    venv_var: str = "VIRTUAL_ENV"
    #: the image path of the virtual environment → where it is here
    venv_image_path: str | None = None

    @property
    def venv(self) -> Path:
        return self.scratch / "venv"

    def set_env(self, env: dict[str, str], cmd: dockerfile.Command) -> None:
        for name, value in env_pairs(cmd, env):
            if name == self.venv_var:
                if self.venv_image_path not in (None, value):
                    where = f"line {cmd.start_line}: ${name}"
                    raise ReplayError(f"{where} is {value}, elsewhere {self.venv_image_path}")
                self.venv_image_path = value
                value = str(self.venv)
            env[name] = value

    def context_files(self) -> set[str]:
        """Files and folders of the build context that ``docker build`` would send (``.dockerignore``)."""
        ignore = self.context / ".dockerignore"
        patterns = []
        if ignore.exists():
            lines = (line.strip() for line in ignore.read_text().splitlines())
            patterns = [line for line in lines if line and not line.startswith("#")]
        return {p.replace(os.sep, "/") for p in exclude_paths(str(self.context), patterns)}

    def copy(
        self, cmd: dockerfile.Command, env: dict[str, str], root: Path, workdir: Path, sent: set[str]
    ) -> None:
        """COPY from the build context as Docker does: a directory's contents, not the directory."""
        *sources, dest = [expand(w, env) for w in cmd.value]
        target = root / dest.lstrip("/") if dest.startswith("/") else workdir / dest
        into_dir = dest.endswith("/") or len(sources) > 1 or target.is_dir()
        for src in sources:
            rel = os.path.normpath(src).replace(os.sep, "/")
            if rel.startswith("../") or rel.startswith("/"):
                raise ReplayError(f"line {cmd.start_line}: {src} is outside the build context")
            origin = self.context / rel
            if rel != "." and rel not in sent:
                raise ReplayError(f"line {cmd.start_line}: {src} is not in the build context (.dockerignore)")
            if rel == "." or origin.is_dir():
                prefix = "" if rel == "." else rel + "/"
                for item in sorted(p for p in sent if p.startswith(prefix)):
                    out = target / item[len(prefix) :]
                    if (self.context / item).is_dir():
                        out.mkdir(parents=True, exist_ok=True)
                    else:
                        out.parent.mkdir(parents=True, exist_ok=True)
                        shutil.copy2(self.context / item, out)
            else:
                out = target / origin.name if into_dir else target
                out.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(origin, out)

    def build(self, stage: Stage, global_args: dict[str, str]) -> None:
        """Run the build stage's steps here."""
        env = build_environment()
        sub = {**global_args, **env}
        shell = list(DEFAULT_SHELL)
        root = self.scratch / "build"
        workdir = root
        workdir.mkdir(parents=True)
        sent = self.context_files()
        stage_args: dict[str, str] = {}
        for cmd in stage.commands:
            t0 = time.perf_counter()
            if cmd.cmd == "ENV":
                self.set_env(env, cmd)
                sub.update(env)
            elif cmd.cmd == "ARG":  # build arguments: seen by the later steps, as variables by RUN
                stage_args.update(env_pairs(cmd, sub))
                sub.update(stage_args)
            elif cmd.cmd == "WORKDIR":
                path = expand(cmd.value[0], sub)
                workdir = root / path.lstrip("/") if path.startswith("/") else workdir / path
                workdir.mkdir(parents=True, exist_ok=True)
            elif cmd.cmd == "COPY":
                if "from" in flags(cmd):
                    raise ReplayError(f"line {cmd.start_line}: COPY --from in a build stage is not replayed")
                self.copy(cmd, sub, root, workdir, sent)
            elif cmd.cmd == "RUN":
                argv = argv_of(cmd, cmd.value, shell)
                say(f"-- line {cmd.start_line}: {cmd.original}")
                done = subprocess.run(
                    argv,
                    cwd=workdir,
                    env={**stage_args, **env},
                    stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT,
                    check=False,
                )
                output = done.stdout.decode(errors="replace").splitlines()
                shown = output[-60:] if done.returncode else output[-2:]
                if shown:
                    say("\n".join(f"   | {line}" for line in shown))
                if done.returncode:
                    raise ReplayError(f"line {cmd.start_line}: RUN exited {done.returncode}")
                say(f"   ({time.perf_counter() - t0:.1f} s)")
            elif cmd.cmd == "SHELL":
                shell = list(cmd.value)
            elif cmd.cmd in ("LABEL",):
                pass
            else:
                raise ReplayError(f"line {cmd.start_line}: {cmd.cmd} in the build stage is not replayed")


@dataclass
class Runtime:
    env: dict[str, str]
    workdir: Path
    argv: list[str]
    healthcheck: list[str]
    health_flags: dict[str, str]
    exposed: list[str]
    user: str | None


def final_stage(stage: Stage, builder: Stage, replay: Replay, global_args: dict[str, str]) -> Runtime:
    """Read the final stage: its environment and command, as they would be in the container."""
    env = run_environment(replay.scratch / "home")
    sub = {**global_args, **env}
    shell = list(DEFAULT_SHELL)
    workdir = replay.scratch / "run"
    workdir.mkdir(parents=True)
    cmd_argv: list[str] | None = None
    entry: list[str] = []
    health: list[str] | None = None
    health_flags: dict[str, str] = {}
    exposed: list[str] = []
    user: str | None = None
    for cmd in stage.commands:
        if cmd.cmd == "ENV":
            replay.set_env(env, cmd)
            sub.update(env)
        elif cmd.cmd == "ARG":
            sub.update(env_pairs(cmd, sub))
        elif cmd.cmd == "COPY":
            src_from = flags(cmd).get("from")
            words = [expand(w, sub) for w in cmd.value]
            if src_from != builder.name or len(words) != 2 or {*words} != {str(replay.venv)}:
                raise ReplayError(
                    f"line {cmd.start_line}: only `COPY --from={builder.name} ${replay.venv_var} "
                    f"${replay.venv_var}` is replayed (the virtual environment, used in place)"
                )
        elif cmd.cmd == "RUN":
            say(f"-- not replayed (line {cmd.start_line}): {cmd.original[:100]}")
        elif cmd.cmd == "WORKDIR":
            path = expand(cmd.value[0], sub)
            workdir = replay.scratch / "run" / path.lstrip("/")
            workdir.mkdir(parents=True, exist_ok=True)
        elif cmd.cmd == "USER":
            user = expand(cmd.value[0], sub)
        elif cmd.cmd == "EXPOSE":
            exposed += [expand(v, sub).split("/")[0] for v in cmd.value]
        elif cmd.cmd == "HEALTHCHECK":
            if cmd.value[0].upper() != "CMD":
                raise ReplayError(f"line {cmd.start_line}: HEALTHCHECK {cmd.value[0]}")
            health = argv_of(cmd, cmd.value[1:], shell)
            health_flags = flags(cmd)
        elif cmd.cmd == "CMD":
            cmd_argv = argv_of(cmd, cmd.value, shell)
        elif cmd.cmd == "ENTRYPOINT":
            entry = argv_of(cmd, cmd.value, shell)
            if not cmd.json:
                cmd_argv = []  # a shell-form ENTRYPOINT ignores CMD
        elif cmd.cmd == "SHELL":
            shell = list(cmd.value)
        elif cmd.cmd in ("LABEL", "STOPSIGNAL"):
            pass
        else:
            raise ReplayError(f"line {cmd.start_line}: {cmd.cmd} in the final stage is not replayed")
    argv = entry + (cmd_argv or [])
    if not argv:
        raise ReplayError("the final stage has no CMD or ENTRYPOINT")
    if health is None:
        raise ReplayError("the final stage has no HEALTHCHECK")
    return Runtime(env, workdir, argv, health, health_flags, exposed, user)


# --------------------------------------------------------------------------------------------------
# Running it
# --------------------------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def http(url: str, body: bytes | None = None, timeout: float = 60.0) -> tuple[int, bytes]:
    request = urllib.request.Request(url, data=body, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def plan_demo(url: str) -> None:
    """GET the demo from the server at ``url`` and POST it to /v1/plan: both must answer 200, the plan
    with status ok."""
    status, demo = http(f"{url}/v1/demo")
    if status != 200:
        raise ReplayError(f"GET /v1/demo answered {status}: {demo[:300]!r}")
    status, answer = http(f"{url}/v1/plan", demo)
    if status != 200 or b'"status":"ok"' not in answer.replace(b" ", b""):
        raise ReplayError(f"POST /v1/plan of the demo answered {status}: {answer[:300]!r}")


def wait_healthy(rt: Runtime, server: subprocess.Popen[bytes]) -> float:
    """Run the HEALTHCHECK until it passes; the time it took [s]."""
    interval = min(seconds(rt.health_flags.get("interval", "30s")), 1.0)  # poll faster than Docker
    timeout = seconds(rt.health_flags.get("timeout", "30s"))
    deadline_s = seconds(rt.health_flags.get("start-period", "0s")) + 30.0
    t0 = time.perf_counter()
    last = ""
    while time.perf_counter() - t0 < deadline_s:
        if server.poll() is not None:
            raise ReplayError(f"the server exited with {server.returncode} before it was healthy")
        try:
            probe = subprocess.run(
                rt.healthcheck, cwd=rt.workdir, env=rt.env, capture_output=True, timeout=timeout, check=False
            )
        except subprocess.TimeoutExpired:
            last = f"timed out after {timeout} s"
        else:
            if probe.returncode == 0:
                return time.perf_counter() - t0
            last = " ".join((probe.stderr or probe.stdout).decode(errors="replace").strip().splitlines()[-1:])
        time.sleep(interval)
    raise ReplayError(f"the HEALTHCHECK did not pass within {deadline_s:.0f} s; last: {last}")


def stop(server: subprocess.Popen[bytes]) -> int:
    """SIGTERM (what `docker stop` sends) and wait; SIGKILL the process group started if it hangs."""
    if server.poll() is None:
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
            raise ReplayError("the server did not stop within 20 s of SIGTERM") from None
    return int(server.returncode)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dockerfile", type=Path, default=Path("Dockerfile"))
    parser.add_argument("--context", type=Path, default=Path("."))
    parser.add_argument("--port-env", required=True, help="the variable the command reads its port from")
    parser.add_argument("--host-env", required=True, help="the variable the command reads its host from")
    parser.add_argument("--keep", action="store_true", help="keep the scratch directory")
    parser.add_argument("test", nargs=argparse.REMAINDER, help="-- command to run against {url}")
    args = parser.parse_args(argv)
    test = args.test[1:] if args.test[:1] == ["--"] else args.test

    scratch = Path(tempfile.mkdtemp(prefix="dockerfile-replay-"))
    replay = Replay(context=args.context.resolve(), scratch=scratch)
    server: subprocess.Popen[bytes] | None = None
    log_path = scratch / "server.log"
    t_start = time.perf_counter()
    try:
        all_stages, global_args = stages(args.dockerfile)
        final = all_stages[-1]
        sources = {flags(c)["from"] for c in final.commands if c.cmd == "COPY" and "from" in flags(c)}
        builders = [s for s in all_stages[:-1] if s.name in sources]
        if len(builders) != 1:
            raise ReplayError(f"the final stage must copy from one build stage, not {sorted(sources)}")
        builder = builders[0]
        if builder.image != final.image:
            raise ReplayError(f"build stage on {builder.image} but final stage on {final.image}")
        tag = re.match(r"python:(\d+\.\d+)", final.image)
        here = f"{sys.version_info.major}.{sys.version_info.minor}"
        if not tag or tag.group(1) != here:
            say(f"!! the image is {final.image}; this replay runs Python {here}")

        say(f"== build stage `{builder.name}` on {builder.image}: replayed in {scratch}")
        t0 = time.perf_counter()
        replay.build(builder, global_args)
        say(f"== build replayed in {time.perf_counter() - t0:.0f} s")

        rt = final_stage(final, builder, replay, global_args)
        if rt.user in (None, "", "root", "0") or (rt.user or "").split(":")[0] in ("root", "0"):
            raise ReplayError(f"the final stage runs as {rt.user or 'root (no USER)'}")
        default_port = rt.env.get(args.port_env)
        if default_port not in rt.exposed:
            raise ReplayError(f"EXPOSE {rt.exposed} does not include {args.port_env}={default_port}")
        port = free_port()
        rt.env[args.port_env], rt.env[args.host_env] = str(port), "127.0.0.1"
        exe = shutil.which(rt.argv[0], path=rt.env["PATH"])
        if rt.env["PATH"].split(os.pathsep)[0] != str(replay.venv / "bin"):
            raise ReplayError(f"PATH does not start with ${replay.venv_var}/bin: {rt.env['PATH']}")
        say(f"== USER {rt.user}, EXPOSE {' '.join(rt.exposed)}")
        say(f"== overridden: {args.port_env}={port} (a free port), {args.host_env}=127.0.0.1")
        shown = {k: v for k, v in rt.env.items() if k not in ("PATH", "HOME", *PASS_THROUGH)}
        say(f"== environment: {' '.join(f'{k}={v}' for k, v in sorted(shown.items()))}")
        say(f"== command ({exe}): {rt.argv}")
        with log_path.open("wb") as log:
            server = subprocess.Popen(
                rt.argv,
                cwd=rt.workdir,
                env=rt.env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        took = wait_healthy(rt, server)
        say(f"== HEALTHCHECK passed after {took:.1f} s: {rt.healthcheck}")

        url = f"http://127.0.0.1:{port}"
        plan_demo(url)
        say("== GET /v1/demo → 200; POST /v1/plan (the demo) → 200, status ok")
        # the viewer's files are package data: the non-editable install must hold them
        for path in ("/viewer", "/viewer/viewer.js", "/viewer/run.schema.json"):
            status, _ = http(f"{url}{path}")
            if status != 200:
                raise ReplayError(f"GET {path} answered {status}: the viewer's files are not installed")
        say("== GET /viewer and its files → 200")

        if test:
            command = [part.replace("{url}", url) for part in test]
            say(f"== {' '.join(command)}")
            done = subprocess.run(command, cwd=replay.context, check=False)
            if done.returncode:
                raise ReplayError(f"the test command exited {done.returncode}")

        code = stop(server)
        # a server may re-raise the signal once it has shut down, so a clean stop may end by SIGTERM
        if code not in (0, -signal.SIGTERM):
            raise ReplayError(f"the server exited {code} on SIGTERM")
        log_text = log_path.read_text(errors="replace")
        if "Traceback" in log_text:
            raise ReplayError("the server logged a traceback")
        how = "exit 0" if code == 0 else "ended by the re-raised signal"
        say(f"== server stopped on SIGTERM within 20 s ({how})")
        say(f"== all passed in {time.perf_counter() - t_start:.0f} s")
        return 0
    except ReplayError as exc:
        say(f"!! {exc}")
        if server is not None:
            try:
                stop(server)
            except ReplayError as again:
                say(f"!! {again}")
        if log_path.exists():
            say("-- server log (last 60 lines):")
            say("\n".join(log_path.read_text(errors="replace").splitlines()[-60:]))
        return 1
    finally:
        if server is not None and server.poll() is None:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
        if args.keep:
            say(f"-- kept {scratch}")
        else:
            shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
