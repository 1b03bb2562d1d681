#!/usr/bin/env bash
# Installs Spangle's build dependencies from Debian 12's packages (run as root; zlib1g-dev inflates
# gzip'd pbrt scenes); with --tests,
# also what only the tests need (headless Chromium and its WebDriver for the live preview page;
# clang and its libFuzzer runtime for the fuzz targets). libtinygltf-dev (2.7.0) reads glTF scenes.
# The list and the CMake traps behind it are in ../shared/NOTES-deps.md and cmake/SpangleDeps.cmake.
set -euo pipefail
packages=(
    cmake ninja-build g++ pkg-config
    libembree-dev libosd-dev libopencolorio-dev libopenimageio-dev libfmt-dev libopenexr-dev libpng-dev
    zlib1g-dev libtbb-dev libtomlplusplus-dev libcli11-dev libtinyobjloader-dev libtinygltf-dev libcpp-httplib-dev libgtest-dev libbenchmark-dev
    openimageio-tools opencolorio-tools clang-format
    libopenmpi-dev openmpi-bin
)
if [ "${1:-}" = "--tests" ]; then
    packages+=(chromium chromium-driver curl clang libclang-rt-14-dev)
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
