#!/usr/bin/env bash
# The pixels of every scene in assets/scenes and tests/scenes, in every mode that renders them,
# hashed and held against the hashes of tests/regression/pixel_hashes.txt: a refactor that
# changes any bit of any channel fails here, whichever mode it broke.
#
#   pixel_hashes.sh check SPANGLE MPIEXEC REPO SCENE   one scene (a ctest test per scene)
#   pixel_hashes.sh write SPANGLE MPIEXEC REPO         every scene: rewrites the reference file
#                                                      for this machine's CPU class
#
# MPIEXEC may be "-" (a build without MPI: that mode is left out). Each scene is rendered small
# (64x36, 4 spp, 32-bit floats, the render layers) as
#   oneshot   spangle render --layers                     -> key "layers"
#   beauty    spangle render (no layers)                   -> key "beauty"
#   crop      three --crop windows, spangle merge          == layers
#   spp-range --spp-range 0..1 and 1..4, spangle merge     == beauty (ranges carry no layers)
#   frames    --frames F..F+1 (F = frame_start)            frame F == layers; frame F+1 -> "next"
#   next      --frames F+1..F+1 in a fresh process         == the sequence's frame F+1
#   watch     --watch, then a point light appended to a copy of the scene: the first image ==
#             layers, the image after the reload == a one-shot render of the edited copy -> "edited"
#   mpi       mpirun -np 2 spangle render --layers          == layers
# The modes are compared with each other on any machine. The stored hashes are compared only on
# machines of the CPU class they were written on (x86-64 with or without AVX-512, AVX2, FMA):
# Embree's kernels and libm's pick code paths by CPU features, which can change last bits.
# iinfo --hash is the SHA-1 of every channel's pixel values (not the header, which holds the
# render time).
set -u
MODE=$1 S=$2 MPIEXEC=$3 REPO=$4
REF="$REPO/tests/regression/pixel_hashes.txt"
T=$(mktemp -d)
PID=
trap '[ -n "$PID" ] && kill -9 $PID 2>/dev/null; rm -rf "$T"' EXIT
COMMON=(--size 64x36 --spp 4 --float --no-preview --threads 2)
ARGS=("${COMMON[@]}" -q)

cpu_class() {
    local flags c=x86_64
    flags=$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null)
    [ "$(uname -m)" = x86_64 ] || c=$(uname -m)
    for f in avx512f avx2 fma; do
        case " $flags " in *" $f "*) c="$c-$f" ;; esac
    done
    echo "$c"
}
CPU=$(cpu_class)

fail() { echo "FAIL: $SCENE_NAME: $*"; [ -f "$T/err.txt" ] && tail -20 "$T/err.txt"; exit 1; }
hash_of() {
    iinfo --hash "$1" 2>/dev/null | sed -n 's/.*SHA-1: *\([0-9A-F]*\).*/\1/p'
}
render() {  # render OUT ARGS...: a one-process render that must succeed
    local out=$1
    shift
    "$S" render "$@" -o "$out" "${ARGS[@]}" > "$T/out.txt" 2> "$T/err.txt" ||
        fail "spangle render $* failed"
}
# equal WHAT HASH EXPECTED: two hashes of one image must agree.
equal() {
    [ -n "$2" ] || fail "$1: no image hash"
    [ "$2" = "$3" ] || fail "$1 gives $2, expected $3"
}

# Renders one scene in every mode; prints "KEY HASH" lines for the stored keys.
run_scene() {
    local scene=$1 dir base start next
    dir=$(cd "$(dirname "$scene")" && pwd)
    base=$(basename "$scene" .toml)
    start=$(sed -n 's/^frame_start *= *\(-\{0,1\}[0-9]*\).*/\1/p' "$scene" | head -1)
    start=${start:-1}
    next=$((start + 1))

    render "$T/one.exr" "$scene" --layers
    local layers beauty
    layers=$(hash_of "$T/one.exr")
    render "$T/beauty.exr" "$scene"
    beauty=$(hash_of "$T/beauty.exr")

    # Crop windows that cut across tiles, merged into the whole frame.
    render "$T/c1.exr" "$scene" --layers --crop 0,0,40,20
    render "$T/c2.exr" "$scene" --layers --crop 40,0,64,36
    render "$T/c3.exr" "$scene" --layers --crop 0,20,40,36
    "$S" merge "$T/c1.exr" "$T/c2.exr" "$T/c3.exr" -o "$T/crop.exr" > /dev/null 2> "$T/err.txt" ||
        fail "spangle merge of the crops failed"
    equal "the merged crop windows" "$(hash_of "$T/crop.exr")" "$layers"

    render "$T/r1.exr" "$scene" --spp-range 0..1
    render "$T/r2.exr" "$scene" --spp-range 1..4
    "$S" merge "$T/r1.exr" "$T/r2.exr" -o "$T/ranges.exr" > /dev/null 2> "$T/err.txt" ||
        fail "spangle merge of the sample ranges failed"
    equal "the merged sample ranges" "$(hash_of "$T/ranges.exr")" "$beauty"

    render "$T/f.#.exr" "$scene" --layers --frames "$start..$next"
    equal "frame $start of --frames" "$(hash_of "$T/f.$start.exr")" "$layers"
    local frame_next
    frame_next=$(hash_of "$T/f.$next.exr")
    render "$T/g.#.exr" "$scene" --layers --frames "$next..$next"
    equal "frame $next alone" "$(hash_of "$T/g.$next.exr")" "$frame_next"

    # Watch mode on a copy whose relative file names are made absolute; the edit appends a
    # point light (a reload that rebuilds the lights and carries meshes, materials and BVHs).
    sed -E "s#\"([^\"/][^\"]*\.(obj|ply|exr|hdr|png|jpg|tif|tx|toml))\"#\"$dir/\1\"#g" "$scene" \
        > "$T/watch.toml"
    "$S" render "$T/watch.toml" --watch --no-pass-output --layers -o "$T/watch.exr" \
        "${COMMON[@]}" > "$T/watch.log" 2>&1 &
    PID=$!
    finished() {
        for _ in $(seq 1 2400); do
            [ "$(grep -c 'watching for changes' "$T/watch.log")" -ge "$1" ] && return 0
            kill -0 $PID 2>/dev/null || break
            sleep 0.05
        done
        cat "$T/watch.log"
        fail "the watch session's render $1 did not finish"
    }
    finished 1
    equal "the watch session's first image" "$(hash_of "$T/watch.exr")" "$layers"
    cp "$T/watch.toml" "$T/edited.toml"
    printf '\n[[light]]\ntype = "point"\nposition = [0.3, 2.5, 1.5]\nintensity = 3.0\n' \
        >> "$T/edited.toml"
    render "$T/edited.exr" "$T/edited.toml" --layers
    local edited
    edited=$(hash_of "$T/edited.exr")
    sleep 0.05  # a new modification time on file systems with coarse timestamps
    cp "$T/edited.toml" "$T/watch.toml"
    finished 2
    grep -q "^reload" "$T/watch.log" || fail "the watch session did not reload"
    equal "the watch session's image after the edit" "$(hash_of "$T/watch.exr")" "$edited"
    kill -INT $PID
    wait $PID 2>/dev/null
    PID=

    if [ "$MPIEXEC" != "-" ]; then
        local mpi=("$MPIEXEC" -np 2 --oversubscribe --mca btl self,vader,tcp
            --mca btl_tcp_if_include lo --mca oob_tcp_if_include lo
            --mca btl_vader_single_copy_mechanism none)
        [ "$(id -u)" = 0 ] && mpi+=(--allow-run-as-root)
        "${mpi[@]}" "$S" render "$scene" --layers -o "$T/mpi.exr" "${ARGS[@]}" \
            > "$T/out.txt" 2> "$T/err.txt" || fail "mpirun -np 2 spangle render failed"
        equal "mpirun -np 2" "$(hash_of "$T/mpi.exr")" "$layers"
    fi
    echo "layers $layers"
    echo "beauty $beauty"
    echo "next $frame_next"
    echo "edited $edited"
}

scenes() {
    ls "$REPO"/assets/scenes/*.toml "$REPO"/tests/scenes/*.toml
}
rel() { echo "${1#"$REPO"/}"; }

case "$MODE" in
check)
    SCENE_NAME=$(rel "$5")
    got=$(run_scene "$5") || { echo "$got"; exit 1; }
    if ! grep -q "^$CPU " "$REF" 2>/dev/null; then
        echo "the modes agree; no stored hashes for CPU class $CPU (stored: $(cut -d' ' -f1 "$REF" 2>/dev/null | sort -u | tr '\n' ' '))"
        exit 0
    fi
    status=0
    while read -r key h; do
        want=$(awk -v c="$CPU" -v s="$SCENE_NAME" -v k="$key" '$1 == c && $2 == s && $3 == k {print $4}' "$REF")
        if [ -z "$want" ]; then
            echo "FAIL: $SCENE_NAME: no stored hash for '$key' (tests/regression/pixel_hashes.sh write)"
            status=1
        elif [ "$want" != "$h" ]; then
            echo "FAIL: $SCENE_NAME: '$key' is $h, stored $want"
            status=1
        fi
    done <<< "$got"
    [ $status = 0 ] && echo "$SCENE_NAME: every mode gives the stored pixels ($CPU)"
    exit $status
    ;;
write)
    out="$T/ref.txt"
    [ -f "$REF" ] && grep -v "^$CPU " "$REF" > "$out"
    for scene in $(scenes); do
        SCENE_NAME=$(rel "$scene")
        echo "$SCENE_NAME" >&2
        got=$(run_scene "$scene") || { echo "$got"; exit 1; }
        while read -r key h; do echo "$CPU $SCENE_NAME $key $h" >> "$out"; done <<< "$got"
    done
    sort "$out" > "$REF"
    echo "wrote $REF"
    ;;
*)
    echo "usage: pixel_hashes.sh check|write SPANGLE MPIEXEC REPO [SCENE]"
    exit 2
    ;;
esac
