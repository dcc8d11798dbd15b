#!/usr/bin/env bash
# Build the SPLITTER image (`make container`): installs what it needs when it is
# missing and it can, starts a Docker engine when none runs, builds the Debian base
# image from Debian packages, then the image. A second run reuses the cached layers.
#
# Environment: SPLITTER_IMAGE (default splitter:jazzy), SPLITTER_BASE_IMAGE (default
# splitter-base:bookworm; python:3.11-slim-bookworm where a registry is reachable).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
image="${SPLITTER_IMAGE:-splitter:jazzy}"
base="${SPLITTER_BASE_IMAGE:-splitter-base:bookworm}"

need() {  # need COMMAND DEBIAN_PACKAGE
  command -v "$1" >/dev/null 2>&1 && return 0
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "installing $2 (for $1) ..."
    apt-get install -y --no-install-recommends "$2" >/dev/null \
      || { apt-get update >/dev/null && apt-get install -y --no-install-recommends "$2" >/dev/null; }
  else
    echo "error: $1 is missing; install the Debian package $2 (as root: apt-get install $2)" >&2
    exit 1
  fi
}

need docker docker.io
need dockerd docker.io
if ! docker info >/dev/null 2>&1; then
  if [ "$(id -u)" != 0 ]; then
    echo "error: no Docker engine answers; start one (as root: dockerd &)" >&2
    exit 1
  fi
  echo "starting a Docker engine (no bridge network: containers run with --network none) ..."
  log="${TMPDIR:-/tmp}/splitter-dockerd.log"
  nohup dockerd --iptables=false --bridge=none >"${log}" 2>&1 &
  for _ in $(seq 60); do docker info >/dev/null 2>&1 && break; sleep 1; done
  docker info >/dev/null 2>&1 || { echo "error: dockerd did not start; see ${log}" >&2; exit 1; }
fi

if ! docker image inspect "${base}" >/dev/null 2>&1; then
  if [ "${base}" != "splitter-base:bookworm" ]; then
    docker pull "${base}"
  else
    need mmdebstrap mmdebstrap
    echo "building ${base} from Debian packages (mmdebstrap, ~1 min) ..."
    rootfs="$(mktemp -d)/rootfs.tar"
    mmdebstrap --quiet --variant=minbase --include=python3,python3-venv,ca-certificates \
      bookworm "${rootfs}"
    docker import "${rootfs}" "${base}" >/dev/null
    rm -rf "$(dirname "${rootfs}")"
  fi
fi

# pip in the build goes through this host's TLS set-up: its CA bundle, never committed
ca="${PIP_CERT:-/etc/ssl/certs/ca-certificates.crt}"
cp "${ca}" "${here}/docker/build-ca.crt"
trap 'rm -f "${here}/docker/build-ca.crt"' EXIT
echo "building ${image} (the first build installs the requirements and compiles the MPC) ..."
DOCKER_BUILDKIT=0 docker build --network host --build-arg "BASE_IMAGE=${base}" \
  -f "${here}/docker/Dockerfile" -t "${image}" "${here}"
size="$(docker image inspect "${image}" --format '{{.Size}}')"
echo "${image}: $((size / 1024 / 1024)) MiB"
