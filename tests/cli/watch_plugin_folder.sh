#!/usr/bin/env bash
# Watch mode and the plugin folders: a developer's --plugin-path library removed (the copy beside
# the binary is then opened) is said, and putting it back (or rebuilding it there) reloads it; it
# was ignored for the rest of the session, every rebuild of it with it.
#   watch_plugin_folder.sh SPANGLE BUILD_DIR REPO
set -u
S=$(realpath "$1") BUILD=$(realpath "$2") REPO=$(realpath "$3")
T=$(mktemp -d)
pid=
trap '[ -n "$pid" ] && kill -9 "$pid" 2> /dev/null; rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/log" 2> /dev/null; exit 1; }
mkdir -p "$T/bin/plugins" "$T/dev"
cp "$S" "$BUILD/libspangle_oiio.so" "$T/bin/"
[ -d "$BUILD/ocio" ] && cp -r "$BUILD/ocio" "$T/bin/"
cp "$BUILD/plugins/libspangle_flake.so" "$BUILD/plugins/libspangle_smooth.so" "$T/bin/plugins/"
cp "$BUILD/plugins/libspangle_flake.so" "$T/dev/"
cat > "$T/s.toml" <<TOML
[render]
width = 24
height = 16
spp = 4
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
[environment]
color = [0.5, 0.5, 0.5]
[[material]]
name = "paint"
plugin = "flake"
[[object]]
mesh = "$REPO/assets/meshes/sphere.obj"
material = "paint"
TOML
cd "$T" || fail "no temp folder"
"$T/bin/spangle" render s.toml -o s.exr --watch -q --no-preview --plugin-path "$T/dev" > log 2>&1 &
pid=$!
wait_for() {  # wait_for PATTERN COUNT: until the log holds COUNT lines matching PATTERN
    for _ in $(seq 1 200); do
        [ "$(grep -c -- "$1" log)" -ge "$2" ] && return 0
        sleep 0.1
    done
    fail "no '$1' ($2) in the log"
}
wait_for "loaded s.toml" 1
rm "$T/dev/libspangle_flake.so"
wait_for "is gone; opened $T/bin/plugins/libspangle_flake.so instead" 1
wait_for "^reload" 1
cp "$BUILD/plugins/libspangle_flake.so" "$T/dev/"
wait_for "new plugin file $T/dev/libspangle_flake.so" 1
# A rebuild in the developer's folder is the plugin in use again: it reloads.
printf '\0' >> "$T/dev/libspangle_flake.so"
wait_for "changed: plugin file $T/dev/libspangle_flake.so" 1
kill -INT "$pid"
wait "$pid"
pid=
echo "watch_plugin_folder: OK"
