#!/usr/bin/env bash
# Install bayesmodal with its test extras and run the tests.  Without arguments: the
# default suite (every test not marked slow, under 15 minutes on a 2-core machine); with
# arguments: pytest with those (e.g. -m slow for the long statistical and fault tests).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh
ensure_venv "[test]"
if [ $# -eq 0 ]; then
    set -- -m "not slow"
fi
"$VENV/bin/python" -m pytest -q "$@"
