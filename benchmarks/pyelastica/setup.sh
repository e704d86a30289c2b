#!/usr/bin/env bash
# Create (idempotently) the PyElastica virtual environment for the benchmark.
#   bash benchmarks/pyelastica/setup.sh    -> ${PYELASTICA_VENV:-benchmarks/results/pyelastica-venv}
# Needs: a python3 >= 3.10 able to create a venv, and access to PyPI.
# The venv is separate from the cosserat-fem one (no dolfinx, no system site packages).
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VENV="${PYELASTICA_VENV:-$(cd "$HERE/.." && pwd)/results/pyelastica-venv}"
REQ="$HERE/requirements.txt"
PIN="$(grep -E '^pyelastica==' "$REQ" | head -n1 | cut -d= -f3)"

log() { echo "[pyelastica-setup] $*" >&2; }

venv_ok() {
    [ -x "$VENV/bin/python" ] &&
        "$VENV/bin/python" - "$PIN" <<'PY' 2>/dev/null
import sys
from importlib.metadata import version
import elastica, numba, numpy, scipy, tqdm  # noqa: F401
sys.exit(0 if version("pyelastica") == sys.argv[1] else 1)
PY
}

if venv_ok; then
    log "venv $VENV already has pyelastica==$PIN: nothing to do"
    exit 0
fi

start=$(date +%s)

py_ok() {  # $1: interpreter; true if >= 3.10
    command -v "$1" >/dev/null 2>&1 &&
        "$1" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' 2>/dev/null
}

candidates=(/usr/bin/python3)
for v in 3.12 3.11 3.10 3.13; do candidates+=("python$v"); done
if [ -d "${PYENV_ROOT:-$HOME/.pyenv}/versions" ]; then
    for d in "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.1[0-3]*; do
        [ -x "$d/bin/python3" ] && candidates+=("$d/bin/python3")
    done
fi
candidates+=(python3)

try_venv() {  # $1: interpreter
    rm -rf "$VENV"
    "$1" -m venv "$VENV" >/dev/null 2>&1 && [ -x "$VENV/bin/pip" ]
}

made=""
for py in "${candidates[@]}"; do
    py_ok "$py" || continue
    if try_venv "$py"; then made="$py"; break; fi
    log "$py -m venv failed (no ensurepip / python3-venv?)"
done

if [ -z "$made" ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    log "installing Debian's python3-venv and retrying /usr/bin/python3"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv) >&2 || true
    if py_ok /usr/bin/python3 && try_venv /usr/bin/python3; then made=/usr/bin/python3; fi
fi

if [ -z "$made" ]; then
    # last resort: a venv without pip, populated by an existing pip (pip >= 22.3 has --python)
    for py in "${candidates[@]}"; do
        py_ok "$py" || continue
        if "$py" -m pip --version >/dev/null 2>&1; then
            rm -rf "$VENV"
            "$py" -m venv --without-pip "$VENV"
            "$py" -m pip --python "$VENV/bin/python" install -r "$REQ"
            made="$py (pip --python)"
            break
        fi
    done
fi

[ -n "$made" ] || { log "no python3 >= 3.10 able to create a venv (install python3-venv)"; exit 1; }
log "venv created from $made"

if [ -x "$VENV/bin/pip" ]; then
    "$VENV/bin/python" -m pip install --upgrade --quiet pip >&2 || true
    "$VENV/bin/python" -m pip install --quiet -r "$REQ" >&2
fi

# Populate numba's on-disk cache (PyElastica kernels use cache=True), so the
# first benchmark run does not pay the ~15-20 s JIT compilation.
if [ "${PYELASTICA_SKIP_WARMUP:-0}" != 1 ]; then
    log "warming numba cache"
    "$VENV/bin/python" "$HERE/cantilever.py" --elements 10 --dt 1e-6 --end 2e-5 >/dev/null
fi

venv_ok || { log "venv check failed"; exit 1; }
end=$(date +%s)
log "done in $((end - start)) s; $(du -sh "$VENV" | cut -f1) in $VENV"
"$VENV/bin/python" -m pip freeze 2>/dev/null | sed 's/^/[pyelastica-setup]   /' >&2 || true
