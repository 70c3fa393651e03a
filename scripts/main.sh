#!/usr/bin/env bash
# Install bayesmodal (in .venv) and run the main job on the default input (the measured
# ECP 210 records in ../shared/data or $BAYESMODAL_DATA):
#   1. reproduce the reference report's tables and plots               -> out/report/
#   2. fit the four records together (shared masses, dampers and input offset, a drive
#      gain per record from its population) and check the intervals by leaving each
#      record out in turn                                                 -> runs/records_free/
# A finished run is kept (--resume is a no-op then); delete the folder to sample again.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/_venv.sh
ensure_venv ""
bayesmodal report --out out/report "$@"
bayesmodal run runs/records_free.toml --resume
echo "open runs/records_free/report.html in a browser (e.g. xdg-open runs/records_free/report.html)"
