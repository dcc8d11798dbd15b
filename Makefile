# SPLITTER: the two set-up commands are `make demo` and `make test`.
# Both create .venv when missing, install the pinned dependencies and the
# workspace packages (only when requirements.txt or a package's setup files
# changed), export the ROS environment and run.

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.splitter-installed
PACKAGES := splitter_msgs_py splitter_model splitter_bag splitter_sim splitter_mpc splitter_ik splitter_bringup splitter_tools
PKG_DIRS := $(addprefix splitter_ws/src/,$(PACKAGES))
PKG_SETUP := $(foreach p,$(PKG_DIRS),$(p)/setup.py $(p)/setup.cfg $(p)/package.xml)
OUT ?= runs/lunar_jumping

# ROS environment of every process make starts (DESIGN.md sections 6 and 8).
export AMENT_PREFIX_PATH := $(abspath $(VENV))
export RMW_IMPLEMENTATION := rmw_fastrtps_cpp
export FASTRTPS_DEFAULT_PROFILES_FILE := $(abspath splitter_ws/src/splitter_msgs_py/splitter_msgs_py/dds/fastdds_loopback.xml)
export FASTDDS_DEFAULT_PROFILES_FILE := $(FASTRTPS_DEFAULT_PROFILES_FILE)
# SUBNET = "use the XML profile as is"; the profile keeps DDS on 127.0.0.1.
export ROS_AUTOMATIC_DISCOVERY_RANGE := SUBNET
# No ROS_DOMAIN_ID here: a graph run chooses a domain no other graph on this machine
# uses unless the caller exports one (README "Networking"); the tests pick their own.
export MPLBACKEND := Agg
export PYTHONDONTWRITEBYTECODE := 1

.PHONY: demo test lint install clean colcon bench container container-test

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): requirements.txt $(PKG_SETUP) | $(BIN)/python
	$(BIN)/pip install --quiet --disable-pip-version-check -r requirements.txt
	$(BIN)/pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
		--use-pep517 $(foreach d,$(PKG_DIRS),-e $(d))
	touch $(STAMP)

install: $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/hadolint docker/Dockerfile

test: lint
	$(BIN)/splitter build-mpc
	$(BIN)/python -m pytest

demo: $(STAMP)
	$(BIN)/splitter run lunar_jumping --out $(OUT)
	@echo "bag, summary.json and plots in $(OUT)"

bench: $(STAMP)
	$(BIN)/splitter bench sim --json
	$(BIN)/splitter bench mpc --json
	$(BIN)/splitter bench bag --json

colcon: $(STAMP)
	cd splitter_ws && ../$(BIN)/colcon build --symlink-install

clean:
	rm -rf $(VENV) splitter_ws/build splitter_ws/install splitter_ws/log

# The container (docker/): `make container` installs docker.io and mmdebstrap when
# missing (as root), starts a Docker engine, builds the Debian base and the image
# splitter:jazzy; `make container-test` runs spin_stabilization in it and checks it
# against a host run (.ci/run calls it after `make test`).
container:
	docker/build.sh

container-test: $(STAMP)
	docker/container_test.sh
