# Sourced by .ci/clients.sh and .ci/fuzz.sh: run `python -m app` (the service as deployed: granian,
# plan processes) on a free loopback port.
#
#   start_server LOGFILE   start it, wait until GET /healthz answers, export BASE_URL
#   stop_server            stop it (also run by the EXIT trap the caller sets)
#
# Assumes the CI venv is active (`python` has the project installed) and the repo root is the cwd.

server_pid=""

_free_port() {
    python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# Wait up to 60 s for GET $1/healthz to answer 200 while process $2 lives; 0 when it does.
_wait_healthy() {
    python - "$1" "$2" <<'EOF'
import os, sys, time, urllib.request

url, pid = sys.argv[1] + "/healthz", int(sys.argv[2])
deadline = time.monotonic() + 60
while time.monotonic() < deadline:
    try:
        os.kill(pid, 0)
    except OSError:
        sys.exit(2)  # the server died (e.g. the port was taken meanwhile)
    try:
        with urllib.request.urlopen(url, timeout=2) as answer:
            if answer.status == 200:
                sys.exit(0)
    except OSError:
        pass
    time.sleep(0.2)
sys.exit(1)
EOF
}

start_server() {
    local log=$1 port attempt status
    for attempt in 1 2 3; do
        port=$(_free_port)
        KAPPA_HOST=127.0.0.1 KAPPA_PORT="$port" KAPPA_LOG_LEVEL=warning python -m app >"$log" 2>&1 &
        server_pid=$!
        status=0
        _wait_healthy "http://127.0.0.1:$port" "$server_pid" || status=$?
        if [[ $status -eq 0 ]]; then
            export BASE_URL="http://127.0.0.1:$port"
            echo "server up at $BASE_URL (pid $server_pid)"
            return 0
        fi
        stop_server
        echo "server did not come up on port $port (attempt $attempt):" >&2
        tail -n 20 "$log" >&2 || true
        [[ $status -eq 2 ]] || break  # a timeout is not a port race: do not retry
    done
    return 1
}

stop_server() {
    if [[ -n $server_pid ]]; then
        kill "$server_pid" 2>/dev/null || true
        wait "$server_pid" 2>/dev/null || true
        server_pid=""
    fi
}
