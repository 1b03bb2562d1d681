#!/usr/bin/env bash
# Image files as users bring them, read as they are meant: a quad that fills a 32x32 image, lit
# by a white sky, shows its diffuse albedo texture's linear value at every pixel. Found by a user
# (each line below failed before): straight alpha was multiplied into a PNG's sRGB colour (alpha
# 0.5 gave 0.17 for 0.8; alpha 0 black); a grey + alpha map gave (grey, alpha, alpha); a layer's
# channels (diffuse.R, .G, .B) came out B, G, R; an EXR's display window was ignored (its data
# window stretched over the quad); an 8-bit PNG environment map was read as linear (128 lit 0.50,
# not 0.22); a valid 1-bit PNG mask was refused as truncated; a texture replaced by another of the
# same size and mtime (cp -p, rsync -t, an unpacked archive) kept its stale converted copy.
#   image_inputs.sh SPANGLE
set -u
S=$1
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
cd "$T" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
cat > quad.obj <<'EOF'
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1 4/4/1
EOF
# scene ALBEDO [ENVIRONMENT BODY] > s.toml
scene() {
    cat <<EOT
[render]
width = 32
height = 32
spp = 4
max_depth = 1
filter = "box"
working_space = "lin_rec709"
[camera]
position = [0, 0, 2]
look_at = [0, 0, 0]
fov = 53.130102354
[environment]
${2:-color = [1, 1, 1]}
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
params = { albedo = $1 }
[[object]]
mesh = "quad.obj"
material = "m"
EOT
}
render() { "$S" render s.toml -o o.exr -q --no-preview --float --texture-cache "$T/cache" || fail "render of $(grep albedo s.toml) failed"; }
# mean R G B of the render, or of one pixel (X Y)
mean() {
    if [ $# -eq 2 ]; then oiiotool o.exr --cut "1x1+$1+$2" --printstats; else oiiotool o.exr --printstats; fi |
        grep 'Stats Avg' | sed 's/.*Avg: *//; s/ (float)//'
}
# near "R G B" "R G B" TOL: every channel within TOL
near() {
    python3 -c "import sys; a=[float(x) for x in sys.argv[1].split()]; b=[float(x) for x in sys.argv[2].split()]; sys.exit(0 if all(abs(x-y)<=float(sys.argv[3]) for x,y in zip(a,b)) and len(a)==len(b)==3 else 1)" "$1" "$2" "$3"
}
expect() {  # expect WHAT "R G B" TOL [X Y]
    local what=$1 want=$2 tol=$3
    shift 3
    local got
    got=$(mean "$@")
    near "$got" "$want" "$tol" || fail "$what: got $got, expected $want"
}
# PNGs written byte by byte (no library premultiplies on the way): sRGB (231, 124, 89) is linear
# (0.8, 0.2, 0.1).
python3 - <<'EOF'
import struct, zlib
def png(path, w, h, bits, ctype, rows):
    chunk = lambda t, d: struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d))
    raw = b''.join(b'\0' + r for r in rows)
    open(path, 'wb').write(b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, bits, ctype, 0, 0, 0))
                           + chunk(b'IDAT', zlib.compress(raw, 9)) + chunk(b'IEND', b''))
png('opaque.png', 8, 8, 8, 2, [bytes([231, 124, 89] * 8)] * 8)
png('alpha50.png', 8, 8, 8, 6, [bytes([231, 124, 89, 128] * 8)] * 8)
png('alpha0.png', 8, 8, 8, 6, [bytes([231, 124, 89, 0] * 8)] * 8)
png('greya.png', 8, 8, 8, 4, [bytes([150, 255] * 8)] * 8)
png('grey128.png', 64, 32, 8, 0, [bytes([128] * 64)] * 32)
# A 16384 x 2048 1-bit mask of 7 KB: deflate packs it at ~4800 pixels per byte.
png('mask.png', 16384, 2048, 1, 0, [b'\xff' * 2048] * 2048)
EOF
oiiotool --pattern constant:color=0.8,0.2,0.1 8x8 3 -d float -o rgb.exr
oiiotool rgb.exr --chnames diffuse.R,diffuse.G,diffuse.B -o layer.exr
oiiotool rgb.exr --origin +4+4 --fullsize 16x16+0+0 -o window.exr
oiiotool --pattern constant:color=0.5 64x32 1 -d float --chnames Y --ch Y,A=1.0 -o greyalpha.exr

for t in opaque.png alpha50.png alpha0.png; do
    scene "{ texture = \"$t\" }" > s.toml
    render
    expect "$t (straight alpha ignored)" "0.8 0.2 0.1" 0.004
done
scene '{ texture = "greya.png", space = "raw" }' > s.toml
render
expect "grey + alpha raw map" "0.588 0.588 0.588" 0.003
scene '{ texture = "layer.exr" }' > s.toml
render
expect "a layer's R, G, B" "0.8 0.2 0.1" 0.002
scene '{ texture = "window.exr" }' > s.toml
render
expect "inside the data window" "0.8 0.2 0.1" 0.002 20 20
expect "outside the data window" "0 0 0" 0.0001 4 4
scene '{ texture = "mask.png" }' > s.toml
render
expect "a 1-bit mask" "1 1 1" 0.002
scene 1.0 'map = "grey128.png"' > s.toml
render
expect "an 8-bit PNG sky (sRGB)" "0.2158 0.2158 0.2158" 0.002
scene 1.0 'map = "greyalpha.exr"' > s.toml
render
expect "a grey + alpha sky" "0.5 0.5 0.5" 0.002
# A sky with negative values (light cannot be negative): taken as 0 and said, with how much light
# that adds (they were clipped silently); a trace of ringing below 0 is not worth a line.
oiiotool --pattern constant:color=-0.5,-0.5,-0.5 8x32 3 -d float --pattern constant:color=0.5,0.5,0.5 64x32 3 -d float --paste +0+0 -o negsky.exr
scene 1.0 'map = "negsky.exr"' > s.toml
"$S" render s.toml -o o.exr -q --no-preview --float 2> err.txt || fail "the negative sky failed: $(cat err.txt)"
grep -q "warning: s.toml:13:[0-9]*: environment map 'negsky.exr' has 768 negative values (the lowest -0.5, at pixel (0, 0)): light cannot be negative, so they are taken as 0, adding 17% to the map's light" err.txt ||
    fail "negative sky values not said: $(cat err.txt)"
oiiotool o.exr --printstats | grep 'Stats Min' | grep -q -- '-' && fail "negative sky values lit negatively: $(oiiotool o.exr --printstats | grep 'Stats Min')"
oiiotool --pattern constant:color=-1e-6,-1e-6,-1e-6 1x1 3 -d float --pattern constant:color=0.5,0.5,0.5 64x32 3 -d float --paste +0+0 -o ringsky.exr
scene 1.0 'map = "ringsky.exr"' > s.toml
"$S" render s.toml -o o.exr -q --no-preview --float 2> err.txt || fail "the ringing sky failed: $(cat err.txt)"
grep -q "negative" err.txt && fail "a trace below 0 was said: $(cat err.txt)"
# A map of colours outside the working space (AP0 blue in lin_rec709): clipped, and said as a
# constant colour's is (it was clipped without a word).
oiiotool --pattern constant:color=0,0,1 64x32 3 -d float -o bluesky.exr
scene 1.0 'map = "bluesky.exr"
color_space = "ACES2065-1"' > s.toml
"$S" render s.toml -o o.exr -q --no-preview --float 2> err.txt || fail "the AP0 sky failed: $(cat err.txt)"
grep -q "environment map 'bluesky.exr' holds colours outside the working space 'lin_rec709' (4096 values negative once converted from 'ACES2065-1'" err.txt ||
    fail "an out-of-gamut map not said: $(cat err.txt)"
# A two-channel normal map (X, Y) tilts as the three-channel one does (it was read as grey).
oiiotool --pattern constant:color=0.75,0.5,0.9330127 8x8 3 -d float -o nxyz.exr
oiiotool nxyz.exr --ch R,G -o nxy.exr
light='color = [0, 0, 0]
[[light]]
type = "distant"
direction = [0.6, 0.3, 0.8]
intensity = 3.14159'
for m in nxyz nxy; do
    scene 0.5 "$light" | sed "s|^params = { albedo = 0.5 }|&\nnormal_map = { texture = \"$m.exr\" }|" > s.toml
    render
    eval "lit_$m=\"\$(mean)\""
done
scene 0.5 "$light" > s.toml
render
flat=$(mean)
near "$lit_nxy" "$lit_nxyz" 0.003 || fail "a two-channel normal map: $lit_nxy, three channels: $lit_nxyz"
near "$lit_nxyz" "$flat" 0.02 && fail "the normal map did not tilt: $lit_nxyz against flat $flat"
# A file's colour space follows what it holds, not its name: a PNG called .exr is sRGB, an EXR
# called .png linear (each was read the other way).
cp opaque.png png_named.exr
cp rgb.exr exr_named.png
for t in png_named.exr exr_named.png; do
    scene "{ texture = \"$t\" }" > s.toml
    render
    expect "$t" "0.8 0.2 0.1" 0.004
done
# NaN and infinite texels are 0, and said (they were replaced silently).
python3 -c "
import struct
vals = [float('nan'), float('inf'), 0.5] * 64
open('nan.pfm', 'wb').write(b'PF\n8 8\n-1.0\n' + struct.pack('<192f', *vals))"
oiiotool nan.pfm -o nan.exr
scene '{ texture = "nan.exr" }' > s.toml
"$S" render s.toml -o o.exr --no-preview --float --texture-cache "$T/cache" 2> err.txt ||
    fail "the NaN texture failed: $(cat err.txt)"
grep -q "has 128 values that are NaN or infinite" err.txt || fail "NaN texels not said: $(cat err.txt)"
expect "NaN and infinity as 0" "0 0 0.5" 0.002
# A texture replaced by another of the same size and modification time.
oiiotool --pattern constant:color=1,0,0 8x8 3 -d uint8 -o swap.tga
touch -d 2020-01-01 swap.tga
scene '{ texture = "swap.tga" }' > s.toml
render
expect "the first texture" "1 0 0" 0.002
oiiotool --pattern constant:color=0,0,1 8x8 3 -d uint8 -o swap.tga
touch -d 2020-01-01 swap.tga
render
expect "the replacement, same size and mtime" "0 0 1" 0.002
# A home whose cache cannot be written (a farm node's read-only or missing home): the converted
# texture goes to the temporary folder, said once (the render failed at the texture's line). A
# cache folder chosen with --texture-cache that cannot be written is an error naming it.
oiiotool --pattern constant:color=0,1,0 8x8 3 -d uint8 -o home.tga
scene '{ texture = "home.tga" }' > s.toml
env -u XDG_CACHE_HOME -u SPANGLE_TEXTURE_CACHE HOME=/proc/no_home TMPDIR="$T" \
    "$S" render s.toml -o o.exr --no-preview --float 2> err.txt ||
    fail "an unwritable home failed the render: $(cat err.txt)"
grep -q "texture cache '/proc/no_home/.cache/spangle/textures' cannot be written" err.txt ||
    fail "the cache's stand-in was not said: $(cat err.txt)"
expect "the texture through the temporary cache" "0 1 0" 0.002
"$S" render s.toml -o o.exr -q --no-preview --texture-cache /proc/no_cache 2> err.txt &&
    fail "an unwritable --texture-cache rendered"
grep -q "choose another folder with --texture-cache" err.txt || fail "unwritable cache: $(cat err.txt)"
# spangle convert of a .glb whose image is embedded copies the image beside the meshes: the
# scene renders the same once the cache it was unpacked to is gone (it named the cache).
CUBE=$(dirname "$0")/../scenes/gltf/cube.glb
mkdir -p conv
XDG_CACHE_HOME="$T/xdg" "$S" convert "$CUBE" -o conv/cube.toml -q || fail "convert of cube.glb failed"
grep -q 'texture = "cube_meshes/' conv/cube.toml || fail "the embedded image is not beside: $(grep texture conv/cube.toml)"
rm -rf "$T/xdg"
"$S" render conv/cube.toml -o c1.exr -q --no-preview --float --size 48x32 --spp 2 \
    --texture-cache "$T/cache" 2> err.txt || fail "the converted cube failed: $(cat err.txt)"
"$S" render "$CUBE" -o c2.exr -q --no-preview --float --size 48x32 --spp 2 \
    --texture-cache "$T/cache" || fail "the cube failed"
[ "$(iinfo --hash c1.exr | grep -o 'SHA-1: .*')" = "$(iinfo --hash c2.exr | grep -o 'SHA-1: .*')" ] ||
    fail "the converted cube renders other pixels"
# Converting again over a converted scene (where edits start) is refused without --force.
XDG_CACHE_HOME="$T/xdg" "$S" convert "$CUBE" -o conv/cube.toml -q 2> err.txt; rc=$?
[ $rc -eq 2 ] || fail "converting over an existing scene exited $rc, not 2"
grep -q "exists; --force writes over it" err.txt || fail "no reason for refusing: $(cat err.txt)"
XDG_CACHE_HOME="$T/xdg" "$S" convert "$CUBE" -o conv/cube.toml -q --force 2> err.txt ||
    fail "convert --force failed: $(cat err.txt)"
echo PASS
