#!/usr/bin/env bash
# filter_samples = "shared" (each sample stays in its pixel and the filter spreads the pixels'
# means) from the command line: crop windows, an adaptive crop, --spp-range parts and two MPI
# ranks (when MPIEXEC is given) give the whole render's pixels bit for bit, in every channel (the
# colours spread, the data not); the spread image is the box render's pixels weighed by the
# filter's integral over each pixel (against oiiotool's own convolution); a box within its pixel
# spreads nothing; the spread image is smoother; a crop split into sample ranges is refused with the
# reason, writing nothing; a bad value is named with its file and line.
#   shared_filter.sh SPANGLE REPO_DIR [MPIEXEC]
set -u
S=$1 REPO=$2 MPIEXEC=${3:-}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/err.txt" 2>/dev/null; exit 1; }
same() {  # same A B WHAT: every channel equal
    oiiotool "$1" "$2" --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
        { cat "$T/diff.txt"; fail "$3"; }
}
# The test scene (flakes, textures, a normal map, light groups) with a filter of its own.
scene() {  # scene NAME FILTER RADIUS SAMPLES
    printf '[render]\nfilter = "%s"\nfilter_radius = %s\nfilter_samples = "%s"\n\n[[import]]\nfile = "%s"\n' \
        "$2" "$3" "$4" "$REPO/tests/scenes/textured.toml" > "$T/$1.toml"
}
scene bh blackman-harris 2 shared
ARGS=(--float --layers --no-preview -q)

"$S" render "$T/bh.toml" -o "$T/whole.exr" "${ARGS[@]}" 2> "$T/err.txt" || fail "whole render"
oiiotool --info -v "$T/whole.exr" | grep -q "glints_studio.R" || fail "the render lacks its layers"
"$S" render "$T/bh.toml" -o "$T/crop.exr" "${ARGS[@]}" --crop 37,11,101,50 2> "$T/err.txt" || fail "crop"
oiiotool "$T/whole.exr" --crop 64x39+37+11 -o "$T/whole_cut.exr"
same "$T/whole_cut.exr" "$T/crop.exr" "a crop window differs from the whole render's pixels"
# At the frame's corner (the spread renormalised where the frame ends).
"$S" render "$T/bh.toml" -o "$T/corner.exr" "${ARGS[@]}" --crop 150,60,160,64 2> "$T/err.txt" || fail "corner crop"
oiiotool "$T/whole.exr" --crop 10x4+150+60 -o "$T/whole_corner.exr"
same "$T/whole_corner.exr" "$T/corner.exr" "a crop at the frame's corner differs"

# Adaptive sampling: the crop renders its tiles and the reach around them.
AD=(--spp 32 --noise-threshold 0.3)
"$S" render "$T/bh.toml" -o "$T/awhole.exr" "${ARGS[@]}" "${AD[@]}" 2> "$T/err.txt" || fail "adaptive render"
"$S" render "$T/bh.toml" -o "$T/acrop.exr" "${ARGS[@]}" "${AD[@]}" --crop 14,15,31,64 2> "$T/err.txt" || fail "adaptive crop"
oiiotool "$T/awhole.exr" --crop 17x49+14+15 -o "$T/awhole_cut.exr"
same "$T/awhole_cut.exr" "$T/acrop.exr" "an adaptive crop differs from the whole render's pixels"

# --spp-range parts of the whole frame merge into the whole render (the merge spreads the merged
# means as the render does).
"$S" render "$T/bh.toml" -o "$T/beauty.exr" --float --no-preview -q 2> "$T/err.txt" || fail "beauty render"
"$S" render "$T/bh.toml" -o "$T/p1.exr" --float --no-preview -q --spp-range 0..3 2> "$T/err.txt" || fail "part 0..3"
"$S" render "$T/bh.toml" -o "$T/p2.exr" --float --no-preview -q --spp-range 3..8 2> "$T/err.txt" || fail "part 3..8"
oiiotool --info -v "$T/p1.exr" | grep -q "spangle:filter_spread" || fail "the part does not say its spread"
"$S" merge "$T/p1.exr" "$T/p2.exr" -o "$T/merged.exr" > "$T/out.txt" 2> "$T/err.txt" || fail "merge"
same "$T/beauty.exr" "$T/merged.exr" "the merged sample ranges differ from the whole render"
# A part of another filter is not a part of this render (refused: its scene differs, which the
# header's scene hash says first; the weights' own check stands behind it).
scene bh15 blackman-harris 1.5 shared
"$S" render "$T/bh15.toml" -o "$T/q2.exr" --float --no-preview -q --spp-range 3..8 2> "$T/err.txt" || fail "part of another filter"
"$S" merge "$T/p1.exr" "$T/q2.exr" -o "$T/bad.exr" > "$T/out.txt" 2> "$T/err.txt" && fail "parts of two filters merged"
[ ! -e "$T/bad.exr" ] || fail "a refused merge wrote its output"

# Sample ranges of a crop window cannot merge (their pixels need samples beyond the window).
"$S" render "$T/bh.toml" -o "$T/bad.exr" --no-preview -q --spp-range 0..3 --crop 10,10,50,40 2> "$T/err.txt"; rc=$?
[ $rc -eq 1 ] || fail "a crop's sample range exited $rc, not 1"
grep -q 'parts of a crop window cannot be merged with filter_samples = "shared"' "$T/err.txt" || fail "no reason for the refusal"
[ ! -e "$T/bad.exr" ] || fail "an output was written for a refused part"

# The spread is the box render weighed by the filter: a box of radius 1 (variance 1/3) spreads
# by 1/8, 3/4, 1/8 (variance 1/4, and the pixel's own 1/12), and both renders draw the same
# samples (uniform in the pixel). oiiotool convolves the own-samples box render with that kernel;
# the frame's edge (where oiiotool pads and Spangle renormalises) is left out.
scene box1 box 1 shared
scene box05 box 0.5 own
"$S" render "$T/box1.toml" -o "$T/box1.exr" --float --no-preview -q 2> "$T/err.txt" || fail "box 1 render"
"$S" render "$T/box05.toml" -o "$T/box05.exr" --float --no-preview -q 2> "$T/err.txt" || fail "box 0.5 render"
python3 - "$T/kernel.pfm" << 'EOF'
import struct, sys
w = [0.125, 0.75, 0.125]
open(sys.argv[1], "wb").write(b"Pf\n3 3\n-1.0\n" + struct.pack("<9f", *[a * b for a in w for b in w]))
EOF
oiiotool "$T/box05.exr" --ch R,G,B "$T/kernel.pfm" --origin -1-1 --convolve --crop 158x62+1+1 -o "$T/conv.exr"
oiiotool "$T/box1.exr" --ch R,G,B --crop 158x62+1+1 -o "$T/box1_in.exr"
oiiotool "$T/box1_in.exr" "$T/conv.exr" --diff --fail 1e-5 --warn 1e-5 > "$T/diff.txt" 2>&1 ||
    { cat "$T/diff.txt"; fail "the shared box 1 image is not the box render spread by 1/8, 3/4, 1/8"; }
# ... and it is smoother: its pixels differ less from their right-hand neighbours'.
roughness() {
    oiiotool "$1" --ch R --crop 158x62+1+1 "$1" --ch R --crop 158x62+2+1 --origin +1+1 --sub --abs \
        --printstats 2>&1 | sed -n 's/.*Stats Avg: \([0-9.e+-]*\).*/\1/p'
}
R05=$(roughness "$T/box05.exr") R1=$(roughness "$T/box1.exr")
python3 -c "import sys; sys.exit(0 if float('$R1') < 0.8 * float('$R05') else 1)" ||
    fail "the spread image is not smoother: mean neighbour difference $R1 against $R05"
# A box within its pixel spreads nothing: the same bits as each pixel's own samples.
scene box05s box 0.5 shared
"$S" render "$T/box05s.toml" -o "$T/box05s.exr" --float --no-preview -q 2> "$T/err.txt" || fail "box 0.5 shared render"
same "$T/box05.exr" "$T/box05s.exr" "a shared box of radius 0.5 differs from its own samples"

# Two MPI ranks, bands of one tile row: each renders the rows its band's pixels reach.
if [ -n "$MPIEXEC" ]; then
    MPI=("$MPIEXEC" -np 2 --oversubscribe --mca btl self,vader,tcp --mca btl_tcp_if_include lo
         --mca oob_tcp_if_include lo --mca btl_vader_single_copy_mechanism none)
    [ "$(id -u)" = 0 ] && MPI+=(--allow-run-as-root)
    "${MPI[@]}" "$S" render "$T/bh.toml" -o "$T/mpi.exr" "${ARGS[@]}" --band-rows 1 > "$T/out.txt" 2> "$T/err.txt" || fail "mpirun"
    same "$T/whole.exr" "$T/mpi.exr" "the MPI image differs from the one-process image"
fi

# A bad value: file and line.
printf '[render]\nwidth = 8\nheight = 8\nfilter_samples = "splat"\n' > "$T/badvalue.toml"
"$S" render "$T/badvalue.toml" -o "$T/bad.exr" -q 2> "$T/err.txt" && fail "a bad filter_samples rendered"
grep -q "badvalue.toml:4.*unknown filter_samples 'splat' (valid: own, shared)" "$T/err.txt" || fail "no file:line for the bad value"
echo PASS
