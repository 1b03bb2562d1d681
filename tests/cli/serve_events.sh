#!/usr/bin/env bash
# The live page's event stream across a restart on the same port: a browser's EventSource
# reconnects sending the id it last heard (Last-Event-ID). The new server does not know the old
# one's ids and replays every event it kept (a bare number from the old server was taken as a
# place among the new one's events: the page missed every pass and log line until the new count
# passed it); its own id resumes after that event.
#   serve_events.sh SPANGLE PLUGIN_DIR REPO_DIR
set -u
S=$1 PLUGINS=$2 REPO=$3
command -v curl > /dev/null || { echo "SKIP: curl missing"; exit 77; }
T=$(mktemp -d)
PID=
trap '[ -n "$PID" ] && kill -9 $PID 2>/dev/null; rm -rf "$T"' EXIT
cd "$T"
sed -e "s|\.\./\.\./assets/|$REPO/assets/|" "$REPO/tests/scenes/small_lit.toml" > scene.toml
fail() { echo "FAIL: $*"; echo "--- spangle"; cat log.txt; exit 1; }
wait_for() {  # wait_for CMD... : retries for up to 30 s
    for _ in $(seq 1 300); do "$@" > /dev/null 2>&1 && return 0; sleep 0.1; done
    return 1
}
serve() {  # serve PORT: a watch session with the live page on PORT (0: any), its log in log.txt;
    # fails (1) when it ends before showing its address (the port still held)
    # (The log emptied first: the session's own redirection empties it only once it runs, and
    # the last server's address line could be read meanwhile.)
    : > log.txt
    "$S" render scene.toml -o out.exr --watch --size 64x40 --spp 4 --serve "$1" \
        --plugin-path "$PLUGINS" > log.txt 2>&1 &
    PID=$!
    for _ in $(seq 1 300); do
        grep -q "^live preview at http" log.txt && break
        kill -0 "$PID" 2> /dev/null || { wait "$PID"; PID=; return 1; }
        sleep 0.1
    done
    grep -q "^live preview at http" log.txt || fail "no address printed"
    URL=$(grep -o "http://127.0.0.1:[0-9]*/" log.txt | head -1)
    wait_for grep -q "watching for changes" log.txt || fail "the render did not finish"
}
events() {  # events [LAST-EVENT-ID]: what /events sends in its first second
    curl -s -m 1 ${1:+-H "Last-Event-ID: $1"} "${URL}events" || true
}
serve 0 || fail "the first server did not start"
PORT=${URL##*:}
PORT=${PORT%/}
events > first.txt
grep -q "^event: pass" first.txt || fail "no pass event: $(cat first.txt)"
OLD=$(sed -n 's/^id: //p' first.txt | tail -1)
[ -n "$OLD" ] || fail "events without ids: $(cat first.txt)"
# Resuming after this server's own last event: nothing kept is sent again.
events "$OLD" > again.txt
grep -q "^event: pass" again.txt && fail "events before the client's last were sent again"
kill -INT $PID
wait $PID
PID=
# A new server on the same port, the old server's last id: every kept event.
for _ in $(seq 1 50); do serve "$PORT" && break; sleep 0.2; done
[ -n "$PID" ] || fail "no server could take port $PORT again"
events "$OLD" > restarted.txt
grep -q "^event: pass" restarted.txt || fail "a client of the old server missed the new passes: $(cat restarted.txt)"
grep -q "^event: log" restarted.txt || fail "a client of the old server missed the new log lines"
echo "serve_events: OK"
