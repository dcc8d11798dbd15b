#!/usr/bin/env bash
# `make container-test` (called by .ci/run after `make test`): build the image, run
# spin_stabilization in it, run it on the host, and check from the host that the
# summaries match and that the container's bag reads back.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
"${here}/docker/build.sh"
work="$(mktemp -d)"
trap 'rm -rf "${work}"' EXIT
options=(--variant mpc --no-animation --no-plots)
echo "== spin_stabilization in the container"
SPLITTER_RUNS="${work}/container" "${here}/docker/run.sh" spin_stabilization "${options[@]}"
echo "== spin_stabilization on the host"
"${here}/.venv/bin/splitter" run spin_stabilization --out "${work}/host/spin_stabilization" \
  "${options[@]}"
"${here}/.venv/bin/python" "${here}/docker/check_container_run.py" \
  "${work}/container/spin_stabilization" "${work}/host/spin_stabilization"
echo "container test passed"
