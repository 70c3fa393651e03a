#!/usr/bin/env bash
# Install bayesmodal and run the main job on the default input.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install -q -e . 2>&1 | grep -v "Running pip as the 'root' user" || true
bayesmodal report --out out/report "$@"
