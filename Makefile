# simenv: two commands on a fresh machine.
#
#   make demo   set up (.venv, Python and Debian packages) and run the main job on bundled data
#   make test   same set-up, then the test suite
#
# Set-up is stamped: re-runs skip it until pyproject.toml changes (or .venv is deleted).
# The package is installed *editable* with its dev extras, so the suite runs the working tree;
# tests/test_packaging.py builds the real wheel, installs it (non-editable) in a fresh venv and
# checks what a user gets: the simenv namespace, bundled assets, the `simenv` command.

SHELL := /bin/bash
.DEFAULT_GOAL := help

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.simenv-setup-stamp
DEMO_OUT ?= out/demo

# Debian packages needed for offscreen rendering on a CPU (OSMesa software OpenGL); python3-venv
# is added when the interpreter cannot create a venv (Debian's system Python without it).
APT_PACKAGES := libosmesa6 libgl1 libegl1

# Offscreen rendering: OSMesa when installed, else EGL (Mesa's surfaceless EGL also works on
# CPU). An explicit MUJOCO_GL from the caller always wins.
GL_BACKEND = $(shell ldconfig -p 2>/dev/null | grep -q 'libOSMesa\.so' && echo osmesa || echo egl)
RUN_ENV = MUJOCO_GL=$${MUJOCO_GL:-$(GL_BACKEND)}

.PHONY: help setup system-deps demo demo-check test lint bench clean distclean

help:
	@echo "make demo   - set up and run the demo (writes $(DEMO_OUT)/, open $(DEMO_OUT)/index.html)"
	@echo "make demo-check - check the demo's page in headless Chromium (installs it as root)"
	@echo "make test   - set up and run the test suite"
	@echo "make lint   - ruff check and the import rules (docs/architecture.md)"
	@echo "make bench  - retargeting benchmark (simenv vs mink)"
	@echo "make clean  - remove build artefacts and outputs (distclean also removes .venv)"

setup: $(STAMP)

# apt only when something is missing, only as root, and `apt-get update` once before installing.
system-deps:
	@if ! command -v dpkg >/dev/null 2>&1; then \
		echo "setup: no dpkg (not Debian/Ubuntu); make sure OSMesa or EGL is installed"; exit 0; \
	fi; \
	missing=""; \
	for p in $(APT_PACKAGES); do dpkg -s "$$p" >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	$(PYTHON) -c "import ensurepip, venv" >/dev/null 2>&1 || missing="$$missing python3-venv"; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" != 0 ]; then \
		echo "setup: missing Debian packages:$$missing (not root: run 'sudo apt-get install$$missing')"; \
		exit 0; \
	fi; \
	echo "setup: installing Debian packages:$$missing"; \
	apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory system-deps
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip "setuptools>=77" wheel
	$(BIN)/python -m pip install --quiet --no-build-isolation -e ".[dev]"
	touch $@

demo: $(STAMP)
	$(RUN_ENV) $(BIN)/simenv demo --out $(DEMO_OUT)

# The demo's page checked in a browser (`simenv demo --check-only`): every link resolves,
# headless Chromium plays every video, and its screenshot ($(DEMO_OUT)/index.png) is not blank
# and shows every video's poster. Chromium (~300 MB) is installed here only (as root, when
# missing), not by set-up: `make test` skips its browser tests without it.
BROWSER_PACKAGES := chromium

demo-check: $(STAMP)
	@if ! command -v chromium >/dev/null 2>&1 && command -v dpkg >/dev/null 2>&1; then \
		if [ "$$(id -u)" != 0 ]; then \
			echo "demo-check: chromium is missing (not root: run 'sudo apt-get install $(BROWSER_PACKAGES)')"; \
			exit 1; \
		fi; \
		echo "demo-check: installing $(BROWSER_PACKAGES)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $(BROWSER_PACKAGES); \
	fi
	test -f $(DEMO_OUT)/index.html || $(MAKE) --no-print-directory demo
	$(RUN_ENV) $(BIN)/simenv demo --out $(DEMO_OUT) --check-only

# The suite runs on every core, at most 4 (pytest-xdist workers; each holds MuJoCo, torch and
# the corpus in memory), one test file per worker at a time so that a file's shared fixtures (a
# retargeted clip, a trained model, a physics run) are built once (files sharing a session
# fixture run as one unit: tests/conftest.py SHARED_FIXTURE_FILES), the longest files first
# (tests/conftest.py LONGEST_FILES, kept in that order by --no-loadscope-reorder). TEST_WORKERS=1 runs it on one.
# numpy's OpenBLAS and torch's OpenMP get the cores left per worker: with two workers on two
# cores each spinning two BLAS threads, the room-descriptor protocol test took 64 s instead of 25.
NPROC := $(shell nproc 2>/dev/null || echo 2)
TEST_WORKERS ?= $(shell echo $$(( $(NPROC) < 4 ? $(NPROC) : 4 )))
TEST_THREADS ?= $(shell echo $$(( $(NPROC) / $(TEST_WORKERS) > 1 ? $(NPROC) / $(TEST_WORKERS) : 1 )))

test: $(STAMP)
	$(RUN_ENV) OMP_NUM_THREADS=$(TEST_THREADS) OPENBLAS_NUM_THREADS=$(TEST_THREADS) \
		$(BIN)/pytest -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# ruff, then the import rules of docs/architecture.md (import-linter contracts and AST scans).
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/pytest -q -p no:cacheprovider tests/test_architecture.py

bench: $(STAMP)
	$(RUN_ENV) $(BIN)/python benchmarks/bench_retarget.py

clean:
	rm -rf build dist out *.egg-info .pytest_cache .ruff_cache .hypothesis
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
