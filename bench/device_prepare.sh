#!/usr/bin/env bash
# Packs .device/ for one call on a lent GPU machine (bench/device_run.sh; README, "Benchmarks on a lent GPU").
# That machine is bare and offline: its Python (3.12, with numpy and threadpoolctl) lacks the render
# path's wgpu, cffi, pycparser and zstandard, it may lack the Vulkan loader, and it has no baked atlas.
# So they travel: the wheels at this project's pins (constraints.txt), Debian's loader packages
# (unpacked there into /, as the device notes advise), and the atlas's files as plain files.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-python3}
DEVICE_PYTHON=${DEVICE_PYTHON:-3.12}

rm -rf .device
mkdir -p .device/whl .device/gl .device/atlas

# --no-deps: every wheel the render path imports is named (wgpu's rendercanvas is only for windows).
pins=$(grep -E '^(wgpu|cffi|pycparser|zstandard)==' constraints.txt)
platforms=()
for p in manylinux_2_28_x86_64 manylinux_2_27_x86_64 manylinux_2_17_x86_64 manylinux2014_x86_64; do
    platforms+=(--platform "$p")
done
# shellcheck disable=SC2086
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version "$DEVICE_PYTHON" --implementation cp \
    "${platforms[@]}" -d .device/whl $pins

# amd64 package lists of their own, so that this works whatever this machine's architecture.
apt=(-oAPT::Sandbox::User=root -oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/atlasgen-amd64-lists)
mkdir -p /tmp/atlasgen-amd64-lists/partial
apt-get "${apt[@]}" update -qq
(cd .device/gl && apt-get "${apt[@]}" download -qq libvulkan1 libegl1 libglvnd0)

# Plain copies: build/atlas.* are links into the generation store, and a link travels only as a link.
for f in dds json wgsl separable.bin; do
    if [ -e "build/atlas.$f" ]; then cp -L "build/atlas.$f" .device/atlas/; fi
done
test -s .device/atlas/atlas.dds || { echo "device-prepare: build/atlas.dds is missing (make atlas)" >&2; exit 1; }
du -sh .device
