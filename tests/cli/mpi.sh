#!/usr/bin/env bash
# mpirun -np 2 spangle render: two ranks on this machine (loopback only) write the image one
# process writes, bit for bit, in every channel (glitter, textures, a normal map, the render
# layers), also for a crop window, narrow bands and a --frames sequence; a bad scene is reported
# once; a rank killed mid-render ends the job with a message naming it, writing nothing.
#   mpi.sh SPANGLE MPIEXEC REPO_DIR
set -u
S=$1 MPIEXEC=$2 REPO=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/err.txt" 2>/dev/null; exit 1; }
# Loopback only, two slots whatever the cores, and root allowed (CI runs as root). No
# single-copy mechanism: containers often forbid the cross-memory attach it needs.
MPI=("$MPIEXEC" -np 2 --oversubscribe --mca btl self,vader,tcp --mca btl_tcp_if_include lo
     --mca oob_tcp_if_include lo --mca btl_vader_single_copy_mechanism none)
[ "$(id -u)" = 0 ] && MPI+=(--allow-run-as-root)
SCENES="$REPO/tests/scenes"
same() {  # same A B WHAT: every channel equal
    oiiotool "$1" "$2" --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
        { cat "$T/diff.txt"; fail "$3: the MPI image differs from the one-process image"; }
}

ARGS=(--float --layers --no-preview -q)
"$S" render "$SCENES/textured.toml" -o "$T/one.exr" "${ARGS[@]}" 2> "$T/err.txt" || fail "one-process render"
"${MPI[@]}" "$S" render "$SCENES/textured.toml" -o "$T/two.exr" "${ARGS[@]}" 2> "$T/err.txt" || fail "mpirun -np 2"
channels() { oiiotool --info "$1" | sed -n 's/.*160 x   64, \([0-9]*\) channel.*/\1/p'; }
[ -n "$(channels "$T/two.exr")" ] && [ "$(channels "$T/two.exr")" = "$(channels "$T/one.exr")" ] &&
    oiiotool --info -v "$T/two.exr" | grep -q "CryptoObject00.R" ||
    fail "the MPI image lacks its layers: $(oiiotool --info "$T/two.exr")"
same "$T/one.exr" "$T/two.exr" "the whole image"

# Without -o, the image the scene asks for ([render] output), as one process writes it.
mkdir -p "$T/asked"
printf '[render]\noutput = "asked.exr"\n\n[[import]]\nfile = "%s"\n' "$SCENES/textured.toml" > "$T/imports.toml"
(cd "$T/asked" && "${MPI[@]}" "$S" render "$T/imports.toml" "${ARGS[@]}" > "$T/out.txt" 2> "$T/err.txt") ||
    fail "mpirun without -o: $(cat "$T/err.txt")"
[ -f "$T/asked/asked.exr" ] || fail "the MPI render did not write the scene's [render] output: $(ls "$T/asked")"
same "$T/one.exr" "$T/asked/asked.exr" "the scene's output"

# The progress line reports the bands each rank took and the balance.
"${MPI[@]}" "$S" render "$SCENES/textured.toml" -o "$T/bands.exr" --float --no-preview --band-rows 2 > "$T/out.txt" 2> "$T/err.txt" || fail "--band-rows 2"
grep -Eq "over 2 ranks \(2 bands of 2 tile rows; 0: [0-9]+ bands .*; 1: [0-9]+ bands .*balance \(busiest / mean\) [0-9.]+; wrote" "$T/out.txt" ||
    fail "no per-rank report: $(cat "$T/out.txt")"
# Without --layers the beauty keeps the environment seen directly: the layered image's
# premultiplied RGB plus its background (float rounding: the layer is a float mean).
oiiotool "$T/one.exr" --ch R,G,B "$T/one.exr" --ch background.R,background.G,background.B \
    --chnames R,G,B --add "$T/bands.exr" --diff --fail 1e-5 --warn 1e-5 > "$T/diff.txt" 2>&1 ||
    { cat "$T/diff.txt"; fail "--band-rows 2"; }

"$S" render "$SCENES/textured.toml" -o "$T/crop1.exr" --crop 7,5,151,43 "${ARGS[@]}" 2> "$T/err.txt" || fail "one-process crop"
"${MPI[@]}" "$S" render "$SCENES/textured.toml" -o "$T/crop2.exr" --crop 7,5,151,43 "${ARGS[@]}" 2> "$T/err.txt" || fail "MPI crop"
oiiotool --info -v "$T/crop2.exr" | grep -q "full/display size: 160 x 64" || fail "the MPI crop is not placed in the frame"
same "$T/crop1.exr" "$T/crop2.exr" "a crop window"

# The beetle (subdivided, instanced, glittering): one band where a one-pass render once differed
# from a progressive one in a pixel (Embree's coherent packets; traced ray by ray since).
BEETLE=(--size 640x360 --spp 16 --crop 160,144,224,160 --float --no-preview -q)
"$S" render "$REPO/assets/scenes/beetle.toml" -o "$T/beetle1.exr" "${BEETLE[@]}" 2> "$T/err.txt" || fail "one-process beetle"
"${MPI[@]}" "$S" render "$REPO/assets/scenes/beetle.toml" -o "$T/beetle2.exr" "${BEETLE[@]}" 2> "$T/err.txt" || fail "MPI beetle"
same "$T/beetle1.exr" "$T/beetle2.exr" "a band of the beetle"

"$S" render "$SCENES/moving_camera.toml" --frames 0..2 -o "$T/f1.#.exr" --float --no-preview -q 2> "$T/err.txt" || fail "one-process frames"
"${MPI[@]}" "$S" render "$SCENES/moving_camera.toml" --frames 0..2 -o "$T/f2.#.exr" --float --no-preview -q 2> "$T/err.txt" || fail "MPI frames"
for f in 0 1 2; do same "$T/f1.$f.exr" "$T/f2.$f.exr" "frame $f"; done

# A scene no rank can read: one message (rank 0's), a failing exit, nothing written.
"${MPI[@]}" "$S" render "$T/missing.toml" -o "$T/missing.exr" -q > "$T/err.txt" 2>&1 && fail "a missing scene rendered"
[ "$(grep -c "spangle: error: scene file .*missing.toml' not found" "$T/err.txt")" = 1 ] || fail "the missing scene is not reported exactly once"
[ ! -e "$T/missing.exr" ] || fail "an image was written for a missing scene"
"${MPI[@]}" "$S" render "$SCENES/textured.toml" --watch > "$T/err.txt" 2>&1 && fail "--watch ran under MPI"
grep -q "are for one process" "$T/err.txt" || fail "--watch under MPI is not refused with a reason"

# Ranks that would render other pixels (another copy of the scene on one node, other options in
# an MPMD launch, another build of a plugin) are refused before any band, naming what differs.
MPMD=("${MPI[@]:0:1}" "${MPI[@]:3}")  # the launcher's options without -np 2
mkdir -p "$T/nodeA" "$T/nodeB"
sed "s#mesh = \"#mesh = \"$SCENES/#" "$SCENES/small_lit.toml" > "$T/nodeA/s.toml"
sed 's/intensity = \([0-9.]*\)/intensity = 2\1/' "$T/nodeA/s.toml" > "$T/nodeB/s.toml"
cmp -s "$T/nodeA/s.toml" "$T/nodeB/s.toml" && fail "the test's second scene is not another scene"
"${MPMD[@]}" -np 1 -wdir "$T/nodeA" "$S" render s.toml -o "$T/mixed.exr" -q : \
    -np 1 -wdir "$T/nodeB" "$S" render s.toml -o "$T/mixed.exr" -q > "$T/err.txt" 2>&1 &&
    fail "ranks reading different scene files rendered one image"
grep -q "rank 1 .*differs from rank 0 in the scene's files" "$T/err.txt" || fail "the differing scene is not named"
[ ! -e "$T/mixed.exr" ] || fail "an image was written from ranks of different scenes"
"${MPMD[@]}" -np 1 "$S" render "$T/nodeA/s.toml" --spp 4 -o "$T/mixed.exr" -q : \
    -np 1 "$S" render "$T/nodeA/s.toml" --spp 8 -o "$T/mixed.exr" -q > "$T/err.txt" 2>&1 &&
    fail "ranks of different --spp rendered one image"
grep -q "differs from rank 0 in the image settings" "$T/err.txt" || fail "the differing spp is not named"
"${MPMD[@]}" -np 1 "$S" render "$T/nodeA/s.toml" --spp 4 -o "$T/mixed.exr" -q : \
    -np 1 "$S" render "$T/nodeA/s.toml" --spp 4 --strategy nee -o "$T/mixed.exr" -q > "$T/err.txt" 2>&1 &&
    fail "ranks of different --strategy rendered one image"
grep -q "differs from rank 0 in the render options" "$T/err.txt" || fail "the differing strategy is not named"
[ ! -e "$T/mixed.exr" ] || fail "an image was written from ranks of different settings"

# A rank killed mid-render (a render that would take minutes): the launcher ends the job and
# names the rank; no image is written.
"${MPI[@]}" "$S" render "$SCENES/textured.toml" --spp 100000 -o "$T/killed.exr" -q > "$T/err.txt" 2>&1 &
job=$!
victim=
for _ in $(seq 1 300); do
    for p in $(pgrep -f "$T/killed.exr"); do
        tr '\0' '\n' < "/proc/$p/environ" 2>/dev/null | grep -qx 'OMPI_COMM_WORLD_RANK=1' && victim=$p
    done
    [ -n "$victim" ] && break
    sleep 0.1
done
[ -n "$victim" ] || { kill "$job"; fail "rank 1 never started"; }
sleep 1
kill -KILL "$victim"
wait "$job" && fail "the job succeeded with a rank killed"
grep -Eq "rank 1 .*(signal 9|Killed)" "$T/err.txt" || fail "the dead rank is not named"
[ ! -e "$T/killed.exr" ] || fail "an image was written by a job that lost a rank"
echo "mpi: OK"
