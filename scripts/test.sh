#!/usr/bin/env bash
# Install bayesmodal with its test extras and run the default test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install -q -e ".[test]" 2>&1 | grep -v "Running pip as the 'root' user" || true
python3 -m pytest -q "$@"
