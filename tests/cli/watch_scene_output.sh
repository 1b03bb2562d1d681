#!/usr/bin/env bash
# `--watch` writes the image the scene asks for ([render] output), as a one-shot render does (it
# wrote <scene name>.exr and said nothing: found by a user); -o still wins over it, and without
# either the image is <scene name>.exr.
#   watch_scene_output.sh SPANGLE PLUGIN_DIR
set -u
S=$1 PLUGINS=$2
T=$(mktemp -d)
PID=
trap '[ -n "$PID" ] && kill -9 $PID 2>/dev/null; rm -rf "$T"' EXIT
cd "$T" || exit 1
fail() { echo "FAIL: $*"; echo "--- log"; cat log.txt 2>/dev/null; exit 1; }
cat > quad.obj <<'EOT'
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
f 1 2 3 4
EOT
cat > scene.toml <<'EOT'
[render]
width = 16
height = 12
spp = 2
output = "named.exr"
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
params = { albedo = 0.5 }
[[object]]
mesh = "quad.obj"
material = "m"
EOT
# watch NAME ARGS...: runs --watch until its first render is done, then stops it with SIGINT.
watch() {
    local name=$1
    shift
    "$S" render scene.toml --watch --plugin-path "$PLUGINS" --no-preview "$@" > log.txt 2>&1 &
    PID=$!
    for _ in $(seq 1 300); do
        grep -q "watching for changes" log.txt && break
        sleep 0.1
    done
    grep -q "watching for changes" log.txt || fail "$name: the first render did not finish"
    kill -INT $PID
    wait $PID
    PID=
}
watch scene
[ -s named.exr ] || fail "--watch did not write the image the scene asks for"
[ -e scene.exr ] && fail "--watch wrote <scene name>.exr instead of the scene's own output"
grep -q "the scene asks for 'named.exr': writing named.exr" log.txt || fail "no line says where"
grep -q "named.exr holds" log.txt || fail "the stop line names another file"
rm -f named.exr
watch option -o given.exr
[ -s given.exr ] || fail "-o given.exr was not written"
[ -e named.exr ] && fail "the scene's output was written although -o was given"
sed -i '/^output = /d' scene.toml
watch default
[ -s scene.exr ] || fail "without -o or a scene output, <scene name>.exr was not written"
echo "ok"
