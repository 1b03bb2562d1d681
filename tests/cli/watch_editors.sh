#!/usr/bin/env bash
# `--watch` as editors, exporters and users save (found by a user; each failed before): a save
# made while the scene (re)loads is not lost (the watches were re-armed after each load, and the
# events queued meanwhile were dropped: the image stayed one save behind); a scene that fails on
# a missing mesh renders once the mesh appears (it waited for another save of the scene); a scene
# reached through a symbolic link reloads when its target is saved (never); a save that changes
# nothing while a render runs lets the render go on (it restarted from its first sample, so an
# autosave kept it from finishing); a stop right after a change's preview says the EXR holds
# that preview (it said "the finished image"). Each ends with the watch output equal to a fresh
# render of the files as they are.
#   watch_editors.sh SPANGLE
set -u
S=$1
T=$(mktemp -d)
PID=
trap '[ -n "$PID" ] && kill -9 $PID 2>/dev/null; rm -rf "$T"' EXIT
cd "$T" || exit 1
fail() { echo "FAIL: $*"; echo "--- log"; cat log.txt 2>/dev/null; exit 1; }
cat > quad.obj <<'EOF'
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3 4/4
EOF
# A large texture: converting it on the first load takes a while (the window for a save).
oiiotool --pattern noise:type=uniform:min=0.2:max=0.8 2048x2048 3 -d uint8 -o big.png
scene() {  # scene COLOUR SIZE SPP
    cat <<EOT
[render]
width = ${2:-48}
height = ${2:-48}
spp = ${3:-4}
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = 45
[environment]
color = [1, 1, 1]
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
start() {  # start SCENE [ARGS]: a watch session writing out.exr, its log in log.txt
    local sc=$1
    shift
    # Emptied here, before the session starts: its own redirection empties it only once it runs,
    # and `finished` read the last part's log meanwhile (part 3 then saved its scene before the
    # first load, and waited for a second render that had nothing to render).
    : > log.txt
    "$S" render "$sc" -o out.exr --watch --threads 1 --texture-cache "$T/cache" "$@" > log.txt 2>&1 &
    PID=$!
}
finished() {  # finished N: waits for the Nth finished render
    for _ in $(seq 1 300); do
        [ "$(grep -c 'watching for changes' log.txt)" -ge "$1" ] && return 0
        sleep 0.1
    done
    fail "render $1 did not finish"
}
stop() {
    kill -INT "$PID"
    wait "$PID"
    PID=
}
fresh() {  # fresh SCENE: the watch output equals a one-shot render of the files as they are now
    "$S" render "$1" -o ref.exr -q --threads 1 --texture-cache "$T/cache" || fail "fresh render of $1"
    idiff -fail 0 -warn 0 out.exr ref.exr > /dev/null || fail "$2: the watch output is stale"
}

# 1. A save while the first load converts the texture.
scene '{ texture = "big.png" }' > s1.toml
start s1.toml
sleep 0.15
scene '{ texture = "big.png", scale = 0.5 }' > s1.toml
sleep 4
finished 1
sleep 1
stop
fresh s1.toml "a save during the first load"

# 2. A scene saved before the mesh it names: rendered when the mesh appears.
scene 0.5 > s2.toml
start s2.toml
finished 1
sed -e 's/quad.obj/later.obj/' -e 's/albedo = 0.5/albedo = 0.25/' s2.toml > s2.tmp && mv s2.tmp s2.toml
for _ in $(seq 1 50); do grep -q "later.obj' not found" log.txt && break; sleep 0.1; done
grep -q "later.obj' not found" log.txt || fail "the missing mesh was not reported"
cp quad.obj later.obj
finished 2
stop
fresh s2.toml "a mesh that appeared after the scene named it"

# 3. A scene reached through a link: saving the target reloads.
mkdir -p shots
scene 0.5 > shots/v1.toml
ln -s shots/v1.toml s3.toml
cp quad.obj shots/
start s3.toml
finished 1
scene 0.75 > shots/v1.toml.tmp && mv shots/v1.toml.tmp shots/v1.toml
finished 2
stop
fresh s3.toml "a save of a linked scene's target"

# 4. A save that changes nothing during a long render: the render goes on and finishes.
scene 0.5 256 128 > s4.toml
start s4.toml --no-pass-output
sleep 0.8  # loaded (3 ms) and rendering (about 3 s)
touch s4.toml
for _ in $(seq 1 50); do grep -q "its render goes on" log.txt && break; sleep 0.1; done
grep -q "its render goes on" log.txt || fail "a save that changed nothing was not let be"
grep -q "first pass\|preview" log.txt && fail "--no-pass-output wrote passes"
finished 1
[ "$(grep -c '^reload' log.txt)" -eq 1 ] || fail "the render was reloaded"
stop
fresh s4.toml "a render that a touch left alone"

# 5. The same for the files the scene reads: a mesh touched, and saved again with its own bytes
# (a bad save put back), during a long render (each restarted it from its first sample). Twice
# times part 4's samples: the render outlasts both saves.
scene 0.5 256 256 > s5.toml
start s5.toml --no-pass-output
sleep 0.8
touch quad.obj
for _ in $(seq 1 50); do grep -q "its render goes on" log.txt && break; sleep 0.1; done
grep -q "reload (quad.obj): the same bytes as the render read them: its render goes on" log.txt ||
    fail "a touched mesh was not let be"
cp quad.obj quad.keep && cp quad.keep quad.obj
finished 1
[ "$(grep -c '^loaded' log.txt)" -eq 1 ] && ! grep -q "changed:" log.txt ||
    fail "a mesh of the same bytes reloaded the render"
stop
fresh s5.toml "a render that a touched mesh left alone"

# 6. The output's folder removed while it renders: the finished image is not claimed written,
# nor at the stop; a save once the folder is back renders and writes it.
mkdir -p od
: > log.txt
"$S" render s4.toml -o od/out.exr --watch --threads 1 --texture-cache "$T/cache" > log.txt 2>&1 &
PID=$!
sleep 0.5
# (A pass image written while rm reads the folder can keep it: removed until it is gone.)
for _ in $(seq 1 50); do rm -rf od 2> /dev/null; [ -e od ] || break; done
finished 1
grep -q "could not write od/out.exr" log.txt || fail "the unwritten image was not said"
grep -q "^wrote od/out.exr" log.txt && fail "an image not written was claimed written"
mkdir od
touch s4.toml
finished 2
grep -q "^wrote od/out.exr (128 spp)" log.txt || fail "a save did not render the unwritten image again"
[ -e od/out.exr ] || fail "no image once the folder was back"
stop
echo PASS
