#!/usr/bin/env bash
# docs/plugins.md's minimal plugin, built from the page as a plugin author would (the header
# from engine/include, nothing else), is listed by `spangle plugins` and renders the image the
# shipped smooth/diffuse model renders (relMSE within noise): the page's code and claims stay true.
#   plugin_example.sh SPANGLE REPO CXX
set -u
S=$1 REPO=$2 CXX=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
python3 - "$REPO/docs/plugins.md" "$T/lambert.cpp" <<'PY' || fail "no C++ block in docs/plugins.md"
import re, sys
code = re.findall(r"```cpp\n(.*?)```", open(sys.argv[1]).read(), re.S)
open(sys.argv[2], "w").write(code[0])
PY
mkdir "$T/plugins"
"$CXX" -std=c++17 -O2 -fPIC -shared -fvisibility=hidden -Wall -Wextra -Werror \
    -I"$REPO/engine/include" -o "$T/plugins/libspangle_lambert.so" "$T/lambert.cpp" ||
    fail "the example does not build"
"$S" plugins --plugin-path "$T/plugins" > "$T/list.txt" 2>&1
grep -q "^lambert (" "$T/list.txt" || fail "not listed: $(cat "$T/list.txt")"
cat > "$T/lambert.toml" <<TOML
[render]
width = 32
height = 32
spp = 64

[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]

[environment]
color = [0.3, 0.3, 0.4]

[[light]]
type = "distant"
direction = [0.3, -0.5, -1]
intensity = 2

[[material]]
name = "clay"
plugin = "lambert"
params = { albedo = [0.6, 0.4, 0.3] }

[[object]]
mesh = "$REPO/tests/scenes/uvless_ball.obj"
material = "clay"
TOML
sed 's/plugin = "lambert"/plugin = "smooth"\nmodel = "diffuse"/' "$T/lambert.toml" > "$T/smooth.toml"
"$S" render "$T/lambert.toml" --plugin-path "$T/plugins" -o "$T/lambert.exr" -q --threads 2 \
    --no-preview || fail "the example does not render"
"$S" render "$T/smooth.toml" -o "$T/smooth.exr" -q --threads 2 --no-preview || fail "smooth"
rel=$("$S" inspect "$T/lambert.exr" --against "$T/smooth.exr" | sed -n 's/^relMSE against .*: //p')
python3 -c "import sys; sys.exit(0 if float('$rel') < 1e-3 else 1)" ||
    fail "relMSE against smooth/diffuse $rel"
echo "ok: relMSE $rel"
