#!/usr/bin/env bash
# Runs the Blender tests (test_blender_addon.py: the add-on; test_spangle_to_blender.py: the
# benchmark's importer of Spangle scenes) with a Python that has bpy:
# $SPANGLE_BLENDER_PYTHON, else /opt/spangle/bpy/bin/python (scripts/install-deps.sh --tests).
# Usage: run.sh BUILD_DIR. Exit 77 (skipped) without one, unless SPANGLE_REQUIRE_BLENDER=1.
set -u
build=$1
here=$(cd "$(dirname "$0")" && pwd)
py=${SPANGLE_BLENDER_PYTHON:-/opt/spangle/bpy/bin/python}
if ! "$py" -c "import bpy" >/dev/null 2>&1; then
    echo "no Python with bpy at $py (bash scripts/install-deps.sh --tests makes one)"
    [ "${SPANGLE_REQUIRE_BLENDER:-0}" = 1 ] && exit 1
    exit 77
fi
export PYTHONPATH="$build/python${PYTHONPATH:+:$PYTHONPATH}" SPANGLE_BUILD="$build"
exec "$py" -m pytest -q -p no:cacheprovider "$here"
