#!/usr/bin/env bash
# Fuzz the live API with schemathesis, every operation of the spec it serves:
#   1. positive: schema-valid requests (the spec's examples, boundary values, then random ones);
#   2. negative: requests that break the schema (hostile bodies): each must get a 4xx.
# Both fail on any 5xx and on any answer whose status, content type, headers or body the spec does
# not document (so every error is in the one error shape, ErrorResponse). Exit status non-zero on
# any failure; the server's log (tracebacks of 500s) is shown then.
#
#   FUZZ_MAX_EXAMPLES  test cases per operation and phase (default 120)
#   FUZZ_SEED          schemathesis/hypothesis seed (default fixed, so CI runs are reproducible)
#   FUZZ_WORKERS       concurrent schemathesis workers (default 2)
#
# Assumes the CI venv is active (schemathesis from the dev extras); run it from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."
. .ci/live_server.sh

examples=${FUZZ_MAX_EXAMPLES:-120}
seed=${FUZZ_SEED:-20250601}
workers=${FUZZ_WORKERS:-2}
work=$(mktemp -d)
trap 'stop_server; rm -rf "$work"' EXIT

start_server "$work/server.log"

# The spec the server serves (CI checks separately that openapi/openapi.json is the same).
# schemathesis ≤ 4.32 validates OpenAPI 3.1 *response* schemas after rewriting `prefixItems` to the
# Draft-4 `items: [...]`, which its Draft 2020-12 validator then rejects as an invalid schema
# (POST /v1/cartesian errors out; nested tuples go unchecked). Our tuples are pairs of one type
# ([x, y], [s, d]), so the fuzzer gets the equivalent `items` + minItems = maxItems = 2 form.
python - "$BASE_URL/openapi.json" "$work/openapi.json" <<'PY'
import json, sys, urllib.request

def untuple(node):
    if isinstance(node, dict):
        prefix = node.get("prefixItems")
        if (
            isinstance(prefix, list) and prefix and "items" not in node
            and all(item == prefix[0] for item in prefix)
            and node.get("minItems") == len(prefix) == node.get("maxItems")
        ):
            node = {k: v for k, v in node.items() if k != "prefixItems"} | {"items": prefix[0]}
        return {k: untuple(v) for k, v in node.items()}
    if isinstance(node, list):
        return [untuple(v) for v in node]
    return node

with urllib.request.urlopen(sys.argv[1], timeout=30) as answer:
    spec = untuple(json.load(answer))
assert "prefixItems" not in json.dumps(spec), "a tuple the rewrite does not cover"
with open(sys.argv[2], "w", encoding="utf-8") as f:
    json.dump(spec, f)
PY

conformance=status_code_conformance,content_type_conformance,response_headers_conformance,response_schema_conformance
common=(
    openapi.json --url "$BASE_URL"
    --phases examples,coverage,fuzzing
    --max-examples "$examples" --seed "$seed" --workers "$workers"
    --generation-database none --request-timeout 60 --no-color
)

# schemathesis keeps a crash cache in ./.schemathesis: run it in the scratch directory.
status=0
echo "== schemathesis: positive (valid requests), $examples examples per operation, seed $seed"
SECONDS=0
(cd "$work" && schemathesis run "${common[@]}" --mode positive --checks "not_a_server_error,$conformance") \
    || status=1
echo "positive run: ${SECONDS}s"

echo "== schemathesis: negative (invalid requests must get a 4xx), $examples examples per operation"
SECONDS=0
(cd "$work" && schemathesis run "${common[@]}" --mode negative \
    --checks "not_a_server_error,negative_data_rejection,$conformance") || status=1
echo "negative run: ${SECONDS}s"

if grep -q "Traceback" "$work/server.log"; then
    echo "the server logged errors" >&2
    status=1
fi
if [[ $status -ne 0 ]]; then
    echo "== server log (last 200 lines)" >&2
    tail -n 200 "$work/server.log" >&2
fi
exit "$status"
