#!/usr/bin/env bash
# A file a scene names that is there but cannot be read (its permissions) is an error at the key
# that names it, saying why. Found by a user: an unreadable [[import]] was read as an empty file,
# so its objects were left out of a render that exited 0 without a word; an unreadable scene
# file was "missing required key 'camera'"; an unreadable mesh "cannot open mesh".
# Root reads every file whatever its permissions: run as root, spangle runs as nobody (setpriv);
# skipped (77) where that cannot be done.
#   unreadable_inputs.sh SPANGLE REPO
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'chmod -R u+rwX "$T"; rm -rf "$T"' EXIT
chmod 755 "$T"
run=()
if [ "$(id -u)" = 0 ]; then
    command -v setpriv > /dev/null || { echo "no setpriv to run as another user: skipped"; exit 77; }
    run=(setpriv --reuid=65534 --regid=65534 --clear-groups)
fi
"${run[@]}" "$S" --version > /dev/null 2>&1 || { echo "spangle cannot run as nobody here: skipped"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }
# expect PATTERN ARGS...: spangle ARGS exits 1 and says PATTERN.
expect() {
    local pattern=$1
    shift
    "${run[@]}" "$S" "$@" > "$T/out.txt" 2> "$T/err.txt"
    local got=$?
    [ "$got" = 1 ] || fail "spangle $*: exit $got, expected 1; stderr: $(cat "$T/err.txt")"
    grep -q -- "$pattern" "$T/err.txt" || fail "spangle $*: stderr lacks '$pattern': $(cat "$T/err.txt")"
}
cd "$T"
mkdir out && chmod 777 out
cp "$REPO/assets/meshes/sphere.obj" sphere.obj
cat > top.toml <<'SCENE'
[render]
width = 8
height = 8
spp = 1
[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
[environment]
color = [0.5, 0.5, 0.5]

[[import]]
file = "objs.toml"
SCENE
cat > objs.toml <<'SCENE'
[[material]]
name = "m"
plugin = "smooth"
model = "diffuse"
[[object]]
mesh = "sphere.obj"
material = "m"
SCENE
chmod 644 top.toml objs.toml sphere.obj
# Readable, it renders (so what fails below is the permissions alone).
"${run[@]}" "$S" render top.toml -o out/ok.exr -q --no-preview > /dev/null 2> "$T/err.txt" ||
    fail "the readable scene does not render as this user: $(cat "$T/err.txt")"
chmod 000 objs.toml
expect "top.toml:12:8: error: file 'objs.toml' cannot be read: Permission denied" \
    render top.toml -o out/a.exr -q --no-preview
[ ! -e out/a.exr ] || fail "an image was written"
expect "top.toml:12:8: error: file 'objs.toml' cannot be read: Permission denied" \
    convert top.toml -o out/conv.toml
chmod 644 objs.toml
chmod 000 sphere.obj
expect "objs.toml:6:8: error: mesh file 'sphere.obj' cannot be read: Permission denied" \
    render top.toml -o out/b.exr -q --no-preview
chmod 644 sphere.obj
chmod 000 top.toml
expect "scene file 'top.toml' cannot be read: Permission denied" \
    render top.toml -o out/c.exr -q --no-preview
echo "unreadable inputs: all refused at their keys"
