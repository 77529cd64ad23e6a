# kappa-planner as a container image.
#
#   docker build -t kappa-planner . && docker run --rm -p 8000:8000 kappa-planner
#
# Two stages: `builder` installs the service's dependencies (`project.dependencies`, no extras) and
# then the service (non-editable) into a virtual environment; the final image holds only that
# environment on a slim Python, run by a non-root user.
# CI has no Docker engine: .ci/container.sh replays the builder's RUN steps in a fresh virtual
# environment and runs this file's CMD with its ENV, then probes it with its HEALTHCHECK, so keep RUN
# steps to plain commands in $VIRTUAL_ENV and the working directory.

FROM python:3.11-slim-bookworm AS builder

ENV PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_NO_CACHE_DIR=1 \
    PYTHONDONTWRITEBYTECODE=1 \
    VIRTUAL_ENV=/opt/venv
ENV PATH=$VIRTUAL_ENV/bin:$PATH

RUN python -m venv "$VIRTUAL_ENV"

WORKDIR /src

# Dependencies first, in their own layer: it is rebuilt only when pyproject.toml changes.
COPY pyproject.toml ./
RUN python -c "import tomllib; print(*tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies'], sep='\n')" > requirements.txt \
    && python -m pip install --no-cache-dir -r requirements.txt

# Then the service itself (app, planner, solvers; not planner_tools, the command line and its extras),
# not editable and without further dependencies; `pip check` fails the build if the two steps disagree,
# and the last command if the tooling or its extra `tools` got in.
COPY README.md ./
COPY app ./app
COPY planner ./planner
COPY solvers ./solvers
RUN python -m pip install --no-cache-dir --no-deps . \
    && python -m pip check \
    && python -c "import importlib.util, sys; \
        found = [m for m in ('planner_tools', 'matplotlib', 'PIL', 'tqdm') if importlib.util.find_spec(m)]; \
        sys.exit(f'tooling in the service image: {found}' if found else 0)"


FROM python:3.11-slim-bookworm

LABEL org.opencontainers.image.title="kappa-planner" \
      org.opencontainers.image.description="Trajectory-planning service robust on hairpins and U-turns (TransF-kappa)" \
      org.opencontainers.image.licenses="MIT"

RUN groupadd --system --gid 10001 kappa \
    && useradd --system --no-log-init --uid 10001 --gid kappa --home-dir /nonexistent --shell /usr/sbin/nologin kappa

ENV VIRTUAL_ENV=/opt/venv
COPY --from=builder $VIRTUAL_ENV $VIRTUAL_ENV

# KAPPA_* configure the service (app.settings, README "Configuration"); override with `docker run -e`.
ENV PATH=$VIRTUAL_ENV/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    KAPPA_HOST=0.0.0.0 \
    KAPPA_PORT=8000 \
    KAPPA_WORKERS=1 \
    KAPPA_LOG_LEVEL=info

# No sources here: the app is imported from the installed package.
WORKDIR /srv/kappa
USER 10001:10001

EXPOSE 8000

# slim has no curl: probe /healthz with the standard library (a non-2xx answer or no answer raises).
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import os, urllib.request; urllib.request.urlopen('http://127.0.0.1:%s/healthz' % os.environ['KAPPA_PORT'], timeout=4)"]

# `python -m app` runs uvicorn with host, port, workers and log level from KAPPA_*, the service's JSON
# logs, and metrics summed over workers. Exec form: it is PID 1 and gets `docker stop`'s SIGTERM.
CMD ["python", "-m", "app"]
