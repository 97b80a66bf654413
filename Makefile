# Developer and CI entry points for joint_space_control.
#
#   make venv          .venv with ROS 2 Jazzy + deps from PyPI, package installed editable
#   make test          ruff check, ruff format --check, pytest   (what .ci/run runs first)
#   make test-long     the tests of whole commands over many runs make test leaves out (CI)
#   make system-deps   Debian packages the tests need beyond PyPI (xvfb, chromium), apt-get
#                      for any missing
#   make demo          short end-to-end demo into out/demo
#   make stress        start/stop every executable 10 times with both signals (CI, a few minutes)
#   make fault-soak    jsc soak --faults' short form: every fault kind once (~3.5 min; CI
#                      runs it within make test-long)
#   make colcon-check  colcon build into build/colcon_ws and check the ament layout
#   make wheel-check   build the wheel, install it into a fresh venv, run jsc from /tmp
#   make lint / format / clean
#
# Every tool is called through .venv/bin/... explicitly: nothing needs `source`.

SHELL := /bin/bash
.DEFAULT_GOAL := test

VENV := .venv
PY := $(VENV)/bin/python
# Python 3.11 when installed, else the default python3 (>= 3.10, see setup.py).
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3 2>/dev/null)
# Re-installs when the packaging changes.
STAMP := $(VENV)/.install-stamp
# Console scripts that must land in .venv/bin (checked after the install, see setup.cfg).
VENV_SCRIPTS := sim_bridge pd_gravity_controller inverse_dynamics_controller trajectory_generator recorder dashboard jsc

.PHONY: venv system-deps demo test test-long browser-test stress fault-soak lint format colcon-check wheel-check clean distclean

venv: $(STAMP)

# `pip install -e` goes through the PEP 660 editable wheel (pyproject.toml exists, so pip
# uses the PEP 517 setuptools backend): pip itself writes the console scripts into
# .venv/bin, and setup.cfg's [develop]/[install] script dirs (meant for colcon's
# `setup.py install/develop`) do not apply. The loop below fails loudly should that change.
# An editable wheel carries no data files, so `setup.py install_data` then puts them in the
# venv as a wheel would: share/joint_space_control (launch files, configs, package.xml), the
# ament index marker and lib/joint_space_control's launchers, where `ros2 run` and
# `ros2 launch` look for the package by name.
# Quiet: each step's output goes to $(INSTALL_LOG) (one log per install, appended step by
# step) and one line per phase is printed; a failing step prints the log's path and its
# last 20 lines and stops make.
INSTALL_LOG := $(VENV)/install.log
$(STAMP): setup.py setup.cfg $(wildcard launch/*.launch.py resource/launchers/*)
	@test -n "$(PYTHON)" || { echo "error: no python3.11 or python3 on PATH" >&2; exit 1; }
	@log=$(INSTALL_LOG); mkdir -p $(VENV) && : >"$$log" || exit 1; \
	step() { \
	  echo "+ $$*" >>"$$log"; \
	  "$$@" >>"$$log" 2>&1 || { \
	    echo "venv: failed: $$*" >&2; \
	    echo "venv: log: $$log (last 20 lines below)" >&2; \
	    tail -n 20 "$$log" | sed 's/^/  | /' >&2; \
	    exit 1; }; \
	}; \
	if ! test -x $(PY); then \
	  echo "venv: creating $(VENV) ($(notdir $(PYTHON)))"; \
	  step $(PYTHON) -m venv $(VENV); \
	fi; \
	echo "venv: installing the package and its dependencies (log: $$log)"; \
	step $(PY) -m pip install --upgrade pip; \
	step $(PY) -m pip install -e '.[pypi,workbench,lab,test]'; \
	step $(PY) setup.py -q install_data -d $(VENV); \
	for exe in $(VENV_SCRIPTS); do \
	  test -x $(VENV)/bin/$$exe || { \
	    echo "error: $(VENV)/bin/$$exe missing after pip install -e (scripts redirected?)" >&2; \
	    exit 1; }; \
	done; \
	echo "venv: ready ($$SECONDS s)"
	@touch $@

# What PyPI cannot give: Xvfb, the X server the GUI test opens PyBullet's window on
# (test/integration/test_gui_view.py), and Chromium, the browser the dashboard's browser
# test drives headless through playwright (test/integration/browser.py: WebGL in software,
# with the SwiftShader that Debian's chromium package ships; DejaVu fonts for its text).
# Each test is skipped without its program. SYSTEM_COMMANDS pairs each command with the
# packages that bring it; those of every missing command are installed with apt-get (root,
# or passwordless sudo). Where that is impossible a message says what to install and the
# rest goes on. A failing apt-get is an error.
SYSTEM_COMMANDS := Xvfb=xvfb chromium=chromium,fonts-dejavu-core
system-deps:
	@missing=""; present=""; pkgs=""; \
	for pair in $(SYSTEM_COMMANDS); do \
	  cmd="$${pair%%=*}"; \
	  if command -v "$$cmd" >/dev/null 2>&1; then present="$$present $$cmd"; \
	  else missing="$$missing $$cmd"; pkgs="$$pkgs $$(echo "$${pair#*=}" | tr , ' ')"; fi; \
	done; \
	why="for the GUI test (Xvfb) and the browser test (Chromium), each skipped without it"; \
	if [ -z "$$missing" ]; then \
	  echo "system-deps:$$present present"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
	  echo "system-deps: no apt-get here; install$$missing $$why"; \
	else \
	  if [ "$$(id -u)" -eq 0 ]; then sudo=""; \
	  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then sudo="sudo -n"; \
	  else \
	    echo "system-deps: not root; run 'sudo apt-get install$$pkgs' $$why"; \
	    exit 0; \
	  fi; \
	  echo "system-deps:$$missing missing; apt-get install$$pkgs"; \
	  $$sudo env DEBIAN_FRONTEND=noninteractive apt-get update -q && \
	  $$sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
	    $$pkgs; \
	fi

demo: venv
	$(VENV)/bin/jsc demo --out out/demo

# Two pytest workers (pytest-xdist): each integration test leases its own ROS domain. The
# tests that judge a realtime loop against the wall clock (marker realtime) then run one at
# a time: beside another test's processes on two cores their loop stalls (issue 16). The
# tests of a whole command over many runs (marker long) are left to make test-long, which
# .ci/run runs after make test: make test stays within 5 minutes (docs/testing.md).
test: venv system-deps
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -m pytest -n 2 -m "not realtime and not long"
	$(PY) -m pytest -n 0 -m "realtime and not long"

# Only the long tests: every scenario's short form on both engines, a sweep of ROS runs on
# threads and on a LocalCluster, a tune confirmed on ROS, the bench, the dashboard's tour
# (about 10 minutes; CI runs it after make test).
test-long: venv system-deps
	$(PY) -m pytest -n 2 -m "long and not realtime"
	$(PY) -m pytest -n 0 -m "long and realtime"

# Only the dashboard's browser tests (make test's realtime part, and make test-long); their screenshots
# go to JSC_SCREENSHOTS when it names a folder (docs/figures/dashboard.png is one).
browser-test: venv system-deps
	$(PY) -m pytest -n 0 -m browser -s

# Every executable started and stopped 10 times (SIGINT and SIGTERM) with its topics busy,
# no traceback in any output (test/stress, a few minutes; CI runs it after make test). A
# crash in C code prints its Python stack (faulthandler).
stress: venv
	PYTHONFAULTHANDLER=1 $(PY) -m pytest -n 2 test/stress

# The fault soak's short form alone (test/integration/test_soak.py; make test-long runs it
# too): every kind of fault once, 15 s apart, judged from the bags. The hour:
# `jsc soak --faults` (docs/safety.md, Fault soak).
fault-soak: venv
	$(PY) -m pytest -n 0 -m long test/integration/test_soak.py -k fault_soak

lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

format: venv
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

colcon-check: venv
	COLCON=$(VENV)/bin/colcon bash .ci/colcon_check.sh

# A regular (non-editable) install, as `pip install '.[pypi]'` users get it: the wheel in a
# fresh venv under build/wheel_check, `jsc experiment --list`, `jsc demo` and one scenario
# run from a temporary directory outside the checkout.
wheel-check: venv
	BUILD_PY=$(PY) PYTHON=$(PYTHON) bash .ci/wheel_check.sh

clean:
	rm -rf build install log out *.egg-info .pytest_cache .ruff_cache .hypothesis
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
