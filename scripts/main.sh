#!/usr/bin/env bash
# Install bayesmodal and run the main job on the default input (the measured ECP 210
# records in ../shared/data or $BAYESMODAL_DATA):
#   1. reproduce the reference report's tables and plots  -> out/report/
#   2. sample the free-damping posterior of data_impulses -> runs/impulses_free/report.html
# A finished run is kept (--resume is a no-op then); delete the folder to sample again.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh
ensure_venv ""
bayesmodal report --out out/report "$@"
bayesmodal run runs/impulses_free.toml --resume
echo "open runs/impulses_free/report.html in a browser (e.g. xdg-open runs/impulses_free/report.html)"
