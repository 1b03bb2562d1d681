#!/usr/bin/env bash
# What a render writes never replaces what it reads or what it should not touch, and parts of
# different renders do not merge (each found by a user trying the command line; before, every
# case below exited 0 and replaced or mixed files):
# - `-o` or `--preview` naming the scene file, a mesh or the environment map is refused before
#   anything renders, and the file is intact;
# - a preview that does not end in .png is refused (it wrote PNG bytes into scene.toml, p.jpg);
# - `--frames` checks every frame's paths before the first renders (a folder at frame 2's path
#   failed after frame 1 with "...: Success");
# - `--layers` with a compression lossy for 32-bit floats (pxr24, dwaa, dwab) is refused: it
#   corrupted the ids, depth and positions;
# - `spangle merge` refuses crops of different scenes, and of different frames of one scene;
#   of a scene whose mesh or texture was edited between them, of another camera (--camera), of another
#   colour space;
# - `spangle new` does not overwrite an existing ground plane PLY without --force.
#   inputs_kept.sh SPANGLE REPO
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
expect() {
    local want=$1 pattern=$2
    shift 2
    "$S" "$@" > "$T/out.txt" 2> "$T/err.txt"
    local got=$?
    [ "$got" = "$want" ] || fail "spangle $*: exit $got, expected $want; stderr: $(cat "$T/err.txt")"
    grep -q -- "$pattern" "$T/err.txt" || fail "spangle $*: stderr lacks '$pattern': $(cat "$T/err.txt")"
    return 0
}
cd "$T"
cp "$REPO/assets/meshes/sphere.obj" "$REPO/assets/meshes/plane.ply" "$REPO/assets/env/studio.exr" .
cp "$REPO/assets/textures/beetle_livery.png" tex.png
cat > scene.toml <<'EOF'
[render]
width = 24
height = 16
spp = 2
frame_start = 1
frame_end = 3
[camera]
position = [0, 1.3, 6]
look_at = [0, 0.7, 0]
fov = 30
[environment]
map = "studio.exr"
[[material]]
name = "grey"
plugin = "smooth"
model = "diffuse"
params = { albedo = 0.5 }
[[material]]
name = "textured"
plugin = "smooth"
model = "diffuse"
params = { albedo = { texture = "tex.png" } }
[[object]]
mesh = "plane.ply"
material = "grey"
scale = 20
[[object]]
mesh = "sphere.obj"
material = "textured"
translate = [0, 0.7, 0]
keys = [{ frame = 1, translate = [0, 0.7, 0] }, { frame = 3, translate = [1, 0.7, 0] }]
EOF
sum() { md5sum scene.toml sphere.obj plane.ply studio.exr tex.png; }
before=$(sum)
expect 1 "a file the scene reads" render scene.toml -o studio.exr -q
expect 1 "a file the scene reads" render scene.toml -o ./studio.exr -q
expect 1 "a file the scene reads" render scene.toml -o scene.toml.exr --preview tex.png -q
expect 2 "must end in .png" render scene.toml -o out.exr --preview scene.toml -q
expect 2 "must end in .png" render scene.toml -o out.exr --preview sphere.obj -q
[ "$(sum)" = "$before" ] || fail "an input file changed"
mkdir o.0002.exr
expect 1 "frame 2's EXR 'o.0002.exr': it is a folder" render scene.toml -o o.exr --frames 1..3 -q
[ ! -e o.0001.exr ] || fail "frame 1 rendered before frame 2's folder was found"
# Frame 2's output is the scene's map: refused before frame 1 renders (frame 1 was written).
cp studio.exr env.0002.exr
sed 's/map = "studio.exr"/map = "env.0002.exr"/' scene.toml > envseq.toml
expect 1 "the EXR 'env.0002.exr' is a file the scene reads" render envseq.toml -o env.exr --frames 1..3 -q
[ ! -e env.0001.exr ] || fail "frame 1 rendered before frame 2's output was found to be an input"
cmp -s studio.exr env.0002.exr || fail "the map was overwritten"
for c in pxr24 dwaa dwab; do
    expect 2 "lossy for 32-bit floats" render scene.toml --layers --compression "$c" -o l.exr -q
done
"$S" render scene.toml --layers --compression b44 -o l.exr -q || fail "b44 with --layers refused"
# Merges.
sed 's/albedo = 0.5/albedo = 0.6/' scene.toml > other.toml
"$S" render scene.toml -o a.exr --crop 0,0,12,16 -q --no-preview || fail "crop a"
"$S" render other.toml -o b.exr --crop 12,0,24,16 -q --no-preview || fail "crop b"
"$S" render scene.toml -o c.exr --crop 12,0,24,16 -q --no-preview || fail "crop c"
expect 1 "rendered from different scenes" merge a.exr b.exr -o m.exr
"$S" merge a.exr c.exr -o m.exr > /dev/null || fail "crops of one render did not merge"
# The merged header's render time is the parts' together (it was the first part's).
t() { iinfo -v "$1" | sed -n 's/.*renderTimeSeconds: *\([0-9.e-]*\).*/\1/p'; }
python3 -c "import sys; a, c, m = map(float, sys.argv[1:]); sys.exit(0 if abs(a + c - m) <= 1e-4 * max(m, 1e-3) else 1)" \
    "$(t a.exr)" "$(t c.exr)" "$(t m.exr)" || fail "merged time $(t m.exr), parts $(t a.exr) + $(t c.exr)"
"$S" render scene.toml -o fa.exr --crop 0,0,12,16 --frames 1..1 -q --no-preview || fail "frame 1"
"$S" render scene.toml -o fb.exr --crop 12,0,24,16 --frames 3..3 -q --no-preview || fail "frame 3"
expect 1 "parts of one frame merge" merge fa.0001.exr fb.0003.exr -o m2.exr
expect 1 "'nope.exr' does not exist" merge nope.exr a.exr -o m3.exr
# A mesh, texture or map edited between the parts changes the scene's hash too (only the scene
# files counted: parts of a scaled sphere merged into a seam); so do another camera position and
# another colour space (another OCIO config or working space).
cp sphere.obj sphere.keep
echo "# edited" >> sphere.obj
"$S" render scene.toml -o d.exr --crop 12,0,24,16 -q --no-preview || fail "crop d"
expect 1 "rendered from different scenes" merge a.exr d.exr -o m4.exr
cp sphere.keep sphere.obj
cp tex.png tex.keep
oiiotool tex.keep --mulc 0.5 -o tex.png
"$S" render scene.toml -o e.exr --crop 12,0,24,16 -q --no-preview || fail "crop e"
expect 1 "rendered from different scenes" merge a.exr e.exr -o m5.exr
cp tex.keep tex.png
cat > two.gltf <<'JSON'
{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
 "nodes": [{"camera": 0, "translation": [0, 0, 5]}, {"camera": 1, "translation": [1, 0, 5]}],
 "cameras": [{"name": "Camera", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}},
             {"name": "Camera2", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]}
JSON
TWO=two.gltf
"$S" render "$TWO" --camera Camera -o f1.exr --size 24x16 --spp 1 --crop 0,0,12,16 -q \
    --no-preview || fail "crop f1"
"$S" render "$TWO" --camera Camera2 -o f2.exr --size 24x16 --spp 1 --crop 12,0,24,16 -q \
    --no-preview || fail "crop f2"
expect 1 "different cameras" merge f1.exr f2.exr -o m6.exr
OCIO="$REPO/tests/ocio/foreign.ocio" "$S" render scene.toml -o g.exr --crop 12,0,24,16 -q \
    --no-preview 2> /dev/null || fail "crop g"
expect 1 "in colour space" merge a.exr g.exr -o m7.exr
"$S" merge a.exr c.exr -o m.exr > /dev/null || fail "crops of one render no longer merge"
# spangle new and its ground plane.
echo precious > ball_ground.ply
expect 2 "ball_ground.ply' (the scene's ground plane) exists" new --mesh sphere.obj -o ball.toml \
    --env studio.exr
[ "$(cat ball_ground.ply)" = precious ] || fail "the ground plane file was replaced"
[ ! -e ball.toml ] || fail "the scene was written although its ground plane was refused"
"$S" new --mesh sphere.obj -o ball.toml --env studio.exr --force -q > /dev/null ||
    fail "new --force failed"
# The ground plane never replaces the model, even with --force (it did: t_ground.ply became the
# plane); the shipped studio map is copied beside the scene (it pointed into the build tree).
cp plane.ply t_ground.ply
before_model=$(md5sum < t_ground.ply)
expect 2 "would overwrite the model" new --mesh t_ground.ply -o t.toml --force
[ "$(md5sum < t_ground.ply)" = "$before_model" ] || fail "new replaced the model"
"$S" new --mesh sphere.obj -o own.toml -q > /dev/null || fail "new without --env failed"
grep -q '^map = "own_studio.exr"' own.toml || fail "the studio map is not beside the scene"
[ -s own_studio.exr ] || fail "the studio map was not copied"
echo "PASS"
