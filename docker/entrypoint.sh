#!/usr/bin/env bash
# Container entrypoint: source ROS and the workspace, then run the `splitter` command
# (default: the launcher running lunar_jumping; see the Dockerfile's CMD).
set -eo pipefail
source /opt/ros/jazzy/setup.bash
source /opt/splitter/splitter_ws/install/setup.bash
export FASTDDS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE}"
exec /opt/venv/bin/python -m splitter_bringup.cli "$@"
