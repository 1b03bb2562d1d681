#!/usr/bin/env bash
# Installs Spangle's build dependencies from Debian 12's packages (run as root; zlib1g-dev inflates
# gzip'd pbrt scenes); with --tests,
# also what only the tests need (headless Chromium and its WebDriver for the live preview page;
# clang and its libFuzzer runtime for the fuzz targets; gltfpack and draco's tools, which compress
# the glTF test files). libtinygltf-dev (2.7.0) reads glTF scenes, libdraco-dev and
# libmeshoptimizer-dev decode their compressed geometry;
# python3-pip fetches Open Image Denoise's libraries (below); pybind11-dev, python3-dev and
# python3-numpy build the Python module (python/), python3-pytest tests it; python3-venv makes
# the environment of the Blender tests (below).
# The list and the CMake traps behind it are in ../shared/NOTES-deps.md and cmake/SpangleDeps.cmake.
set -euo pipefail
packages=(
    cmake ninja-build g++ pkg-config
    libembree-dev libosd-dev libopencolorio-dev libopenimageio-dev libfmt-dev libopenexr-dev libpng-dev
    zlib1g-dev libtbb-dev libtomlplusplus-dev libcli11-dev libtinyobjloader-dev libtinygltf-dev libgtest-dev libbenchmark-dev
    libdraco-dev libmeshoptimizer-dev
    openimageio-tools opencolorio-tools clang-format python3-pip
    pybind11-dev python3-dev python3-numpy
    libopenmpi-dev openmpi-bin
)
if [ "${1:-}" = "--tests" ]; then
    packages+=(chromium chromium-driver curl clang libclang-rt-14-dev python3-pytest python3-venv
        gltfpack draco)
fi
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
# Intel Open Image Denoise 2 (spangle render --denoise; optional): Debian 12 does not package it,
# and the pyoidn wheel on PyPI carries its shared libraries (the CPU device and the oneTBB it was
# built with). Only those are unpacked, into /opt/spangle/oidn/lib, where Spangle looks for the
# library (docs/denoise.md). Without network access the rest still builds and runs.
oidn_wheel=pyoidn==2.5.1.0
oidn_lib=/opt/spangle/oidn/lib
if [ ! -f "$oidn_lib/libOpenImageDenoise.so.2" ]; then
    tmp=$(mktemp -d)
    if python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux2014_x86_64 \
            -d "$tmp" "$oidn_wheel"; then
        python3 - "$tmp" "$oidn_lib" <<'PY'
import glob, os, sys, zipfile
wheel = glob.glob(os.path.join(sys.argv[1], "pyoidn-*.whl"))[0]
dest = sys.argv[2]
keep = {"libOpenImageDenoise.so.2", "libOpenImageDenoise_core.so.2.5.1",
        "libOpenImageDenoise_device_cpu.so.2.5.1", "libtbb.so.12"}
os.makedirs(dest, exist_ok=True)
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        base = name.rsplit("/", 1)[-1]
        if name.startswith("pyoidn/oidn/lib/") and base in keep:
            with z.open(name) as src, open(os.path.join(dest, base), "wb") as out:
                out.write(src.read())
            os.chmod(os.path.join(dest, base), 0o755)
PY
    else
        echo "install-deps: pyoidn could not be downloaded: spangle render --denoise will say so" >&2
    fi
    rm -rf "$tmp"
fi

# Blender as a Python module (PyPI's bpy, 4.2 LTS, for Debian's Python 3.11) for the headless
# tests of the Blender add-on (tests/blender): a virtual environment at /opt/spangle/bpy that also
# sees Debian's packages (numpy, pytest). Only with --tests; without network access it warns, and
# the add-on's test is skipped (or fails where SPANGLE_REQUIRE_BLENDER=1, as in .ci/run).
bpy_env=/opt/spangle/bpy
if [ "${1:-}" = "--tests" ] && ! "$bpy_env/bin/python" -c "import bpy" >/dev/null 2>&1; then
    if /usr/bin/python3 -m venv --system-site-packages "$bpy_env" &&
            "$bpy_env/bin/pip" install -q "bpy==4.2.23"; then
        :
    else
        echo "install-deps: bpy could not be installed: the Blender add-on's test will be skipped" >&2
    fi
fi
