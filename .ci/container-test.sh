#!/usr/bin/env bash
# make container-test: build the Dockerfile and run, inside the image, `make test` and the
# paper's demo under `mpirun -n 2`. Uses docker where an engine answers, else rootful podman
# (../shared/notes/containers.md: no registry here, so the debian:bookworm base image is made
# locally with debootstrap when it is missing). Cleans up the image and the containers; fails
# loudly with the reason. Prints the build and test times and the image size.
#
#   bash .ci/container-test.sh            # ENGINE=podman|docker to choose
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
TAG=${TAG:-cosserat-fem-ci:$$}
BASE=docker.io/library/debian:bookworm
WORK=$(mktemp -d /tmp/cosserat-container.XXXXXX)

fail() { echo "container-test: FAILED: $*" >&2; exit 1; }
log() { echo "container-test: $*"; }
now() { date +%s; }

pick_engine() {
  if [ -n "${ENGINE:-}" ]; then echo "$ENGINE"; return; fi
  if command -v docker >/dev/null && docker info >/dev/null 2>&1; then echo docker; return; fi
  echo podman
}
ENGINE=$(pick_engine)

if [ "$ENGINE" = podman ]; then
  if ! command -v podman >/dev/null || ! command -v debootstrap >/dev/null \
     || ! command -v runc >/dev/null; then
    log "installing podman, runc, debootstrap (apt)"
    SUDO=""; [ "$(id -u)" != 0 ] && SUDO=sudo
    $SUDO apt-get update -q >/dev/null || fail "apt-get update"
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends \
      podman runc debootstrap uidmap fuse-overlayfs ca-certificates >/dev/null \
      || fail "cannot install podman (apt-get install podman runc debootstrap)"
  fi
  [ "$(id -u)" = 0 ] || fail "podman here must run as root (rootful): no user namespaces"
  # Limits root may not raise, runc instead of crun, no systemd (containers.md).
  nofile=$(ulimit -Hn)
  nproc=$(ulimit -Hu); [ "$nproc" = unlimited ] && nproc=32768
  [ "$nproc" -gt 32768 ] && nproc=32768
  export CONTAINERS_CONF="$WORK/containers.conf"
  cat > "$CONTAINERS_CONF" <<EOF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
events_logger = "file"
EOF
fi

cleanup() {
  status=$?
  "$ENGINE" rmi -f "$TAG" >/dev/null 2>&1 || true
  # KEEP_CACHE=1 keeps the build's layers (the apt layer takes minutes to remake).
  if [ "$ENGINE" = podman ] && [ -z "${KEEP_CACHE:-}" ]; then
    podman image prune -f >/dev/null 2>&1 || true
  fi
  rm -rf "$WORK"
  exit $status
}
trap cleanup EXIT

if [ "$ENGINE" = podman ] && ! podman image exists "$BASE"; then
  log "making the base image $BASE with debootstrap (no registry here)"
  t0=$(now)
  rootfs="$WORK/rootfs"
  debootstrap --variant=minbase bookworm "$rootfs" http://deb.debian.org/debian >/dev/null \
    || fail "debootstrap bookworm (is deb.debian.org reachable?)"
  cat > "$rootfs/etc/apt/sources.list" <<EOF
deb http://deb.debian.org/debian bookworm main
deb http://deb.debian.org/debian bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
  echo 'Acquire::Check-Valid-Until "false";' > "$rootfs/etc/apt/apt.conf.d/99no-check-valid"
  tar -C "$rootfs" -c . | podman import - "$BASE" >/dev/null || fail "podman import"
  rm -rf "$rootfs"
  log "base image made in $(( $(now) - t0 )) s"
fi

# A machine behind a TLS-intercepting proxy (this one) trusts an extra CA that the image does
# not: lend the host's CA bundle to the build's pip, read-only, outside the image's own paths.
build_args=()
host_ca=${PIP_CERT:-${SSL_CERT_FILE:-}}
if [ -n "$host_ca" ] && [ -f "$host_ca" ] && [ "$ENGINE" = podman ]; then
  build_args+=(--volume "$host_ca:/run/host-ca.crt:ro" --build-arg PIP_CERT=/run/host-ca.crt)
  log "pip in the build trusts the host's CA bundle $host_ca"
fi

log "building $TAG with $ENGINE"
t0=$(now)
"$ENGINE" build "${build_args[@]}" -t "$TAG" "$ROOT" > "$WORK/build.log" 2>&1 \
  || { tail -40 "$WORK/build.log" >&2; fail "$ENGINE build (log above)"; }
build_s=$(( $(now) - t0 ))
size=$("$ENGINE" image inspect "$TAG" --format '{{.Size}}')
log "built in ${build_s} s, image size $(( size / 1000000 )) MB"

t0=$(now)
"$ENGINE" run --rm --shm-size=512m "$TAG" make test VENV=/opt/venv \
  || fail "make test inside the image"
test_s=$(( $(now) - t0 ))
log "make test inside the image: ${test_s} s"

t0=$(now)
"$ENGINE" run --rm --shm-size=512m "$TAG" bash -c \
  'mpirun -n 2 /opt/venv/bin/python demos/cao_tucker_2008.py --out /tmp/demo | tail -5' \
  || fail "the paper's demo under mpirun -n 2 inside the image"
log "demo under mpirun -n 2: $(( $(now) - t0 )) s"
log "passed: build ${build_s} s, make test ${test_s} s, image $(( size / 1000000 )) MB"
