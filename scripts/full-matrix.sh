#!/usr/bin/env bash
# Runs every case of the matrix tests (the contact, thrust, structure, scatter, water and
# softening matrices), of which the suite runs a covering sample; extra arguments go to pytest
# (a file, -k, ...). About 450 tests, most of them scenes compiled afresh: a study, not part of the suite.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNOUT_FULL_MATRIX=1 exec bash scripts/test.sh -m matrix "$@"
