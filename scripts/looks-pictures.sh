#!/usr/bin/env bash
# Renders the flake looks' scenes (tests/scenes/looks/) and writes their pictures in docs/: each
# render at the top, nearest-neighbour crops of its glints below. After a Release build:
#
#     bash scripts/looks-pictures.sh [SPANGLE] [PLUGIN_DIR]
#
# (defaults: the repository's build/spangle and build/plugins; about 20 seconds on 2 cores).
# Needs oiiotool (openimageio-tools). flake-facets.png, a larger render with its own crops, is
# not made here.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
spangle=$(realpath "${1:-$root/build/spangle}")
plugins=$(realpath "${2:-$root/build/plugins}")
if ! command -v oiiotool > /dev/null; then
    echo "looks-pictures.sh: needs oiiotool (openimageio-tools)" >&2
    exit 1
fi
cd "$root"
# The shipped colour configuration, whatever $OCIO says: the pictures are the docs'.
unset OCIO
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# render SCENE: renders tests/scenes/looks/SCENE.toml; its display PNG is $work/SCENE.png.
render() {
    "$spangle" render "tests/scenes/looks/$1.toml" --plugin-path "$plugins" -o "$work/$1.exr" -q
}

# crop SCENE NAME WxH+X+Y ZW ZH: cuts the region from the render and scales it to ZW x ZH
# pixels without interpolation (each rendered pixel a block).
crop() {
    oiiotool "$work/$1.png" --cut "$3" --resample:interp=0 "${4}x${5}" -o "$work/$2.png"
}

# compose OUT W H SCENE [CROP X Y]...: the render at the top left of a W x H canvas and each
# crop pasted at (X, Y).
compose() {
    local out=$1 w=$2 h=$3 scene=$4
    shift 4
    # (--paste puts the image below the top of the stack onto the top one.)
    local args=("$work/$scene.png" --create "${w}x${h}" 3 --paste +0+0)
    while [ $# -gt 0 ]; do
        args+=("$work/$1.png" --swap --paste "+$2+$3")
        shift 3
    done
    oiiotool "${args[@]}" -d uint8 -o "$out"
    echo "wrote $out"
}

# Per-flake colour variation: the first two spheres' upper left (their highlights) at 4x.
render flake_hsv
crop flake_hsv hsv1 80x51+150+66 320 204
crop flake_hsv hsv2 80x51+276+66 320 204
compose docs/flake-hsv.png 640 444 flake_hsv hsv1 0 240 hsv2 320 240

# Interference flakes: each sphere at 1.6x.
render flake_pearl
for k in 0 1 2 3; do
    crop flake_pearl "pearl$k" "100x100+$((132 + 92 * k))+50" 160 160
done
compose docs/flake-pearl.png 640 360 flake_pearl pearl0 0 200 pearl1 160 200 pearl2 320 200 \
    pearl3 480 200

# Two populations: the second and third spheres at 3x.
render flake_two_populations
crop flake_two_populations two2 106x106+267+67 318 318
crop flake_two_populations two3 106x106+394+67 318 318
compose docs/flake-two-populations.png 640 558 flake_two_populations two2 0 240 two3 322 240
