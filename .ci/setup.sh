#!/usr/bin/env bash
# The project's one set-up script: Debian packages, a --system-site-packages venv made from
# Debian's /usr/bin/python3, and the project installed into it (editable) with its extras.
# Used by the Makefile and the Dockerfile. Idempotent: a second run changes nothing and takes
# about a second.
#
#   bash .ci/setup.sh            # apt packages + .venv + editable install
#   VENV=/opt/venv bash .ci/setup.sh
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${VENV:-$ROOT/.venv}
EXTRAS=${EXTRAS:-test,plot,render}

# DOLFINx 0.5.2 and its PETSc/MPI stack exist only as Debian packages for /usr/bin/python3.
APT_PACKAGES=(
  python3-dolfinx python3-dolfinx-real python3-petsc4py python3-slepc4py python3-mpi4py
  python3-scipy python3-matplotlib python3-venv python3-dev openmpi-bin g++ make git
  ca-certificates
  # meshio reads a structure's geometry from a file of line cells (cosserat_fem/io/line_mesh.py)
  python3-meshio
  # ParaView's own Python (pvpython) and a virtual screen for it: tests/test_visualisation.py
  # opens the XDMF output as ParaView does (pvpython on an Xvfb display, tests/virtual_display.py).
  paraview python3-paraview xvfb xauth
)

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

if [ -n "${SETUP_APT_ONLY:-}" ]; then
  echo "setup: Debian packages done (SETUP_APT_ONLY set)"
  exit 0
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup: creating $VENV from /usr/bin/python3 (--system-site-packages)"
  /usr/bin/python3 -m venv --system-site-packages "$VENV"
fi

# Pin the ABI-matched Debian builds so that pip never replaces them as a dependency of
# something else (matplotlib would otherwise pull a newer numpy). matplotlib itself comes from
# Debian too: a second, pip-installed copy in the venv breaks 3D plots as soon as Debian's
# python3-matplotlib is present (ParaView depends on it), because the mpl_toolkits namespace
# of /usr/lib/python3/dist-packages then shadows the venv's.
CONSTRAINTS="$VENV/constraints.txt"
/usr/bin/python3 - > "$CONSTRAINTS.new" <<'PY'
import importlib.metadata as md
for name in ("numpy", "mpi4py", "petsc4py", "slepc4py", "scipy", "matplotlib"):
    try:
        print(f"{name}=={md.version(name)}")
    except md.PackageNotFoundError:
        pass
PY
mv "$CONSTRAINTS.new" "$CONSTRAINTS"

# Reinstall only when the project metadata, the extras or this script changed.
STAMP="$VENV/.cosserat-fem-installed"
WANT=$(cat "$ROOT/pyproject.toml" "$ROOT/.ci/setup.sh" "$CONSTRAINTS" | sha256sum | cut -c1-16)-$EXTRAS
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ] || [ ! -x "$VENV/bin/cosserat-fem" ]; then
  echo "setup: installing cosserat-fem[$EXTRAS] (editable) into $VENV"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check \
    -c "$CONSTRAINTS" -e "$ROOT[$EXTRAS]"
  echo "$WANT" > "$STAMP"
fi
# Bytecode for the project's modules: with PYTHONDONTWRITEBYTECODE set (as on the development
# machines) Python would compile them anew in every process, 0.08 s of each start-up (docs/
# decisions.md, "Start-up"). Only changed files are compiled again.
"$VENV/bin/python" -m compileall -q "$ROOT/cosserat_fem" "$ROOT/forms" > /dev/null
"$VENV/bin/python" -c "import dolfinx, cosserat_fem; print('setup: dolfinx', dolfinx.__version__, '| cosserat-fem', cosserat_fem.__version__)"
