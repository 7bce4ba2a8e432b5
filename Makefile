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

.PHONY: help demo test test-rust test-python test-web test-wheel bench build clean editor edit wasm-target chromium wheel

help: ## Show this help.
	@grep -E '^[a-zA-Z_-]+:.*?## ' $(MAKEFILE_LIST) | awk 'BEGIN {FS = ":.*?## "}; {printf "  make %-12s %s\n", $$1, $$2}'

$(VPY):
	$(PYTHON) -m venv $(VENV)

$(DEPS_STAMP): requirements-dev.txt pyproject.toml | $(VPY)
	$(VPY) -m pip install --disable-pip-version-check -q --upgrade pip
	$(VPY) -m pip install --disable-pip-version-check -q -r requirements-dev.txt
	touch $@

$(BUILD_STAMP): $(DEPS_STAMP) $(RUST_SOURCES) $(shell find python -type f -not -name '*.so' -not -path 'python/inkwarp/editor/*' -not -path 'python/inkwarp/examples/*' 2>/dev/null)
	$(VENV)/bin/maturin develop --release --quiet
	touch $@

build: $(BUILD_STAMP) ## Build the engine and install the Python package into .venv.

demo: build ## Render the still demo and every example scene (GIF, MP4) into out/ and print every path.
	$(VENV)/bin/inkwarp demo -o out

test: test-rust test-python test-web test-wheel ## Run every test suite (what CI runs).

test-rust: ## Rust unit and property tests of the core.
	$(CARGO) test --workspace --exclude inkwarp-py --release

test-python: build ## Python API, numerics (oracle), CLI and docs tests.
	$(VPY) -m pytest

# --- The browser editor (web/, crates/inkwarp-wasm) ---------------------------------------
WASM_TARGET := wasm32-unknown-unknown
WASM := target/$(WASM_TARGET)/release/inkwarp_wasm.wasm
WEB_WASM := web/src/generated/inkwarp.wasm
NODE_STAMP := web/node_modules/.ci-stamp
EDITOR := python/inkwarp/editor/index.html
WEB_SOURCES := $(shell find web/src web/scripts web/index.html web/vite.config.ts web/tsconfig.json examples -type f -not -path 'web/src/generated/*' 2>/dev/null)
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

wasm-target:
	@rustup target list --installed 2>/dev/null | grep -qx $(WASM_TARGET) || rustup target add $(WASM_TARGET)

$(WASM): $(RUST_SOURCES) | wasm-target
	$(CARGO) build -p inkwarp-wasm --target $(WASM_TARGET) --release

$(WEB_WASM): $(WASM)
	mkdir -p $(dir $@) && cp $< $@

$(NODE_STAMP): web/package.json web/package-lock.json
	cd web && npm ci --no-audit --no-fund --loglevel=error
	touch $@

$(EDITOR): $(WEB_WASM) $(NODE_STAMP) $(WEB_SOURCES)
	cd web && node scripts/bundle-examples.mjs && npx tsc --noEmit && npx vite build --logLevel warn

editor: $(EDITOR) ## Build the browser editor (WebAssembly engine + TypeScript) into the package.

edit: build editor ## Open the editor in the browser (`make edit SCENE=examples/cat/scene.json`).
	$(VENV)/bin/inkwarp edit $(SCENE)

chromium:
	@test -x /usr/bin/chromium || ($(SUDO) apt-get update -q && $(SUDO) apt-get install -y -q chromium)

test-web: build editor chromium ## Editor unit tests (Vitest) and end-to-end tests in headless Chromium.
	cd web && npx vitest run
	cd web && node e2e/run.mjs

# --- The wheel ----------------------------------------------------------------------------
WHEEL_DIR := target/wheels
EXAMPLES_COPY := python/inkwarp/examples

wheel: $(DEPS_STAMP) editor ## Build a wheel (engine, built editor, examples' scenes and art) into target/wheels/.
	rm -rf $(EXAMPLES_COPY) $(WHEEL_DIR)/inkwarp-*.whl
	$(VPY) -c "import shutil; shutil.copytree('examples', '$(EXAMPLES_COPY)', ignore=shutil.ignore_patterns('*.gif', '*.mp4', '*.py', '*.md', '__pycache__'))"
	$(VENV)/bin/maturin build --release --quiet --out $(WHEEL_DIR)

test-wheel: wheel ## Install the wheel in a fresh virtualenv without Rust or Node, run demo, render and edit.
	$(VPY) -m pytest -p no:cacheprovider tests/wheel/check_wheel.py

bench: build ## Benchmarks against the tools users would pick instead.
	$(VPY) -m pip install --disable-pip-version-check -q -r requirements-bench.txt
	$(VPY) benchmarks/run.py

clean: ## Remove build outputs (keeps .venv).
	rm -rf target out $(BUILD_STAMP) python/inkwarp/editor python/inkwarp/examples web/src/generated
