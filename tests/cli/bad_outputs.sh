#!/usr/bin/env bash
# Bad command lines and output paths are refused before any rendering, with the documented exit
# status (2: the command line, 1: an input or output problem), one clear message, and no file
# left behind. Before: --size 4294967312x16 rendered 16x16; a bad --size or --compression exited
# 1; `-o same.exr --preview same.exr` replaced the EXR with a PNG and exited 0; a missing folder,
# a folder as output or an unwritable place was found after the whole render; `spangle rendr`
# said "A subcommand is required"; --noise-threshold nan, --preview with --no-preview, a missing
# --plugin-path, a .jpg preview (PNG bytes) and a second run of '#' were accepted. A panorama that
# is not 2:1 renders stretched with a warning.
#   bad_outputs.sh SPANGLE SCENE
set -u
S=$1 SCENE=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
# expect STATUS PATTERN ARGS...: runs spangle, checks the status and that stderr matches.
expect() {
    local want=$1 pattern=$2
    shift 2
    local start=$SECONDS
    "$S" "$@" > "$T/out.txt" 2> "$T/err.txt"
    local got=$?
    [ "$got" = "$want" ] || fail "spangle $*: exit $got, expected $want; stderr: $(cat "$T/err.txt")"
    grep -q -- "$pattern" "$T/err.txt" || fail "spangle $*: stderr lacks '$pattern': $(cat "$T/err.txt")"
    grep -q "render:" "$T/err.txt" && fail "spangle $*: rendered before refusing"
    [ $((SECONDS - start)) -le 5 ] || fail "spangle $*: took $((SECONDS - start)) s to refuse"
    return 0
}
cd "$T"
expect 2 "did you mean 'render'" rendr "$SCENE"
expect 2 "unknown command 'frobnicate'" frobnicate
expect 2 "WIDTHxHEIGHT" render "$SCENE" --size 4294967312x16
# A --min-spp above --spp (without --max-spp) is the command line's error (it exited 1).
expect 2 "is more than --spp 16" render "$SCENE" --spp 16 --min-spp 32 --noise-threshold 0.05
expect 2 "WIDTHxHEIGHT" render "$SCENE" --size 16x
expect 2 "WIDTHxHEIGHT" render "$SCENE" --size -16x16
expect 2 "unknown EXR compression 'foo'" render "$SCENE" --compression foo
expect 2 "must end in .exr" render "$SCENE" -o out.png
expect 2 "same file" render "$SCENE" -o same.exr --preview same.exr
mkdir sub
expect 2 "same file" render "$SCENE" -o same.exr --preview ./sub/../same.exr
expect 2 "PORT or ADDR:PORT" render "$SCENE" --serve 70000
# Options that contradict each other or name nothing (one of them silently won before).
expect 2 "got nan" render "$SCENE" --noise-threshold nan
expect 2 "choose one" render "$SCENE" --preview p.png --no-preview
expect 2 "choose one" render "$SCENE" --pass-output --no-pass-output
expect 2 "is not a folder" render "$SCENE" --plugin-path "$T/no_such_plugins"
expect 2 "must end in .png" render "$SCENE" -o out.exr --preview out.jpg
expect 2 "more than one run of '#'" render "$SCENE" -o "a.##.##.exr" --frames 1..1
expect 2 "add --denoise" render "$SCENE" --denoise-glints apart
# An empty value (an unset shell variable): `-o ''` wrote SCENE.exr beside the scene.
expect 2 "--output needs a value" render "$SCENE" -o ''
expect 2 "--preview needs a value" render "$SCENE" --preview ''
expect 2 "--output needs a value" merge -o '' a.exr
expect 1 "folder '$T/missing' does not exist" render "$SCENE" -o "$T/missing/out.exr"
# Through a missing folder: the missing one is named (it named the folder at the end, which exists).
expect 1 "folder '$T/missing' does not exist" render "$SCENE" -o "$T/missing/../out.exr"
expect 1 "folder '$T/missing' does not exist" render "$SCENE" -o "$T/missing/deeper/out.exr"
touch "$T/afile"
expect 1 "'$T/afile' is not a folder" render "$SCENE" -o "$T/afile/../out.exr"
rm "$T/afile"
mkdir folder.exr
expect 1 "it is a folder" render "$SCENE" -o folder.exr
expect 1 "it is a folder" render "$SCENE" -o out.exr --preview folder.exr
LONG=$(printf 'a%.0s' $(seq 1 300))
expect 1 "file name is longer" render "$SCENE" -o "$LONG.exr"
expect 1 "cannot create files in folder '/proc'" render "$SCENE" -o /proc/out.exr
[ -z "$(ls -A "$T" | grep -v -e out.txt -e err.txt -e folder.exr -e "^sub$")" ] ||
    fail "files left behind: $(ls -A "$T")"
# And a good command line still renders.
"$S" render "$SCENE" -o good.exr -q || fail "a good render failed"
[ -s good.exr ] && [ -s good.png ] || fail "the good render wrote no images"
# --min-spp / --max-spp without adaptive sampling render, and say they do nothing (silent before).
"$S" render "$SCENE" -o good.exr -q --min-spp 4 --max-spp 8 2> "$T/err.txt" ||
    fail "--min-spp without a threshold failed: $(cat "$T/err.txt")"
grep -q "adaptive sampling, which is off" "$T/err.txt" ||
    fail "--min-spp without a threshold said nothing: $(cat "$T/err.txt")"
"$S" render "$SCENE" -o good.exr -q --min-spp 4 --noise-threshold 0.1 2> "$T/err.txt" ||
    fail "--min-spp with a threshold failed"
grep -q "adaptive sampling, which is off" "$T/err.txt" && fail "warned with a threshold"
# A panorama on an image that is not 2:1 renders stretched: said (silent before), and not at 2:1.
cat > pano.toml <<'TOML'
[render]
width = 32
height = 16
spp = 1
[camera]
position = [0, 0, 0]
look_at = [0, 0, -1]
projection = "equirectangular"
[environment]
color = [0.5, 0.5, 0.5]
TOML
"$S" render pano.toml -o pano.exr -q --size 40x16 2> "$T/err.txt" || fail "a 40x16 panorama failed"
grep -q "40x16 image, which is not 2:1" "$T/err.txt" ||
    fail "a 40x16 panorama said nothing: $(cat "$T/err.txt")"
"$S" render pano.toml -o pano.exr -q 2> "$T/err.txt" || fail "a 32x16 panorama failed"
[ -s "$T/err.txt" ] && fail "a 2:1 panorama warned: $(cat "$T/err.txt")"
# A file-size limit (ulimit -f) is a write error naming the file, exit 1, no temporary file left
# (SIGXFSZ killed the process, exit 153, its temporary file left behind).
(ulimit -f 4; "$S" render pano.toml -o big.exr --size 256x128 --float --compression none -q \
    2> "$T/err.txt")
RC=$?
[ $RC = 1 ] || fail "a write past ulimit -f exited $RC: $(cat "$T/err.txt")"
grep -q "cannot write '.*big.exr'" "$T/err.txt" || fail "ulimit -f: $(cat "$T/err.txt")"
ls -A | grep -q "big.exr" && fail "a write past ulimit -f left $(ls -A | grep big.exr)"
# A bad value on the command line is one line like every other error, exit 2.
"$S" render pano.toml --threads 0 > /dev/null 2> "$T/err.txt" && fail "--threads 0 rendered"
[ "$(wc -l < "$T/err.txt")" = 1 ] && grep -q "^spangle: error: --threads: Value 0" "$T/err.txt" ||
    fail "--threads 0 said: $(cat "$T/err.txt")"
# spangle inspect reads a grey (Y-only) EXR, says where a crop part lies in its frame, and gives
# no range for Cryptomatte's id channels (hashes). Each was refused, missing or meaningless.
oiiotool --pattern constant:color=0.5 16x8 1 --chnames Y -o y.exr
"$S" inspect y.exr > "$T/out.txt" 2>&1 || fail "inspect of a Y-only EXR: $(cat "$T/out.txt")"
grep -q "mean luminance: 0.5" "$T/out.txt" || fail "Y-only EXR: $(cat "$T/out.txt")"
"$S" render pano.toml --crop 8,4,20,12 --layers -o cropped.exr -q --no-preview ||
    fail "the crop failed"
"$S" inspect cropped.exr > "$T/out.txt" || fail "inspect of a crop failed"
grep -q "12x8 at (8, 4) of a 32x16 frame" "$T/out.txt" || fail "crop: $(head -1 "$T/out.txt")"
grep -q "CryptoObject00.R .*(Cryptomatte ids: hashes, no range)" "$T/out.txt" ||
    fail "crypto ids: $(grep Crypto "$T/out.txt")"
# Luminance by the image's own primaries (an ACEScg render weighed as Rec.709 read 0.2464 for
# 0.2578), and a grey PNG read (it was refused: "expected RGB").
printf '[render]\nwidth = 8\nheight = 8\nspp = 1\nworking_space = "ACEScg"\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n[environment]\ncolor = [0.5, 0.2, 0.1]\n' > aces.toml
"$S" render aces.toml -o aces.exr --float -q --no-preview || fail "the ACEScg render failed"
"$S" inspect aces.exr > "$T/out.txt" || fail "inspect of the ACEScg render failed"
grep -q "mean luminance: 0.257.*chromaticities" "$T/out.txt" || fail "ACEScg luminance: $(head -2 "$T/out.txt")"
oiiotool --pattern constant:color=0.25 8x8 1 -d uint8 -o grey.png
"$S" inspect grey.png > "$T/out.txt" 2>&1 || fail "inspect of a grey PNG: $(cat "$T/out.txt")"
# (sRGB 64/255 decoded: 0.0513 in linear)
grep -q "mean luminance: 0.0512" "$T/out.txt" || fail "grey PNG: $(cat "$T/out.txt")"
# Two renders of one output write their EXR and PNG one pair at a time (a hidden lock file
# beside the EXR): a render waits while another holds the pair's lock, and removes the lock when
# done. (Unlocked, duplicate jobs left the EXR of one render beside the PNG of the other.)
if command -v flock > /dev/null; then
    : > .locked.exr.lock
    flock .locked.exr.lock sleep 2 &
    HOLDER=$!
    # Until the holder has the lock (a fixed 0.3 s was not always enough on a loaded machine:
    # the render took the lock first and the check below failed).
    for _ in $(seq 100); do flock -n .locked.exr.lock true || break; sleep 0.02; done
    "$S" render pano.toml -o locked.exr -q 2> "$T/err.txt" || fail "a locked render failed"
    kill -0 $HOLDER 2> /dev/null && fail "the render wrote while another held the output's lock"
    wait $HOLDER
    [ -e .locked.exr.lock ] && fail "the lock file was left behind"
    [ -s locked.exr ] && [ -s locked.png ] || fail "the locked render wrote nothing"
fi
# An upper-case ending is an EXR (out.EXR was refused: "must end in .exr").
"$S" render pano.toml -o upper.EXR --preview upper.PNG -q 2> "$T/err.txt" ||
    fail "an .EXR output was refused: $(cat "$T/err.txt")"
[ -s upper.EXR ] && [ -s upper.PNG ] || fail "the .EXR render wrote nothing"
# An output that is a symbolic link is written where it points (the link was replaced by a
# file of its own, the target never written), dangling or not.
mkdir -p real && : > real/target.exr && ln -s real/target.exr link.exr && ln -s real/new.png link.png
"$S" render pano.toml -o link.exr -q 2> "$T/err.txt" || fail "a linked output failed: $(cat "$T/err.txt")"
[ -L link.exr ] && [ -L link.png ] || fail "the links were replaced by files"
[ -s real/target.exr ] && [ -s real/new.png ] || fail "the links' targets were not written"
echo "PASS"
