#!/usr/bin/env bash
# A render killed while writing (SIGKILL cannot be caught) leaves its temporary image
# ".NAME.tmpPID.N" beside the output; the next render to that folder removes it and says so.
# Left alone: the files of a process still running, of a file some process holds locked (a
# writer on another machine), and files that are not temporary images. Before: they stayed for
# ever.
#   stale_temporaries.sh SPANGLE SCENE
set -u
S=$1 SCENE=$2
T=$(mktemp -d)
LIVE= HOLDER=
trap '[ -n "$LIVE" ] && kill $LIVE 2>/dev/null; [ -n "$HOLDER" ] && kill $HOLDER 2>/dev/null; rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; ls -la "$T" "$T/png"; cat "$T/err.txt" 2>/dev/null; exit 1; }
cd "$T"
mkdir png
# A process that is gone: a PID that ran and was killed.
sleep 60 > /dev/null 2>&1 & DEAD=$!
kill -9 $DEAD; wait $DEAD 2>/dev/null
kill -0 $DEAD 2>/dev/null && fail "PID $DEAD still runs"
sleep 60 > /dev/null 2>&1 & LIVE=$!
for f in ".out.exr.tmp$DEAD.0" ".out.exr.tmp$DEAD.7" "png/.out.png.tmp$DEAD.1" \
         ".out.exr.tmp$LIVE.0" ".held.exr.tmp$DEAD.0" ".notes.txt.tmp$DEAD.0" "out.exr.tmp$DEAD.0" \
         ".other.exr.tmp$DEAD.x"; do
    echo "half an image" > "$f"
done
# flock holds the lock itself (-o: not its command), so killing it releases the lock.
flock -o ".held.exr.tmp$DEAD.0" sleep 30 > /dev/null 2>&1 & HOLDER=$!
for _ in $(seq 1 50); do flock -n ".held.exr.tmp$DEAD.0" true || break; sleep 0.1; done

"$S" render "$SCENE" -o out.exr --preview png/out.png --size 16x8 --spp 1 > out.txt 2> err.txt ||
    fail "the render failed"
for f in ".out.exr.tmp$DEAD.0" ".out.exr.tmp$DEAD.7" "png/.out.png.tmp$DEAD.1"; do
    [ -e "$f" ] && fail "$f of a killed render was not removed"
    grep -q "removed '.*$(basename "$f")', left by a render that was killed" err.txt ||
        fail "the removal of $f was not reported"
done
[ -e ".out.exr.tmp$LIVE.0" ] || fail "removed the temporary file of a running process"
[ -e ".held.exr.tmp$DEAD.0" ] || fail "removed a temporary file another process holds locked"
for f in ".notes.txt.tmp$DEAD.0" "out.exr.tmp$DEAD.0" ".other.exr.tmp$DEAD.x"; do
    [ -e "$f" ] || fail "removed $f, which is not a temporary image"
done
[ -s out.exr ] && [ -s png/out.png ] || fail "no output written"
# The render's own temporary files were renamed into place: none but the running process's left.
left=$( (ls -a; ls -a png) | grep '^\.out\.\(exr\|png\)\.tmp' | grep -v "tmp$LIVE\.")
[ -z "$left" ] || fail "temporary images left: $left"
echo "PASS: stale temporary images removed, the others kept"
