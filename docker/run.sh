#!/usr/bin/env bash
# Run a scenario in the container and leave its bag, summary and plots on the host.
# Usage: docker/run.sh [SCENARIO] [extra `splitter run` options]
# SPLITTER_RUNS: host output folder (default runs/); SPLITTER_IMAGE (default splitter:jazzy).
set -euo pipefail
scenario="${1:-lunar_jumping}"
shift || true
here="$(cd "$(dirname "$0")/.." && pwd)"
out="${SPLITTER_RUNS:-${here}/runs}"
image="${SPLITTER_IMAGE:-splitter:jazzy}"
mkdir -p "${out}"
out="$(cd "${out}" && pwd)"
if ! docker image inspect "${image}" >/dev/null 2>&1; then
  "${here}/docker/build.sh"
fi
# A scenario given as a YAML file on the host is mounted read-only beside the runs.
extra=()
if [ -f "${scenario}" ]; then
  extra=(-v "$(cd "$(dirname "${scenario}")" && pwd)/$(basename "${scenario}"):/scenario.yaml:ro")
  name="$(basename "${scenario}" .yaml)"
  scenario=/scenario.yaml
else
  name="${scenario}"
fi
# --network none: the container's DDS never leaves its own loopback. As the calling
# user, so that the results on the host belong to them.
docker run --rm --network none --user "$(id -u):$(id -g)" "${extra[@]}" \
  -v "${out}:/runs" "${image}" run "${scenario}" --out "/runs/${name}" "$@"
echo "results in ${out}/${name}"
