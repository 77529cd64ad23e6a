#!/usr/bin/env bash
# The viewer (/viewer) in a real browser: headless Chromium driven by Playwright against a live
# server (.ci/live_server.sh), the tests of tests/browser (marker `browser`, which the plain
# `python -m pytest` deselects). Debian's chromium is installed here when missing (CI runs as root
# on a fresh Debian machine); Playwright comes from PyPI (extra `browser`) and drives that Chromium:
# no browser is downloaded. Screenshots: .ci/artifacts/viewer/ (git-ignored), kept after the run.
#
# Assumes the CI venv is active (the project installed with the dev extras); run it from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."
. .ci/live_server.sh

t0=$SECONDS
if ! command -v chromium >/dev/null 2>&1; then
    if [[ $(id -u) -ne 0 ]]; then
        echo "no chromium on PATH and not root: apt-get install chromium (Debian), then run this again" >&2
        exit 1
    fi
    echo "== apt-get install chromium"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends chromium fonts-dejavu-core >/dev/null
fi
echo "== $(chromium --version 2>/dev/null | head -n 1)"
python -m pip install --quiet -e '.[browser]'
echo "== playwright $(python -m playwright --version | head -n 1) (installed in $((SECONDS - t0)) s)"

work=$(mktemp -d)
trap 'stop_server; rm -rf "$work"' EXIT
start_server "$work/server.log"
export VIEWER_ARTIFACTS=${VIEWER_ARTIFACTS:-$PWD/.ci/artifacts/viewer}
rm -rf "$VIEWER_ARTIFACTS"
status=0
python -m pytest -m browser tests/browser --viewer-url "$BASE_URL" -p no:cacheprovider || status=$?
echo "== screenshots: $VIEWER_ARTIFACTS ($(find "$VIEWER_ARTIFACTS" -name '*.png' 2>/dev/null | wc -l) files)"
if [[ $status -ne 0 ]]; then
    echo "== server log" >&2
    tail -n 100 "$work/server.log" >&2
fi
exit "$status"
