#!/usr/bin/env bash
# Sets up a fresh machine for tsrl: Debian packages for off-screen rendering, a virtual environment
# in .venv, the CPU build of torch 2.13.0 first (so nothing pulls CUDA wheels), then tsrl itself.
# Usage: bash scripts/setup.sh [EXTRAS]   (default extras: dev)
set -euo pipefail
cd "$(dirname "$0")/.."
extras=${1:-dev}

# Off-screen OpenGL: EGL (mesa, software rendering works without a GPU) and OSMesa as the fallback.
missing=()
for pkg in libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
    sudo=""; [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "setup: installing Debian packages: ${missing[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

python=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$python" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q torch==2.13.0
.venv/bin/python -m pip install -q -e ".[$extras]"

# Pick the off-screen GL backend that works here; the Makefile reads it.
for backend in egl osmesa; do
    if MUJOCO_GL=$backend .venv/bin/python -c \
        "import mujoco; c = mujoco.GLContext(8, 8); c.make_current(); c.free()" >/dev/null 2>&1; then
        echo "$backend" > .venv/mujoco_gl
        echo "setup: off-screen rendering with MUJOCO_GL=$backend"
        break
    fi
done
