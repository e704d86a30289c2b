#!/usr/bin/env bash
# Everything in one go (~5 min on 2 cores): venv, stable dt, convergence, benchmark.
# Results go to benchmarks/pyelastica/results/ (git-ignored).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VENV="${PYELASTICA_VENV:-$(cd "$HERE/.." && pwd)/results/pyelastica-venv}"
bash "$HERE/setup.sh"
PY="$VENV/bin/python"
cd "$HERE"
"$PY" cantilever.py --static-check --elements 40
"$PY" stable_dt.py --elements 10 20 40 80 160 320 640
"$PY" convergence.py
"$PY" convergence.py --shift-clamp
"$PY" benchmark.py
"$PY" benchmark.py --shift-clamp --modes dt90
