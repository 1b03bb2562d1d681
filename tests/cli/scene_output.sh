#!/usr/bin/env bash
# The image a scene asks for: a pbrt Film's "filename" is the output when -o gives none (as an
# EXR, its PNG preview beside it, in the working folder as pbrt writes it), in every mode (one
# shot, --watch, --frames); -o wins over it.
#   scene_output.sh SPANGLE TESTS_DIR
set -u
S=$1 TESTS=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
mkdir -p "$T/scene" "$T/work"
cp "$TESTS/scenes/pbrt/twin_box.ply" "$T/scene/"
sed 's/"string filename" "twin_v3.exr"/"string filename" "asked_for.png"/' \
    "$TESTS/scenes/pbrt/twin_v3.pbrt" > "$T/scene/twin.pbrt"
scene="$T/scene/twin.pbrt"
cd "$T/work" || fail "no temp folder"
"$S" render "$scene" --size 24x18 --spp 1 > out.txt 2>&1 || fail "render failed: $(cat out.txt)"
[ -f asked_for.exr ] || fail "no asked_for.exr (the Film's filename as an EXR): $(ls)"
[ -f asked_for.png ] || fail "no asked_for.png preview beside it"
grep -q "asks for 'asked_for.png'" out.txt || fail "no line saying where the image went"
"$S" render "$scene" --size 24x18 --spp 1 -q -o given.exr || fail "render -o failed"
[ -f given.exr ] || fail "-o did not win over the Film's filename"
# The same scene converted to TOML keeps the name ([render] output), and renders to it.
rm -f asked_for.exr asked_for.png
"$S" convert "$scene" -o "$T/scene/twin.toml" -q > conv.txt 2>&1 || fail "convert failed: $(cat conv.txt)"
grep -q '^output = "asked_for.png"' "$T/scene/twin.toml" || fail "convert dropped the Film's filename"
"$S" render "$T/scene/twin.toml" --size 24x18 --spp 1 > out2.txt 2>&1 || fail "TOML render failed: $(cat out2.txt)"
[ -f asked_for.exr ] || fail "the TOML scene's output was not written: $(ls)"
# --watch writes it too, and says so (it wrote <scene name>.exr and said nothing); -o wins over
# it; without either the image is <scene name>.exr.
watch() {  # watch SCENE LOG ARGS...: --watch until its first render is done, then SIGINT
    local scene=$1 log=$2
    shift 2
    "$S" render "$scene" --size 24x18 --spp 1 --watch --no-preview "$@" > "$log" 2>&1 &
    local pid=$!
    for _ in $(seq 1 300); do
        grep -q "watching for changes" "$log" && break
        sleep 0.1
    done
    kill -INT $pid
    wait $pid
    grep -q "watching for changes" "$log" || fail "--watch did not finish its first render: $(cat "$log")"
}
rm -f asked_for.exr
watch "$T/scene/twin.toml" watch1.txt
[ -f asked_for.exr ] || fail "--watch did not write the scene's output: $(ls)"
[ -e twin.exr ] && fail "--watch wrote <scene name>.exr instead of the scene's output"
grep -q "asks for 'asked_for.png'" watch1.txt || fail "--watch said no line saying where the image went"
grep -q "asked_for.exr holds" watch1.txt || fail "the --watch stop line names another file: $(cat watch1.txt)"
rm -f asked_for.exr
watch "$T/scene/twin.toml" watch2.txt -o watched.exr
[ -f watched.exr ] || fail "-o was not written with --watch"
[ -e asked_for.exr ] && fail "--watch wrote the scene's output although -o was given"
sed '/^output = /d' "$T/scene/twin.toml" > "$T/scene/plain.toml"
watch "$T/scene/plain.toml" watch3.txt
[ -f plain.exr ] || fail "--watch without -o or a scene output did not write <scene name>.exr: $(ls)"
# A sequence writes the images the scene asks for too, numbered (.#### before the extension).
"$S" render "$T/scene/twin.toml" --size 24x18 --spp 1 --frames 1..2 > out3.txt 2>&1 || fail "--frames render failed: $(cat out3.txt)"
[ -f asked_for.0001.exr ] && [ -f asked_for.0002.exr ] || fail "--frames did not write the scene's output, numbered: $(ls)"
grep -q "asks for 'asked_for.png'" out3.txt || fail "no line saying where the frames went"
sed 's/^output = "asked_for.png"/output = "seq_##.exr"/' "$T/scene/twin.toml" > "$T/scene/hashes.toml"
"$S" render "$T/scene/hashes.toml" --size 24x18 --spp 1 --frames 3..4 -q > out4.txt 2>&1 || fail "--frames with # failed: $(cat out4.txt)"
[ -f seq_03.exr ] && [ -f seq_04.exr ] || fail "the # run of [render] output was not the frame number: $(ls)"
"$S" render "$T/scene/hashes.toml" --size 24x18 --spp 1 --frames 3..3 -q -o given_#.exr || fail "--frames -o failed"
[ -f given_3.exr ] || fail "-o did not win over [render] output with --frames: $(ls)"
# A still render of a scene whose output holds a frame number: an error at that line (it was a
# usage error, exit 2, without the scene's line).
"$S" render "$T/scene/hashes.toml" --size 24x18 --spp 1 > out5.txt 2>&1
status=$?
[ "$status" = 1 ] || fail "a still render of a '#' output exited $status: $(cat out5.txt)"
grep -q "hashes.toml:[0-9]*:[0-9]*: error: the scene asks for 'seq_##.exr'" out5.txt || fail "no file:line for a '#' output in a still render: $(cat out5.txt)"
# A folder the scene's output names that does not exist: at the scene's line, the folder said
# where it is (the working folder's, as pbrt's).
sed 's/^output = "asked_for.png"/output = "nofolder\/x.exr"/' "$T/scene/twin.toml" > "$T/scene/nofolder.toml"
"$S" render "$T/scene/nofolder.toml" --size 24x18 --spp 1 > out6.txt 2>&1 && fail "a missing output folder was accepted"
grep -q "nofolder.toml:[0-9]*:[0-9]*: error: the scene asks for 'nofolder/x.exr'" out6.txt || fail "no file:line for a missing output folder: $(cat out6.txt)"
grep -q "('nofolder' in the working folder) does not exist" out6.txt || fail "the missing folder is not said as the working folder's: $(cat out6.txt)"
# An empty name is refused at its line.
printf '[render]\noutput = ""\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n' > bad.toml
"$S" render bad.toml --spp 1 > bad.txt 2>&1 && fail "an empty output was accepted"
grep -q "bad.toml:2" bad.txt || fail "no file:line for an empty output: $(cat bad.txt)"
echo "ok"
