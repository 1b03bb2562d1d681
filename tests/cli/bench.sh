#!/usr/bin/env bash
# `spangle bench`: every scene renders in its own process and reports finite, positive rates;
# the generated interior scene is complete (30 object meshes, a room, 14 materials, > 300k
# triangles); a render of a small scene stays far below the ~135 MiB that linking OpenImageIO
# into the process used to cost before anything was loaded (it is opened only for non-EXR images).
#   bench.sh SPANGLE
set -u
S=$1
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/out.txt" "$T/b.csv" 2>/dev/null; exit 1; }

"$S" bench demo interior --size 48x27 --spp 2 --threads 2 --work-dir "$T/work" --csv "$T/b.csv" > "$T/out.txt" 2>&1 ||
    fail "bench failed"
[ "$(ls "$T/work/interior"/object_*.ply | wc -l)" -eq 30 ] || fail "the interior does not have 30 object meshes"
[ -s "$T/work/interior/walls.ply" ] && [ -s "$T/work/interior/floor.ply" ] || fail "no room meshes"
[ "$(grep -c '^\[\[material\]\]' "$T/work/interior/interior.toml")" -eq 14 ] || fail "not 14 materials"
[ "$(wc -l < "$T/b.csv")" -eq 3 ] || fail "expected a header and two rows"
# Columns: scene,width,height,spp,threads,triangles,geometry_s,bvh_s,other_s,render_s,msamples_per_s,
# mrays_per_s,camera_rays,bounce_rays,shadow_rays,peak_mib,mesh_mib,bvh_mib,rest_mib
awk -F, 'NR > 1 {
    if ($2 != 48 || $3 != 27 || $4 != 2) { print "wrong size or spp: " $0; bad = 1 }
    for (i = 10; i <= 16; ++i) if (!($i > 0)) { print "column " i " not positive: " $0; bad = 1 }
    if ($13 != 48 * 27 * 2) { print "camera rays are not one per sample: " $0; bad = 1 }
    if (!($5 >= 1 && $5 <= 2)) { print "threads column is not the 2 asked for (1 on one core): " $0; bad = 1 }
    if ($1 == "interior" && $6 < 300000) { print "interior has too few triangles: " $0; bad = 1 }
    if ($1 == "demo" && $16 >= 100) { print "demo peak memory is " $16 " MiB: is OpenImageIO linked again?"; bad = 1 }
} END { exit bad }' "$T/b.csv" || fail "bad figures"

# The scene's own size ('scene'; the help offered '', which every option refuses), and the
# threads a default run used (the CSV said 0).
"$S" bench demo --size scene --spp 1 --work-dir "$T/work" --csv "$T/c.csv" > "$T/out.txt" 2>&1 ||
    fail "bench --size scene failed"
W=$(sed -n 's/^width = \([0-9]*\).*/\1/p' "$(dirname "$0")/../../assets/scenes/demo.toml" | head -1)
awk -F, -v w="$W" 'NR == 2 { if ($2 != w || !($5 > 0)) { print "size or threads: " $0; exit 1 } }' "$T/c.csv" ||
    fail "bench --size scene did not render the scene's width $W"
"$S" bench no_such_scene > "$T/out.txt" 2>&1; [ $? -eq 2 ] || fail "an unknown scene name is not a usage error"
grep -q "neither a scene file nor a shipped scene" "$T/out.txt" || fail "no message for an unknown scene"
echo OK
