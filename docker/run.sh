#!/usr/bin/env bash
# Run a scenario in the container and leave its bag, summary and plots on the host.
# Usage: docker/run.sh [SCENARIO] [extra `splitter run` options]
set -euo pipefail
scenario="${1:-lunar_jumping}"
shift || true
here="$(cd "$(dirname "$0")/.." && pwd)"
out="${SPLITTER_RUNS:-${here}/runs}"
image="${SPLITTER_IMAGE:-splitter:jazzy}"
mkdir -p "${out}"
if ! docker image inspect "${image}" >/dev/null 2>&1; then
  docker build -f "${here}/docker/Dockerfile" -t "${image}" "${here}"
fi
# --network none: the container's DDS never leaves its own loopback.
docker run --rm --network none --user "$(id -u):$(id -g)" \
  -v "${out}:/runs" "${image}" run "${scenario}" --out "/runs/${scenario}" "$@"
echo "results in ${out}/${scenario}"
