#!/usr/bin/env bash
# Installs what the tests need and runs the whole suite (CPU Taichi; GUI tests under Xvfb).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export QT_QPA_PLATFORM=${QT_QPA_PLATFORM:-xcb}
exec .venv/bin/python -m pytest -q -p no:cacheprovider "$@"
