#!/usr/bin/env bash
# Runs Spangle's libFuzzer targets over their seed corpus.
#   tests/fuzz/run.sh BUILD_DIR [TARGET|all] [RUNS] [libFuzzer options...]
# BUILD_DIR is a build folder configured with clang and -DSPANGLE_FUZZ=ON (tests/fuzz/README.md).
# Each target starts from the seeds (tests/scenes*, tests/scenes_bad/, assets/) plus what earlier
# runs found (BUILD_DIR/fuzz-corpus/TARGET, kept between runs), runs RUNS inputs (default
# 100000; -1 runs until stopped) with a 10 s per-input limit and a 2 GB memory limit, and prints
# the number of executions. A crash leaves its input as BUILD_DIR/fuzz-crashes/TARGET/crash-*;
# turn it into a case in tests/scenes_bad/ (see the README) before fixing it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
src="$(cd "$here/../.." && pwd)"
build="$(cd "${1:?usage: run.sh BUILD_DIR [TARGET|all] [RUNS] [libFuzzer options...]}" && pwd)"
which="${2:-all}"
runs="${3:-100000}"
shift $(( $# < 3 ? $# : 3 ))
targets=(scene pbrt gltf ply obj cage)
[ "$which" = all ] || targets=("$which")

seeds() {  # seeds TARGET DIR: copies the target's seed files into DIR
    local t="$1" dir="$2" f
    mkdir -p "$dir"
    case "$t" in
        scene) for f in "$src"/tests/scenes/*.toml "$src"/tests/scenes_bad/*.toml "$src"/assets/scenes/*.toml; do cp "$f" "$dir/"; done ;;
        pbrt) for f in "$src"/tests/scenes/pbrt/*.pbrt "$src"/tests/scenes_bad/pbrt/*.pbrt; do cp "$f" "$dir/"; done ;;
        gltf) for f in "$src"/tests/scenes/gltf/*.gltf "$src"/tests/scenes/gltf/*.glb "$src"/tests/scenes_bad/gltf/*; do cp "$f" "$dir/"; done ;;
        ply) for f in "$src"/tests/scenes_bad/meshes/*.ply "$src"/assets/meshes/*.ply; do cp "$f" "$dir/"; done ;;
        obj) for f in "$src"/tests/scenes_bad/meshes/*.obj "$src"/assets/meshes/snowman_nose.obj; do cp "$f" "$dir/"; done ;;
        cage) for f in "$src"/tests/scenes_bad/cages/*.obj "$src"/assets/meshes/snowman_*.obj "$src"/assets/meshes/beetle_boards.obj; do cp "$f" "$dir/"; done ;;
    esac
    if [ -d "$here/corpus/$t" ]; then cp "$here/corpus/$t"/* "$dir/" 2>/dev/null || true; fi
}

total=0
for t in "${targets[@]}"; do
    bin="$build/spangle_fuzz_$t"
    [ -x "$bin" ] || { echo "run.sh: $bin not built (cmake --build $build --target spangle_fuzz_all)" >&2; exit 2; }
    corpus="$build/fuzz-corpus/$t"
    seed_dir="$(mktemp -d)"
    seeds "$t" "$seed_dir"
    mkdir -p "$corpus" "$build/fuzz-crashes/$t"
    dict=()
    [ -f "$here/$t.dict" ] && dict=(-dict="$here/$t.dict")
    [ "$t" = cage ] && [ -f "$here/obj.dict" ] && dict=(-dict="$here/obj.dict")
    log="$build/fuzz-crashes/$t/last-run.log"
    echo "fuzz $t: $runs runs (log: $log)"
    status=0
    # glTF: 30 s. Debian's libdraco reads one count in a Draco stream's texture-coordinate
    # prediction unchecked and loops up to 2^31 times on it (about 20 s under the sanitizers,
    # tests/fuzz/slow/, README "Known: a slow Draco stream"); every other target: 10 s.
    limit=10
    [ "$t" = gltf ] && limit=30
    ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=0" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
        "$bin" "$corpus" "$seed_dir" -runs="$runs" -timeout="$limit" -rss_limit_mb=2048 -max_len=65536 \
        -artifact_prefix="$build/fuzz-crashes/$t/" -print_final_stats=1 "${dict[@]}" "$@" > "$log" 2>&1 || status=$?
    rm -rf "$seed_dir"
    execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
    echo "fuzz $t: ${execs:-?} executions, exit $status"
    total=$(( total + ${execs:-0} ))
    if [ "$status" -ne 0 ]; then
        # The report without its shadow-byte map (a CI log shows only its end): the error, its
        # stack frames, the summary, and the input itself (gzip, base64) when it is small, so
        # that a failure seen only in a log can be replayed:
        #   echo TEXT | base64 -d | gunzip > crash; BUILD_DIR/spangle_fuzz_TARGET crash
        grep -E "ERROR:|runtime error|READ of size|WRITE of size|is located|allocated by|freed by|previously allocated|Direct leak|Indirect leak|^ *#[0-9]+ |SUMMARY|^MS:|Test unit written|deadly signal" \
            "$log" | head -80 | cut -c1-240 >&2 || true
        # The input this run wrote (the folder keeps earlier runs' too: none is taken for it).
        unit="$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1 || true)"
        if [ -n "$unit" ] && [ -f "$unit" ] && [ "$(gzip -9nc "$unit" | wc -c)" -le 6000 ]; then
            echo "fuzz $t: the input, gzip and base64: $(gzip -9nc "$unit" | base64 -w 0)" >&2
        fi
        tail -4 "$log" >&2
        exit 1
    fi
done
echo "fuzz: $total executions in all, no crash, hang or sanitizer report"
