# kappa-planner as a container image.
#
#   docker build -t kappa-planner . && docker run --rm -p 8000:8000 kappa-planner
#
# Two stages: `builder` installs the service's dependencies, exactly as `requirements.lock` pins them
# (every version and every file's hash; wheels only, nothing built from source), then the service
# (non-editable, built with the locked setuptools) into a virtual environment; the final image holds
# only that environment on a slim Python, run by a non-root user. The base image is pinned by digest.
# README "Container" says how to refresh the lock and the digest.
# CI has no Docker engine: .ci/container.sh replays the builder's RUN steps in a fresh virtual
# environment and runs this file's CMD with its ENV, then probes it with its HEALTHCHECK, so keep RUN
# steps to plain commands in $VIRTUAL_ENV and the working directory.

FROM python:3.11-slim-bookworm@sha256:2e32f7d302adc1c37428355c1e646897c0c53f4fd60b6a551245fb90ee129f91 AS builder

ENV PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_NO_CACHE_DIR=1 \
    PYTHONDONTWRITEBYTECODE=1 \
    VIRTUAL_ENV=/opt/venv
ENV PATH=$VIRTUAL_ENV/bin:$PATH

RUN python -m venv "$VIRTUAL_ENV"

WORKDIR /src

# Dependencies first, in their own layer: it is rebuilt only when the lock changes.
COPY requirements.lock ./
RUN python -m pip install --no-cache-dir --require-hashes --only-binary=:all: -r requirements.lock

# Then the service itself (app, planner, solvers; not planner_tools, the command line and its extras),
# not editable, without further dependencies and built with the locked setuptools (no build
# isolation: nothing fetched unpinned); `pip check` fails the build if pyproject.toml and the lock
# disagree, and the last command if the tooling or its extra `tools` got in. The `kappa-planner` console
# script is the tooling's (planner_tools.cli): removed, so the image has no command that cannot import.
COPY pyproject.toml README.md ./
COPY app ./app
COPY planner ./planner
COPY solvers ./solvers
RUN python -m pip install --no-cache-dir --no-deps --no-build-isolation . \
    && rm "$VIRTUAL_ENV/bin/kappa-planner" \
    && python -m pip check \
    && python -c "import importlib.util, sys; \
        found = [m for m in ('planner_tools', 'matplotlib', 'PIL', 'tqdm') if importlib.util.find_spec(m)]; \
        sys.exit(f'tooling in the service image: {found}' if found else 0)"


FROM python:3.11-slim-bookworm@sha256:2e32f7d302adc1c37428355c1e646897c0c53f4fd60b6a551245fb90ee129f91

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

# `python -m app` runs granian with host, port, workers, limits and log level from KAPPA_*, the
# service's JSON logs, and metrics summed over workers. Exec form: it is PID 1 and gets `docker stop`'s
# SIGTERM, and stops within KAPPA_SHUTDOWN_TIMEOUT (8 s, inside docker stop's 10 s).
CMD ["python", "-m", "app"]
