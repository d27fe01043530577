#!/usr/bin/env bash
# The peer simulators' Python environment (.peers-venv): gym-electric-motor and motulator,
# which `bench perf` times beside the bench on the same 1 s scenario (shared/peers/).
# Idempotent: an existing venv with the pinned versions is left alone.
#
#   scripts/peers.sh            create or complete .peers-venv in the repository
#   PEERS_VENV=DIR scripts/peers.sh
#
# They need Python 3.12 (motulator 0.18: >= 3.12); found as python3.12 on PATH or in pyenv.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${PEERS_VENV:-$repo/.peers-venv}"
# Exact versions that install on the project's machines (PyPI, Python 3.12).
pins=("gym-electric-motor==3.0.3" "motulator==0.18.0")

find_python() {
    if [ -n "${PEERS_PYTHON:-}" ]; then
        [ -x "$PEERS_PYTHON" ] || { echo "peers.sh: PEERS_PYTHON=$PEERS_PYTHON is not executable" >&2; return 1; }
        echo "$PEERS_PYTHON"
        return
    fi
    local root="${PYENV_ROOT:-$HOME/.pyenv}" p
    # pyenv's own install first (its shim on PATH fails when 3.12 is not the selected version)
    for p in "$root"/versions/3.12.*/bin/python3.12 "$(command -v python3.12 2>/dev/null || true)"; do
        if [ -n "$p" ] && [ -x "$p" ] && "$p" -c 'import sys; assert sys.version_info[:2] == (3, 12)' 2>/dev/null; then
            echo "$p"
            return
        fi
    done
    return 1
}

installed() {  # every pin already installed in the venv?
    [ -x "$venv/bin/python" ] || return 1
    "$venv/bin/python" - "${pins[@]}" <<'EOF' 2>/dev/null
import importlib.metadata as md, sys
for pin in sys.argv[1:]:
    name, _, version = pin.partition("==")
    if md.version(name) != version:
        sys.exit(1)
EOF
}

if installed; then
    echo "peers.sh: $venv has ${pins[*]}"
    exit 0
fi
py="$(find_python)" || { echo "peers.sh: no Python 3.12 found (PATH, pyenv); set PEERS_PYTHON" >&2; exit 2; }
if [ ! -x "$venv/bin/python" ]; then
    echo "peers.sh: creating $venv with $py"
    "$py" -m venv "$venv"
fi
echo "peers.sh: installing ${pins[*]} into $venv"
"$venv/bin/python" -m pip install --quiet "${pins[@]}"
installed || { echo "peers.sh: the pinned versions did not install" >&2; exit 1; }
echo "peers.sh: $venv ready ($("$venv/bin/python" --version))"
