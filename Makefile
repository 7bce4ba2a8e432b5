# inkwarp — every target installs what it is missing, so a fresh machine needs only `make`.
# `make help` lists the targets.

SHELL := /bin/bash
.DEFAULT_GOAL := help

PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
DEPS_STAMP := $(VENV)/.deps-stamp
BUILD_STAMP := $(VENV)/.build-stamp
CARGO ?= cargo
export VIRTUAL_ENV := $(abspath $(VENV))
export PATH := $(abspath $(VENV))/bin:$(HOME)/.cargo/bin:$(PATH)

RUST_SOURCES := $(shell find crates -name '*.rs' -o -name Cargo.toml 2>/dev/null) Cargo.toml

.PHONY: help demo test test-rust test-python bench build clean

help: ## Show this help.
	@grep -E '^[a-zA-Z_-]+:.*?## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*?## "}; {printf "  make %-12s %s\n", $$1, $$2}'

$(VPY):
	$(PYTHON) -m venv $(VENV)

$(DEPS_STAMP): requirements-dev.txt pyproject.toml | $(VPY)
	$(VPY) -m pip install --disable-pip-version-check -q --upgrade pip
	$(VPY) -m pip install --disable-pip-version-check -q -r requirements-dev.txt
	touch $@

$(BUILD_STAMP): $(DEPS_STAMP) $(RUST_SOURCES) $(shell find python -type f -not -name '*.so' 2>/dev/null)
	$(VENV)/bin/maturin develop --release --quiet
	touch $@

build: $(BUILD_STAMP) ## Build the engine and install the Python package into .venv.

demo: build ## Render the still demo and the three examples (GIF, MP4) into out/ and print every path.
	$(VENV)/bin/inkwarp demo -o out

test: test-rust test-python ## Run every test suite (what CI runs).

test-rust: ## Rust unit and property tests of the core.
	$(CARGO) test --workspace --exclude inkwarp-py --release

test-python: build ## Python API, numerics (oracle), CLI and docs tests.
	$(VPY) -m pytest

bench: build ## Benchmarks against the tools users would pick instead.
	$(VPY) -m pip install --disable-pip-version-check -q -r requirements-bench.txt
	$(VPY) benchmarks/run.py

clean: ## Remove build outputs (keeps .venv).
	rm -rf target out $(BUILD_STAMP)
