#!/usr/bin/env bash
# Clients generated from the committed openapi/openapi.json, exercised against a live server:
#   python:     openapi-python-client (pinned in the dev extras) generates kappa-planner-client into
#               a scratch directory; it is pip-installed into a venv of its own (its declared
#               dependencies must suffice) and openapi/clients/python/plan_demo.py plans the demo;
#   typescript: openapi-typescript types (versions pinned in openapi/clients/typescript/package-lock.json),
#               a strict `tsc --noEmit`, then openapi/clients/typescript/src/plan-demo.ts compiled and
#               run with node plans the demo through openapi-fetch.
# Any warning of the Python generator, type error or failed check fails the run.
#
# Assumes the CI venv is active (python with the dev extras) and node ≥ 20 + npm on PATH.
set -euo pipefail
cd "$(dirname "$0")/.."
. .ci/live_server.sh

work=$(mktemp -d)
trap 'stop_server; rm -rf "$work"' EXIT
ts=openapi/clients/typescript

echo "== python client: generate ($(openapi-python-client --version))"
openapi-python-client generate --path openapi/openapi.json \
    --config openapi/clients/python/config.yaml --meta setup \
    --output-path "$work/kappa-planner-client" --fail-on-warning
# openapi-python-client ≤ 0.29.1 breaks from_dict of models with a property `d` (see the script)
python openapi/clients/python/fix_generated.py "$work/kappa-planner-client"
python -m venv "$work/client-venv"
"$work/client-venv/bin/python" -m pip install --quiet --disable-pip-version-check "$work/kappa-planner-client"

echo "== typescript: npm ci, generate, type-check, build (node $(node --version))"
(
    cd "$ts"
    npm ci --no-audit --no-fund --loglevel=error
    npm run --silent generate
    npm run --silent typecheck
    npm run --silent build
)

start_server "$work/server.log"
status=0
echo "== python client: plan the demo"
"$work/client-venv/bin/python" openapi/clients/python/plan_demo.py "$BASE_URL" || status=1
echo "== typescript client: plan the demo"
node "$ts/build/plan-demo.js" "$BASE_URL" || status=1

if [[ $status -ne 0 ]]; then
    echo "== server log" >&2
    tail -n 100 "$work/server.log" >&2
fi
exit "$status"
