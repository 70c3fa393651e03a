# Sourced by scripts/main.sh and scripts/test.sh: create (once) and use the project's own
# virtual environment, without the machine's site packages, so that every run sees what a
# new user gets.  BAYESMODAL_VENV names another folder (.ci/run uses a fresh one).
# Usage: ensure_venv EXTRAS   (e.g. "" or "[test]")
ensure_venv() {
    local extras="$1"
    VENV="${BAYESMODAL_VENV:-$PWD/.venv}"
    if [ ! -x "$VENV/bin/python" ]; then
        local py
        py="$(command -v python3.11 || command -v python3)"
        echo "creating the virtual environment $VENV (python: $py)"
        "$py" -m venv "$VENV"
        "$VENV/bin/python" -m pip install -q --upgrade pip
    fi
    # a failed install must stop the script (no '|| true'): pipefail keeps pip's status
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check -e ".${extras}" \
        2>&1 | { grep -v "Running pip as the 'root' user" || true; }
    export PATH="$VENV/bin:$PATH"
}
