#!/usr/bin/env bash
# One-shot, idempotent set-up of everything the bench needs on a Debian machine:
#   1. Debian packages (C toolchains, clang-format, can-utils, rt-tests; the QEMU/virtme-ng
#      fallback only when the host kernel has no SocketCAN),
#   2. the Python virtual environment .venv with the pinned dependencies of
#      pyproject.toml and the `bench` command,
#   3. the C build (make).
# Called by `make demo` and `make test`; safe to run again (each step is skipped
# when already done).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)

log() { printf '[setup] %s\n' "$*"; }

have_host_can() {
    python3 - <<'EOF'
import socket, sys
try:
    socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
except OSError:
    sys.exit(1)
EOF
}

# ---------------------------------------------------------------- Debian packages
# rt-tests: cyclictest, the scheduler's own latency beside the plant's (bench perf --only realtime)
PKGS=(gcc make clang libclang-rt-14-dev clang-format can-utils valgrind gcc-arm-none-eabi
      libnewlib-arm-none-eabi qemu-system-arm iproute2 kmod chromium rt-tests)
if have_host_can; then
    log "host kernel has SocketCAN: no VM fallback needed"
else
    log "host kernel has no SocketCAN (socket(AF_CAN) fails): installing the virtme-ng VM fallback"
    PKGS+=(qemu-system-x86 linux-image-amd64 busybox-static file iproute2 procps)
fi
missing=()
for p in "${PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    log "installing Debian packages: ${missing[*]}"
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# ---------------------------------------------------------------- Python venv
PY=${PYTHON:-python3}
stamp=.venv/.installed-$(cat pyproject.toml requirements.lock | sha256sum | cut -c1-16)
if [ ! -f "$stamp" ]; then
    log "creating .venv with the exact versions of requirements.lock (pyproject.toml's ranges, every extra)"
    [ -x .venv/bin/python ] || "$PY" -m venv .venv
    .venv/bin/pip install -q --disable-pip-version-check --upgrade pip==24.3.1
    .venv/bin/pip install -q --disable-pip-version-check -c requirements.lock -e ".[all,dev]"
    rm -f .venv/.installed-*
    # Pre-compile so a guest VM (read-only view of the venv) never writes .pyc.
    .venv/bin/python -m compileall -q .venv/lib >/dev/null 2>&1 || true
    touch "$stamp"
fi

# ---------------------------------------------------------------- C build
log "building C (make -j2)"
PATH="$ROOT/.venv/bin:$PATH" make -s -j2 all
.venv/bin/python -m compileall -q bench tests >/dev/null 2>&1 || true
log "ready"
