#!/usr/bin/env bash
# `spangle render --frames` says a warning that holds for every frame once, for the first frame:
# an emitter that moves while the shutter is open (it is not blurred) was said once per frame,
# burying the frames' own lines. A warning that differs between frames is still said for each.
# Frames past the scene's frame range and its keys are said (once).
#   frames_warnings.sh SPANGLE REPO
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cd "$T"
cp "$REPO/assets/meshes/plane.ply" .
cat > scene.toml <<'SCENE'
[render]
width = 16
height = 12
spp = 1
frame_start = 0
frame_end = 3
fps = 4
shutter = [0, 1]
[camera]
position = [0, 4, 6]
look_at = [0, 0.5, 0]
[[material]]
name = "white"
plugin = "smooth"
model = "diffuse"
[[object]]
mesh = "plane.ply"
material = "white"
emission = [1, 1, 1]
interpolation = "linear"
[[object.keys]]
time = 0.0
[[object.keys]]
time = 1.0
translate = [1, 1, 0]
SCENE
"$S" render scene.toml --frames 0..3 -o f.#.exr --no-preview > out.txt 2> err.txt ||
    fail "the sequence did not render: $(cat err.txt)"
n=$(grep -c "emits light" err.txt)
[ "$n" = 1 ] || fail "the moving emitter's warning was said $n times, not once: $(cat err.txt)"
for f in 0 1 2 3; do [ -f "f.$f.exr" ] || fail "frame $f was not written"; done
grep -q "beyond the scene's frame range" err.txt && fail "frames inside the range warned"
# Frames past the scene's range are said once (they rendered the last pose, silently).
"$S" render scene.toml --frames 3..5 -o g.#.exr --no-preview > out.txt 2> err.txt ||
    fail "frames past the range did not render: $(cat err.txt)"
n=$(grep -c "frames 3..5 reach beyond the scene's frame range 0..3" err.txt)
[ "$n" = 1 ] || fail "frames past the range said $n times: $(cat err.txt)"
# Frames past frame_end but within the keys (1 s = frame 4) move: nothing to say (a turntable's
# keys ran past a frame_end left at its default and every frame was warned of holding a key).
"$S" render scene.toml --frames 3..4 -o h.#.exr --no-preview > out.txt 2> err.txt ||
    fail "frames within the keys did not render: $(cat err.txt)"
grep -q "beyond the scene's frame range" err.txt && fail "frames within the keys warned: $(cat err.txt)"
# A mesh sequence: every frame past frame_end reads its own file, so none holds a key (they were
# said to).
for f in 0 1 2 3 4 5; do cp plane.ply "p.$f.ply"; done
sed -e 's/^mesh = "plane.ply"/mesh = "p.#.ply"/' scene.toml > seq.toml
"$S" render seq.toml --frames 3..5 -o s.#.exr --no-preview > out.txt 2> err.txt ||
    fail "the mesh sequence did not render: $(cat err.txt)"
grep -q "beyond the scene's frame range" err.txt && fail "a mesh sequence's frames warned: $(cat err.txt)"
# A telephoto whose pixels are finer than 32-bit ray directions resolve (it rendered streaks and
# blocks without a word): said once for the sequence; an ordinary fov says nothing.
sed -e 's/^look_at = \[0, 0.5, 0\]/look_at = [0, 0.5, 0]\nfov = 0.00001/' scene.toml > tele.toml
"$S" render tele.toml --frames 0..2 -o t.#.exr --no-preview > out.txt 2> err.txt ||
    fail "the telephoto did not render: $(cat err.txt)"
n=$(grep -c "finer than 32-bit ray directions resolve" err.txt)
[ "$n" = 1 ] || fail "the telephoto's pixels said $n times, not once: $(cat err.txt)"
# The same through a narrow screen window (pbrt's, which convert writes) in an ordinary fov.
sed -e 's/^look_at = \[0, 0.5, 0\]/look_at = [0, 0.5, 0]\nscreen_window = [-1e-6, 1e-6, -1e-6, 1e-6]/' scene.toml > window.toml
"$S" render window.toml -o w.exr --no-preview 2> err.txt || fail "the screen window did not render: $(cat err.txt)"
grep -q "finer than 32-bit ray directions resolve" err.txt || fail "a narrow screen window was not said: $(cat err.txt)"
"$S" render scene.toml -o o.exr --no-preview 2> err.txt || fail "the still did not render"
grep -q "finer than 32-bit" err.txt && fail "an ordinary fov warned: $(cat err.txt)"
echo PASS
