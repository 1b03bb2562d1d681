#!/usr/bin/env bash
# End to end: `spangle render --watch` on a temporary copy of a scene. Edits, in turn, a material
# parameter, a transform, the mesh file, the camera; saves a syntax error, then fixes it in a save
# that also moves the camera (compared with the last good scene: only the camera changed); saves
# another error and fixes it back (nothing changed: the image is kept, nothing renders); "rebuilds"
# the plugin (a new file over the old one). After each, checks the reload line (what changed and
# which systems ran) and whether the output EXR changed, stayed, or recovered. The scene has an
# unused material: its warning is said once, not at every reload. SIGINT ends with one line
# saying what the EXR holds. A mesh given as the scene ends the command at once.
#   watch_session.sh SPANGLE PLUGIN_DIR SCENE_DIR
set -u
S=$1 PLUGINS=$2 SCENES=$3
T=$(mktemp -d)
trap 'kill -9 $PID 2>/dev/null; rm -rf "$T"' EXIT
cp "$SCENES/flake_uvless.toml" "$T/scene.toml"
cp "$SCENES/uvless_ball.obj" "$T/"
mkdir "$T/plugins"
cp "$PLUGINS/libspangle_flake.so" "$T/plugins/"
cd "$T"
sed -i 's/^spp = 16/spp = 4/' scene.toml
printf '\n[[material]]\nname = "spare"\nplugin = "smooth"\nmodel = "diffuse"\nparams = { albedo = 0.5 }\n' >> scene.toml

fail() { echo "FAIL: $*"; echo "--- log"; cat log.txt; exit 1; }
LINES=0
# Waits until the log has a new line matching $1; sets NEW to it. The next wait reads from the
# line after it (not from the log's end: a line printed in the same tenth of a second as the one
# matched was skipped, and the reload after a "render goes on" line was never seen).
await() {
    local hit
    for _ in $(seq 1 300); do
        hit=$(tail -n +$((LINES + 1)) log.txt | grep -n -m1 -E "$1" || true)
        if [ -n "$hit" ]; then
            LINES=$((LINES + ${hit%%:*}))
            NEW=${hit#*:}
            return 0
        fi
        sleep 0.1
    done
    fail "no line matching '$1'"
}
finished() {  # waits for the render of the current scene to finish
    for _ in $(seq 1 300); do
        [ "$(grep -c 'watching for changes' log.txt)" -ge "$1" ] && return 0
        sleep 0.1
    done
    fail "render $1 did not finish"
}
# Keeps a copy of the current output as $1; same A B: their pixels are identical.
keep() { cp out.exr "$1.exr"; }
same() { oiiotool "$1.exr" "$2.exr" --diff --fail 0 --failpercent 0 --warn 0 > /dev/null 2>&1; }
# reloaded WHAT LINE N BEFORE AFTER: the next reload line contains LINE (a regex), render N
# finishes, its image is kept as AFTER and differs from BEFORE.
reloaded() {
    await "^reload"
    # A save seen twice (its event and the identity poll) may first be read while the render of
    # its own content runs: "the same as the scene being rendered" is not the reload awaited.
    while echo "$NEW" | grep -q "its render goes on$"; do await "^reload"; done
    echo "$NEW" | grep -q "$2" || fail "$1: $NEW"
    finished "$3"
    keep "$5"; ! same "$4" "$5" || fail "$1 edit did not change the image"
}

# A mesh named as the scene can never become one by a save: --watch says so and exits 1 (it
# waited for a good save).
timeout 20 "$S" render uvless_ball.obj -o mesh.exr --watch > mesh_log.txt 2>&1
RC=$?
[ "$RC" = 1 ] || fail "--watch on a mesh: exit $RC, expected 1: $(cat mesh_log.txt)"
grep -q "this is a mesh (obj), not a scene" mesh_log.txt || fail "--watch on a mesh: $(cat mesh_log.txt)"

"$S" render scene.toml -o out.exr --watch --plugin-path "$T/plugins" > log.txt 2>&1 &
PID=$!
await "^loaded scene.toml"
finished 1
keep A

sed -i 's/gamma = 3/gamma = 4/' scene.toml
reloaded material "changed: Material; ran: materials; rebuilt: material 'glitter'" 2 A B

sed -i 's/rotate = \[30, 20, 0\]/rotate = [30, 50, 0]/' scene.toml
reloaded transform "changed: Transform; ran: area_lights, accelerate, light_selection; rebuilt: top-level BVH; reused: 1 mesh BVHs" 3 B C

# The mesh, rewritten by "write a temporary file and rename it over": a smaller ball.
awk '/^v /{printf "v %g %g %g\n", $2*0.8, $3*0.8, $4*0.8; next} {print}' uvless_ball.obj > ball.tmp
mv ball.tmp uvless_ball.obj
reloaded mesh "changed: mesh file .*uvless_ball.obj; ran: mesh_load, area_lights, accelerate, light_selection; rebuilt: mesh .*uvless_ball.obj, 1 mesh BVH, top-level BVH" 4 C D

sed -i 's/fov = 32/fov = 28/' scene.toml
reloaded camera "changed: Camera; ran: nothing; rebuilt: nothing" 5 D E

echo "broken = = 1" >> scene.toml
await "reload failed"
grep -q "scene.toml:[0-9]*:[0-9]*: error" log.txt || fail "no file:line for the syntax error"
sleep 1
keep F; same E F || fail "a bad save changed the image on disk"

# The fix comes with another edit: compared with the last good scene, only the camera changed.
sed -i -e '$d' -e 's/fov = 28/fov = 30/' scene.toml
await "^reload"
echo "$NEW" | grep -q "changed: Camera; ran: nothing; rebuilt: nothing" || fail "fixed save: $NEW"
finished 6
keep G; ! same E G || fail "the fixed save's camera edit did not change the image"

# Broken again and fixed back: the same scene as the last good one, its image kept.
echo "broken = = 1" >> scene.toml
await "reload failed"
sed -i '$d' scene.toml
await "^reload"
echo "$NEW" | grep -q "changed: nothing; .*the same as the last good scene: its image is kept" ||
    fail "fixed back: $NEW"
# Only the scene is named (sed -i's temporary file, seen in the folder watched after the failed
# load, was: "reload (scene.toml, sedSIiHUg)").
echo "$NEW" | grep -q "^reload (scene.toml): " || fail "the reload line names another file: $NEW"
sleep 1
[ "$(grep -c 'watching for changes' log.txt)" -eq 6 ] || fail "the unchanged scene rendered again"
keep G2; same G G2 || fail "the image changed after a save that changed nothing"

# The mesh saved broken, then put back as it was (the same bytes, a new file): nothing changed
# (it was "changed: mesh file", and the scene rendered again).
cp uvless_ball.obj ball.bak
head -c 200 ball.bak > uvless_ball.obj
await "reload failed"
cp ball.bak uvless_ball.obj
await "^reload"
echo "$NEW" | grep -q "changed: nothing; .*the same as the last good scene: its image is kept" ||
    fail "mesh put back: $NEW"
sleep 1
[ "$(grep -c 'watching for changes' log.txt)" -eq 6 ] || fail "the mesh put back rendered again"
rm ball.bak

# A rebuilt plugin: a new file replaces the library (the same code, other bytes: a trailing one,
# which the dynamic loader ignores): it is reopened.
cp "$PLUGINS/libspangle_flake.so" plugins/new.so && printf '\0' >> plugins/new.so &&
    mv plugins/new.so plugins/libspangle_flake.so
await "^reload"
echo "$NEW" | grep -q "changed: plugin file .*libspangle_flake.so; ran: materials; rebuilt: material 'glitter'" || fail "plugin: $NEW"
finished 7
keep H; same G H || fail "the reopened plugin renders differently"

kill -INT $PID
wait $PID
RC=$?
[ $RC -eq 0 ] || fail "exit status $RC after SIGINT"
# The materials system ran at the first load, the material edit and the plugin: one warning.
[ "$(grep -c "material 'spare' is not used" log.txt)" -eq 1 ] || fail "the unused material's warning repeated"
grep -qx 'stopped by SIGINT: out.exr holds the finished image at 4 samples per pixel' log.txt ||
    fail "no line saying what SIGINT left"
ls -a | grep -q '\.tmp' && fail "temporary file left behind"
echo "watch session: all reloads as expected"
exit 0
