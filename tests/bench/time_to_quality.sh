#!/usr/bin/env bash
# Time to a clean image: how long each way of rendering a scene takes to reach a relMSE target
# against a converged reference (docs/adaptive.md, docs/denoise.md).
#
#   tests/bench/time_to_quality.sh BUILD_DIR [OUT_DIR] [SCENE...]
#
# SCENE: a scene file, or `interior` (spangle bench's procedural room); default: the beetle and
# the interior. For each scene: a reference of REF_SPP samples that shares none with the runs
# (cached in OUT_DIR for the same scene, size, sample counts and build), then fixed sample
# counts (with and without --denoise), adaptive sampling at falling thresholds, and adaptive
# sampling with --denoise; each whole process timed (wall seconds,
# `date`), its relMSE against the reference measured by `spangle inspect --against`. Prints every
# run, then per way the first time it reached relMSE 0.01 and 0.002. Environment: SIZE (320x180), REF_SPP (2048), MAX_SPP
# (1024), THREADS (all cores). Time it on a quiet machine: anything running beside it counts.
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

# render NAME SCENE ARGS...: renders to OUT/NAME.exr; prints "seconds relMSE".
render() {
    local name=$1 scene=$2
    shift 2
    local t0 t1
    t0=$(now)
    "$spangle" render "$scene" --size "$size" -q --float --no-preview "${threads[@]}" \
        -o "$out/$name.exr" "$@"
    t1=$(now)
    local e
    e=$("$spangle" inspect "$out/$name.exr" --against "$out/ref_$label.exr" |
        sed -n 's/^relMSE against .*: //p')
    echo "$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }') $e"
}

for scene in "${scenes[@]}"; do
    if [ "$scene" = interior ]; then
        "$spangle" bench --write-scene "$out/interior" > /dev/null
        scene="$out/interior/interior.toml"
    fi
    label=$(basename "$scene" .toml)
    # The reference holds for one scene text, size, sample counts and build: another renders it
    # again. It takes samples max_spp.. of a longer frame, so no run (samples 0 to at most
    # max_spp - 1) shares a sample with it: a run of N samples that did would be closer to it
    # than its error, by about N / REF_SPP of it.
    key=$( { cat "$scene"; echo "$size $ref_spp $max_spp"
             stat -c '%n %s %Y' "$spangle" "$build"/plugins/*.so; } | sha256sum | cut -d' ' -f1)
    if [ ! -f "$out/ref_$label.exr" ] || [ "$(cat "$out/ref_$label.key" 2>/dev/null)" != "$key" ]; then
        echo "# $label: rendering the reference ($ref_spp spp)..." >&2
        rm -f "$out/ref_$label.exr" "$out/ref_$label.key"
        "$spangle" render "$scene" --size "$size" -q --float --no-preview "${threads[@]}" \
            --spp $((max_spp + ref_spp)) --spp-range "$max_spp..$((max_spp + ref_spp))" \
            -o "$out/ref_$label.exr"
        echo "$key" > "$out/ref_$label.key"
    fi
    echo "# $label at $size: way, setting, seconds, relMSE"
    results=()
    for spp in 4 8 16 32 64 128 256 512; do
        r=$(render "${label}_fixed_$spp" "$scene" --spp "$spp")
        echo "fixed $spp $r"
        results+=("fixed $spp $r")
        r=$(render "${label}_fixed_denoised_$spp" "$scene" --spp "$spp" --denoise)
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
                $1 == w && $4 <= t && (best == "" || $3 < best) { best = $3; at = $2 }
                END { if (best == "") printf "%s: %s never reached relMSE %s\n", l, w, t;
                      else printf "%s: %s reached relMSE %s in %.2f s (%s)\n", l, w, t, best, at }'
        done
    done
done
