#!/usr/bin/env bash
# The MPI speed-up on the beetle: the same render as one process and over 1..N ranks of mpirun
# on this machine, each rank with T threads, and the load balance (busiest rank's render time
# over the mean). The images are compared with the one-process image (they must be equal).
#   tests/bench/mpi.sh [SPANGLE] [RANKS...]      e.g. tests/bench/mpi.sh build/spangle 1 2
# Environment: SIZE (640x360), SPP (16), THREADS (threads per rank, 1), BAND_ROWS (1),
# SCENE (assets/scenes/beetle.toml). Run it with nothing else on the machine.
set -eu
REPO=$(cd "$(dirname "$0")/../.." && pwd)
S=${1:-$REPO/build/spangle}
shift || true
RANKS=("$@")
[ ${#RANKS[@]} -gt 0 ] || RANKS=(1 2)
SIZE=${SIZE:-640x360} SPP=${SPP:-16} THREADS=${THREADS:-1} BAND_ROWS=${BAND_ROWS:-1}
SCENE=${SCENE:-$REPO/assets/scenes/beetle.toml}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
MPI=(mpirun --oversubscribe --bind-to none --mca btl self,vader,tcp --mca btl_tcp_if_include lo
     --mca oob_tcp_if_include lo --mca btl_vader_single_copy_mechanism none)
[ "$(id -u)" = 0 ] && MPI+=(--allow-run-as-root)
ARGS=(--size "$SIZE" --spp "$SPP" --threads "$THREADS" --float --no-preview)

now() { date +%s.%N; }
echo "scene $(basename "$SCENE"), $SIZE, $SPP spp, $THREADS thread(s) per rank, bands of $BAND_ROWS tile row(s); $(nproc) cores"
t0=$(now)
"$S" render "$SCENE" -o "$T/one.exr" "${ARGS[@]}" -q
t1=$(now)
base=$(echo "$t1 - $t0" | bc -l)
printf "one process: %.2f s wall\n" "$base"
for n in "${RANKS[@]}"; do
    t0=$(now)
    "${MPI[@]}" -np "$n" "$S" render "$SCENE" -o "$T/mpi$n.exr" "${ARGS[@]}" --band-rows "$BAND_ROWS" > "$T/out$n.txt" 2> "$T/err$n.txt"
    t1=$(now)
    wall=$(echo "$t1 - $t0" | bc -l)
    # One rank is the one-process render under the launcher (no bands, no report).
    line=$(grep "over $n ranks" "$T/out$n.txt" || echo "- s over 1 rank (1 band; whole image); balance (busiest / mean) 1")
    render=$(echo "$line" | sed -E 's/^([0-9.-]+) s over.*/\1/')
    balance=$(echo "$line" | sed -E 's/.*balance \(busiest \/ mean\) ([0-9.]+).*/\1/')
    same=equal
    oiiotool "$T/one.exr" "$T/mpi$n.exr" --diff --fail 0 --warn 0 > /dev/null 2>&1 || same=DIFFERENT
    printf "%2d ranks: %.2f s wall (speed-up %.2f), render %s s, balance %s, image %s\n" \
        "$n" "$wall" "$(echo "$base / $wall" | bc -l)" "$render" "$balance" "$same"
    [ "$n" -gt 1 ] && echo "    $(echo "$line" | sed -E 's/.*bands of [0-9]+ tile rows; (.*)\); balance.*/\1/')"
done
