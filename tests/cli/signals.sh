#!/usr/bin/env bash
# SIGINT, SIGTERM and SIGHUP (the terminal closed: it killed the render, its temporary file and
# lock left behind; ignored under nohup, it is not caught) in the middle of a render: the passes completed so far are written, the EXR
# header says partial and how many samples per pixel, the exit status is 130 (SIGINT; it was 0,
# and a farm took the partial image for a finished one) or 143 (SIGTERM) or 129 (SIGHUP), and no temporary file
# is left; a render stopped before its first pass writes nothing and exits 130 (it exited 0,
# leaving an older image at the output path to be taken for this one); a sequence stopped before its last frame exits 130;
# a stopped --spp-range part holds the samples it completed, as a part of that range.
#   signals.sh SPANGLE PLUGIN_DIR SCENE_DIR
set -u
S=$1 PLUGINS=$2 SCENES=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
cp "$SCENES/flake_uvless.toml" "$SCENES/uvless_ball.obj" "$T/"
cd "$T"
fail() { echo "FAIL: $*"; exit 1; }
for sig in INT TERM HUP; do
    "$S" render flake_uvless.toml -o $sig.exr --spp 100000 --threads 2 -q --pass-output \
        --plugin-path "$PLUGINS" 2> err.txt &
    PID=$!
    # Wait for the first pass output, then a little more, then signal.
    for _ in $(seq 1 200); do [ -f $sig.exr ] && break; sleep 0.05; done
    [ -f $sig.exr ] || fail "no pass output before SIG$sig"
    sleep 0.5
    kill -$sig $PID
    wait $PID
    RC=$?
    want=130; [ $sig = TERM ] && want=143; [ $sig = HUP ] && want=129
    [ $RC -eq $want ] || fail "SIG$sig: exit status $RC, expected $want"
    oiiotool --info -v $sig.exr > info.txt || fail "SIG$sig: unreadable output"
    grep -q 'spangle:partial: "1"' info.txt || fail "SIG$sig: not marked partial"
    spp=$(sed -n 's/.*spangle:spp: "\([0-9]*\)".*/\1/p' info.txt)
    [ -n "$spp" ] && [ "$spp" -ge 1 ] && [ "$spp" -lt 100000 ] || fail "SIG$sig: spp '$spp'"
    grep -q "stopped by a signal" err.txt || fail "SIG$sig: no message"
    ls -a | grep -q '\.tmp' && fail "SIG$sig: temporary file left behind"
done
# A second SIGINT while the EXR is written, once the preview's temporary file exists: neither
# temporary file is left (the preview's was, 2.4 MB at 1600x900).
"$S" render flake_uvless.toml -o pair.exr --spp 1 --size 1600x900 --layers --float --threads 2 -q \
    --plugin-path "$PLUGINS" 2> err.txt &
PID=$!
seen=0
for _ in $(seq 1 2000); do ls -a | grep -q '^\.pair\.png\.tmp' && { seen=1; break; }; sleep 0.005; done
# (Timing: where the write ends before both signals land, only the last check applies.)
both=0
if [ $seen = 1 ] && kill -INT $PID 2> /dev/null; then
    sleep 0.02
    kill -INT $PID 2> /dev/null && both=1
fi
wait $PID
RC=$?
[ $both = 0 ] || [ $RC -eq 130 ] || fail "a second SIGINT while writing: exit status $RC, expected 130"
ls -a | grep -q '^\.pair\..*tmp' && fail "a second SIGINT while writing left a temporary file: $(ls -a)"
# The terminal closing (a pty whose other end goes away): SIGHUP, and every write to the
# terminal fails from then on; a progress line or the warning threw, and the render ended in
# std::terminate without its image. It writes what it has, with no temporary file left.
if command -v script > /dev/null; then
    # (The shell in the pty passes SIGHUP on to its job, as an interactive shell does, and lives
    # to write the render's status.)
    script -qfc "trap 'kill -HUP \$p' HUP; '$S' render flake_uvless.toml -o closed_tty.exr --spp 100000 --threads 2 --pass-output --plugin-path '$PLUGINS' & p=\$!; wait \$p; wait \$p; echo \$? > closed_tty.rc" /dev/null > /dev/null 2>&1 &
    SPID=$!
    for _ in $(seq 1 200); do [ -f closed_tty.exr ] && break; sleep 0.05; done
    [ -f closed_tty.exr ] || fail "no pass output under a pty"
    kill -9 $SPID
    for _ in $(seq 1 200); do pgrep -f "closed_tty.exr" > /dev/null || break; sleep 0.1; done
    pgrep -f "closed_tty.exr" > /dev/null && { pkill -9 -f "closed_tty.exr"; fail "the render went on after its terminal closed"; }
    for _ in $(seq 1 50); do [ -s closed_tty.rc ] && break; sleep 0.1; done
    [ "$(cat closed_tty.rc 2> /dev/null)" = 129 ] || fail "a closed terminal: exit status '$(cat closed_tty.rc 2> /dev/null)', expected 129"
    oiiotool --info -v closed_tty.exr | grep -q 'spangle:partial: "1"' || fail "a closed terminal: the image is not the partial one it had"
    ls -a | grep -q '^\.closed_tty\..*tmp' && fail "a closed terminal left a temporary file"
fi
# SIGHUP ignored (nohup: the terminal closing must not stop the render) stays ignored.
( trap '' HUP; exec "$S" render flake_uvless.toml -o nohup.exr --spp 3000 --size 32x24 --threads 2 -q \
    --plugin-path "$PLUGINS" ) 2> err.txt &
PID=$!
sleep 0.5
kill -HUP $PID 2> /dev/null || fail "the nohup render ended before its SIGHUP (make it longer)"
wait $PID
RC=$?
[ $RC -eq 0 ] || fail "an ignored SIGHUP stopped the render: exit status $RC"
oiiotool --info -v nohup.exr | grep -q 'spangle:partial: "1"' && fail "an ignored SIGHUP made a partial image"
# Stopped before the first pass: nothing written, the older image left alone, exit 130.
echo "older" > early.exr
"$S" render flake_uvless.toml -o early.exr --spp 100000 --size 3840x2160 --threads 2 -q \
    --plugin-path "$PLUGINS" 2> err.txt &
PID=$!
sleep 0.3
kill -INT $PID
wait $PID
RC=$?
[ $RC -eq 130 ] || fail "SIGINT before the first pass: exit status $RC, expected 130"
[ "$(cat early.exr)" = "older" ] || fail "SIGINT before the first pass: the older file changed"
grep -q "before the first pass ended: no image written" err.txt ||
    fail "SIGINT before the first pass: $(cat err.txt)"
# A second SIGINT exits at once, without leaving a temporary file or a lock, and says so (it
# exited without a word, and the older file at the path could be taken for this render's).
# Two SIGINTs sent together may reach the process as one (a pending signal is not counted
# twice), and a second sent late finds the render already gone: both end as one SIGINT does. The
# second-SIGINT path is taken once in a few tries.
second=0
for _ in 1 2 3 4 5 6; do
    rm -f twice.exr
    "$S" render flake_uvless.toml -o twice.exr --spp 100000 --threads 2 -q --plugin-path "$PLUGINS" \
        2> twice_err.txt &
    PID=$!
    sleep 1
    kill -INT $PID; sleep 0.01; kill -INT $PID 2> /dev/null
    wait $PID
    RC=$?
    [ $RC -eq 0 ] || [ $RC -eq 130 ] || fail "second SIGINT: exit status $RC"
    ls -a | grep -q '\.tmp' && fail "second SIGINT: temporary file left behind"
    ls -a | grep -q '\.lock' && fail "second SIGINT: lock file left behind"
    if grep -q "stopped at once by a second SIGINT" twice_err.txt; then
        [ $RC -eq 130 ] || fail "second SIGINT: exit status $RC, expected 130"
        second=1
        break
    fi
    # One SIGINT, as far as the process knew: the normal stop, said.
    grep -q "stopped by a signal (SIGINT)" twice_err.txt ||
        fail "SIGINT: neither stop was said: $(cat twice_err.txt)"
done
[ $second -eq 1 ] || fail "a second SIGINT was never seen in six tries: $(cat twice_err.txt)"
# A sequence stopped before its last frame is not done: exit status 130 (SIGINT), and the line
# names the frames left (it exited 0 with frames 3..8 never rendered).
"$S" render flake_uvless.toml -o seq.####.exr --spp 100000 --threads 2 -q --pass-output \
    --frames 1..8 --plugin-path "$PLUGINS" 2> err.txt &
PID=$!
for _ in $(seq 1 200); do [ -f seq.0001.exr ] && break; sleep 0.05; done
sleep 0.5
kill -INT $PID
wait $PID
RC=$?
[ $RC -eq 130 ] || fail "SIGINT in a sequence: exit status $RC, expected 130"
grep -q "stopped by a signal (SIGINT): wrote seq.0001.exr with .*; frames 2..8 not rendered" err.txt ||
    fail "SIGINT in a sequence: $(cat err.txt)"
# A --spp-range part stopped by SIGINT is the part of the samples its passes completed (it was a
# plain image, which merge called "not crops of one render"): merge names the samples missing.
"$S" render flake_uvless.toml -o range.exr --spp 100000 --spp-range 0..100000 --threads 2 -q \
    --pass-output --plugin-path "$PLUGINS" 2> err.txt &
PID=$!
for _ in $(seq 1 200); do [ -f range.exr ] && break; sleep 0.05; done
sleep 0.5
kill -INT $PID
wait $PID
oiiotool --info -v range.exr > info.txt || fail "stopped range: unreadable output"
spp=$(sed -n 's/.*spangle:spp: "\([0-9]*\)".*/\1/p' info.txt)
grep -q "spangle:spp_range: \"0..$spp\"" info.txt || fail "stopped range: $(grep spangle info.txt)"
"$S" merge range.exr -o merged.exr 2> err.txt && fail "a stopped range merged as the whole frame"
grep -q "samples $spp..100000 of the frame's 100000 are in no part" err.txt ||
    fail "stopped range: merge said $(cat err.txt)"
echo "signals: partial images, exit statuses and no temporary files as expected"
