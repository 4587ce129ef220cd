#!/usr/bin/env bash
# Installs what the tests need and runs the whole suite (CPU Taichi; GUI tests under Xvfb), one
# test file per CPU core at a time.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export QT_QPA_PLATFORM=${QT_QPA_PLATFORM:-xcb}
# one worker per CPU core (pytest-xdist), each running whole test files, so that module fixtures
# (the benchmark run, the Ray cluster, the coarse aluminium-bar run) are built once;
# RUNOUT_TEST_WORKERS=0 runs everything in this one process
exec .venv/bin/python -m pytest -q -p no:cacheprovider -n "${RUNOUT_TEST_WORKERS:-logical}" --dist loadfile "$@"
