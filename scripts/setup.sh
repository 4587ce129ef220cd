#!/usr/bin/env bash
# Installs what Runout needs on a fresh Debian machine with Python 3.11: the system libraries that
# VTK, gmsh and Qt load (and Xvfb for the GUI tests), then a virtual environment in .venv with
# Runout and its test tools. Safe to run again: it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

DEB_PACKAGES=(
  xvfb xauth                                   # virtual display for the GUI tests and screenshots
  libgl1 libegl1 libglu1-mesa libosmesa6        # OpenGL for VTK offscreen rendering, gmsh
  libxrender1 libxcursor1 libxft2 libxinerama1 libxi6 libxrandr2 libxfixes3 libsm6 libice6  # gmsh, VTK
  libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-shape0
  libxcb-randr0 libxcb-render-util0 libxcb-image0 libxcb-xinerama0 libxcb-xkb1 libdbus-1-3
  libfontconfig1 libfreetype6 libglib2.0-0      # Qt's xcb platform plugin
  libgomp1                                     # gmsh (OpenMP)
)

missing=()
for pkg in "${DEB_PACKAGES[@]}"; do
  dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
done
if ((${#missing[@]})); then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
# Runout from this checkout, as a path entry (setuptools' "compat" editable mode): the default
# editable mode imports a module finder at every interpreter start, 15-50 ms of every run's
# start-up (docs/performance.md); the plain editable install where a setuptools has no compat mode
.venv/bin/python -m pip install -q -e ".[test]" --config-settings editable_mode=compat 2>/dev/null \
  || .venv/bin/python -m pip install -q -e ".[test]"
