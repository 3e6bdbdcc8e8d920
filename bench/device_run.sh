#!/usr/bin/env bash
# Runs on a lent GPU machine, in one call, what `make bench` cannot measure here: the render section on a
# real GPU (issue 22's lighting-pass figure). Prepared by `make device-prepare`; the call is
#
#     run(command="bash bench/device_run.sh", carry=[".device"], timeout_s=300)
#
# and the data comes back as render-gpu.json, for `bench/run.py --import render_gpu FILE`.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$PATH:/usr/sbin:/sbin"
# The Vulkan loader, where the image has none (the device notes' way: the packages unpacked into /).
# (grep reads it all: with -q, ldconfig could die of SIGPIPE and pipefail would call the loader missing.)
if ! ldconfig -p | grep 'libvulkan\.so\.1 ' >/dev/null; then
    for f in .device/gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/atlasgen-site \
    .device/whl/*.whl
export PYTHONPATH="/tmp/atlasgen-site:$PWD" PYTHONUNBUFFERED=1 XDG_RUNTIME_DIR=/tmp/atlasgen-xdg
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
# The NVIDIA driver's ICD where the image keeps it apart from the loader's search path.
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -e "$icd" ]; then export VK_DRIVER_FILES="$icd"; fi
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
mkdir -p build
cp .device/atlas/* build/
python3 bench/run.py --save "${OUT:-build}/render-gpu.json" render
