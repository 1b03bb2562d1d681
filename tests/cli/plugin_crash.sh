#!/usr/bin/env bash
# A material plugin that crashes (SIGSEGV in eval()) killed spangle with no word: exit 139 and an
# empty stderr, whichever of several plugins it was. Now the last line names the kernel, the
# plugin, its file and the material, and the exit is still the signal's. An entry point that
# throws no longer hides every other plugin from `spangle plugins`.
#   plugin_crash.sh SPANGLE TEST_PLUGIN_DIR MESH
set -u
S=$1 PLUGINS=$2 MESH=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cat > "$T/crash.toml" <<TOML
[render]
width = 8
height = 8
spp = 1

[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]

[[light]]
type = "distant"
direction = [0, 0, -1]
intensity = 1

[[material]]
name = "crasher"
plugin = "kernels"
params = { x = 0.9 }

[[object]]
mesh = "$MESH"
material = "crasher"
TOML
"$S" render "$T/crash.toml" --plugin-path "$PLUGINS" -o "$T/crash.exr" --threads 1 -q \
    > "$T/out.txt" 2> "$T/err.txt"
status=$?
[ "$status" = 139 ] || fail "exit $status, expected 139 (SIGSEGV); stderr: $(cat "$T/err.txt")"
grep -q "fatal: SIGSEGV (invalid memory access) in eval() of plugin 'kernels' ($PLUGINS/libspangle_kernels.so), material 'crasher'" \
    "$T/err.txt" || fail "stderr does not name the crash: $(cat "$T/err.txt")"
[ -e "$T/crash.exr" ] && fail "an image was written"
ls "$T" | grep -q '\.tmp' && fail "a temporary file was left: $(ls "$T")"
# `spangle plugins` lists every plugin, the one whose entry point throws as not usable.
"$S" plugins --plugin-path "$PLUGINS" > "$T/list.txt" 2>&1
grep -q "libspangle_throwentry.so: not usable: .*its entry point threw" "$T/list.txt" ||
    fail "the throwing entry point is not reported: $(cat "$T/list.txt")"
grep -q "^kernels (" "$T/list.txt" || fail "the other plugins are not listed: $(cat "$T/list.txt")"
echo "ok"
