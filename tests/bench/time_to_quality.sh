#!/usr/bin/env bash
# Time to a clean image: how long each way of rendering a scene takes to reach a relMSE target
# against a converged reference (docs/adaptive.md, docs/denoise.md).
#
#   tests/bench/time_to_quality.sh BUILD_DIR [OUT_DIR] [SCENE...]
#
# SCENE: a scene file, or `interior` (spangle bench's procedural room); default: the beetle and
# the interior. For each scene: a reference of REF_SPP samples from two other seeds than the
# runs', whose own noise is measured and taken off each run's relMSE (cached in OUT_DIR for the
# same scene, size, sample count and build), then fixed sample counts (with and without
# --denoise), adaptive sampling at falling thresholds, and adaptive sampling with --denoise;
# each whole process timed (wall seconds, `date`), its relMSE against the reference and the glints
# it keeps of those both halves of the reference find measured by `spangle inspect --against`
# (given both halves). Prints every run, then per way the first time it reached relMSE 0.01 and
# 0.002 (less the reference's noise). Environment: SIZE (320x180), REF_SPP (2048),
# MAX_SPP (1024), THREADS (all cores). Time it on a quiet machine: anything running beside it
# counts. The reference and the fixed runs sample every pixel alike (--noise-threshold 0), even
# where the scene's [render] asks for adaptive sampling.
set -euo pipefail
build=$(cd "${1:?usage: time_to_quality.sh BUILD_DIR [OUT_DIR] [SCENE...]}" && pwd)
out=${2:-ttq}
shift $(( $# >= 2 ? 2 : 1 ))
root=$(cd "$(dirname "$0")/../.." && pwd)
size=${SIZE:-320x180}
ref_spp=${REF_SPP:-2048}
max_spp=${MAX_SPP:-1024}
threads=()
[ -n "${THREADS:-}" ] && threads=(--threads "$THREADS")
mkdir -p "$out"
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=("$root/assets/scenes/beetle.toml" interior)
spangle="$build/spangle"

# Seconds since the epoch, to the millisecond.
now() { date +%s.%N; }

# render NAME SCENE ARGS...: renders to OUT/NAME.exr; prints "seconds relMSE corrected-relMSE
# glints-kept" (glints kept as K/N, "-" where none were measured).
render() {
    local name=$1 scene=$2
    shift 2
    local t0 t1
    t0=$(now)
    "$spangle" render "$scene" --size "$size" -q --float --no-preview "${threads[@]}" \
        -o "$out/$name.exr" "$@"
    t1=$(now)
    # Against the two halves of the reference: the relMSE against their mean, and how many of
    # the glints both halves find the run keeps ("-" where it has none to measure).
    local report e g
    report=$("$spangle" inspect "$out/$name.exr" --against "$out/ref_${label}_977.exr" \
        --against "$out/ref_${label}_978.exr")
    # (The figure is the first word after the line's first ": ": a note of pixels left out
    # follows it.)
    e=$(awk '/^relMSE against / { sub(/^[^:]*: /, ""); print $1 }' <<< "$report")
    g=$(sed -n 's/^glints kept ([^)]*): \([0-9]*\) of \([0-9]*\).*/\1\/\2/p' <<< "$report")
    awk -v a="$t0" -v b="$t1" -v e="$e" -v n="$noise" -v g="${g:--}" \
        'BEGIN { printf "%.3f %s %.6f %s\n", b - a, e, e - n, g }'
}

# Seeded copies of a scene, written beside it (its relative paths hold) and removed on exit.
copies=()
trap 'rm -f "${copies[@]}"' EXIT
trap 'exit 130' INT TERM
# write_seeded SCENE SEED COPY: SCENE with [render] seed = SEED (replacing one it has).
write_seeded() {
    awk -v seed="$2" '
        /^[[:space:]]*\[/ { in_render = ($0 ~ /^[[:space:]]*\[render\][[:space:]]*(#.*)?$/)
                             print; if (in_render) { print "seed = " seed; done = 1 }; next }
        in_render && /^[[:space:]]*seed[[:space:]]*=/ { next }
        { print }
        END { if (!done) printf "\n[render]\nseed = %s\n", seed }' "$1" > "$3"
}

for scene in "${scenes[@]}"; do
    if [ "$scene" = interior ]; then
        "$spangle" bench --write-scene "$out/interior" > /dev/null
        scene="$out/interior/interior.toml"
    fi
    label=$(basename "$scene" .toml)
    # The reference: two halves of REF_SPP / 2 samples with their own seeds (977, 978), so
    # that neither shares samples, nor a sample pattern, with a run (a run of N samples that
    # began the reference would read closer to it than its error by about 2 N / REF_SPP of
    # it), averaged. It is not exact: relMSE against it is a run's error plus the reference's
    # own noise, the halves' relMSE against each other / 4, which is printed and taken off
    # ("corrected") before the targets are judged. Cached for one scene text, size, sample
    # count and build.
    key=$( { cat "$scene"; echo "$size $ref_spp layers"
             stat -c '%n %s %Y' "$spangle" "$build"/plugins/*.so 2>/dev/null || true; } |
           sha256sum | cut -d' ' -f1)
    if [ ! -f "$out/ref_${label}_977.exr" ] || [ ! -f "$out/ref_${label}_978.exr" ] ||
        [ "$(cat "$out/ref_$label.key" 2>/dev/null)" != "$key" ]; then
        echo "# $label: rendering the reference ($ref_spp spp, two seeds)..." >&2
        rm -f "$out/ref_$label".*
        for half in 977 978; do
            copy="$(dirname "$scene")/.$label.ttq-seed$half.$$.toml"
            copies+=("$copy")
            write_seeded "$scene" "$half" "$copy"
            "$spangle" render "$copy" --size "$size" -q --float --no-preview "${threads[@]}" \
                --spp $((ref_spp / 2)) --noise-threshold 0 --layers \
                -o "$out/ref_${label}_$half.exr"
            rm -f "$copy"
        done
        "$spangle" inspect "$out/ref_${label}_977.exr" --against "$out/ref_${label}_978.exr" |
            awk '/^relMSE against / { sub(/^[^:]*: /, ""); printf "%.6f\n", $1 / 4 }' \
            > "$out/ref_$label.noise"
        echo "$key" > "$out/ref_$label.key"
    fi
    noise=$(cat "$out/ref_$label.noise")
    echo "# $label at $size: reference noise (relMSE) $noise"
    echo "# $label at $size: way, setting, seconds, relMSE, relMSE - reference noise, glints kept"
    results=()
    for spp in 4 8 16 32 64 128 256 512; do
        r=$(render "${label}_fixed_$spp" "$scene" --spp "$spp" --noise-threshold 0)
        echo "fixed $spp $r"
        results+=("fixed $spp $r")
        r=$(render "${label}_fixed_denoised_$spp" "$scene" --spp "$spp" --noise-threshold 0 \
            --denoise)
        echo "fixed+denoise $spp $r"
        results+=("fixed+denoise $spp $r")
    done
    for t in 0.5 0.3 0.2 0.1 0.05 0.03 0.02 0.01; do
        r=$(render "${label}_adaptive_$t" "$scene" --spp "$max_spp" --noise-threshold "$t")
        echo "adaptive $t $r"
        results+=("adaptive $t $r")
        r=$(render "${label}_denoised_$t" "$scene" --spp "$max_spp" --noise-threshold "$t" \
            --denoise)
        echo "adaptive+denoise $t $r"
        results+=("adaptive+denoise $t $r")
    done
    for target in 0.01 0.002; do
        for way in fixed fixed+denoise adaptive adaptive+denoise; do
            printf '%s\n' "${results[@]}" | awk -v w="$way" -v t="$target" -v l="$label" '
                $1 == w && $5 <= t && (best == "" || $3 < best) { best = $3; at = $2; g = $6 }
                END { if (best == "") printf "%s: %s never reached relMSE %s\n", l, w, t;
                      else printf "%s: %s reached relMSE %s in %.2f s (%s; glints kept %s)\n",
                                  l, w, t, best, at, g }'
        done
    done
done
