#!/usr/bin/env bash
# Install bayesmodal with its test extras and run the tests.  Without arguments: the
# default suite (every test not marked slow, one worker per core, under 15 minutes on a
# 2-core machine); with arguments: pytest with those (e.g. -m slow for the long
# statistical and fault tests).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh
ensure_venv "[test]"
if [ $# -eq 0 ]; then
    # one pytest worker per core (pytest-xdist), each test file on one worker so that its
    # module fixtures are built once; BAYESMODAL_TEST_WORKERS=0 runs in this process),
    # the files in the order tests/conftest.py gives them (the longest first, not
    # pytest-xdist's most-tests-first); the ten slowest tests are listed at the end, so
    # every run shows where the time goes
    set -- -m "not slow" -n "${BAYESMODAL_TEST_WORKERS:-auto}" --dist loadfile \
        --no-loadscope-reorder --durations=10
fi
"$VENV/bin/python" -m pytest -q "$@"
