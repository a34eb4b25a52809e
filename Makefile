# KinDER: the two commands are `make demo` (the main job) and `make test` (lint, types, tests).
# Both work on a fresh machine with only python3, pip and make: uv is bootstrapped if missing, and
# `make test` installs the Debian and npm packages the tests need (tools/install_system_deps.sh).
SHELL := /bin/bash
.DEFAULT_GOAL := help
PACKAGES := kinder-core kinder-garden2d kinder-garden3d kinder-gym kinder-bench
UV := $(shell command -v uv 2>/dev/null || echo "python3 -m uv")
export SDL_VIDEODRIVER ?= dummy
export MUJOCO_GL ?= egl
PYTEST_ARGS ?=

.PHONY: help bootstrap sync system-deps demo test test-all lint typecheck fmt bench docs results-doc conformance-table datasets clean

help:  ## List the targets.
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  %-10s %s\n", $$1, $$2}'

# Debian's own python3 is "externally managed" (PEP 668): pip then installs uv, a standalone tool,
# into the user's site only with --break-system-packages.
bootstrap:  ## Install uv if it is missing (pip, then pip --user).
	@command -v uv >/dev/null 2>&1 || python3 -m uv --version >/dev/null 2>&1 || \
	  python3 -m pip install --quiet uv 2>/dev/null || \
	  python3 -m pip install --quiet --user uv 2>/dev/null || \
	  python3 -m pip install --quiet --user --break-system-packages uv

sync: bootstrap  ## Create .venv from uv.lock: all packages with every extra (torch, SB3, lerobot).
	$(UV) sync --locked --all-packages --all-extras

system-deps:  ## Debian packages (ffmpeg, chromium, nodejs, npm) and npm packages the tests need.
	bash tools/install_system_deps.sh

demo: sync  ## The main job: BP, MPC and random on 2D and 3D envs; table, GIFs, HTML report.
	$(UV) run --no-sync kinder demo

lint: sync  ## ruff lint and format check; the import-layering contracts (pyproject.toml).
	$(UV) run --no-sync ruff check .
	$(UV) run --no-sync ruff format --check .
	$(UV) run --no-sync lint-imports

typecheck: sync  ## mypy --strict on every package's src.
	$(UV) run --no-sync mypy

test: system-deps lint typecheck  ## System packages, lint, type-check and every package's fast tests.
	@set -e; for p in $(PACKAGES); do \
	  echo "== $$p"; \
	  (cd packages/$$p && $(UV) run --no-sync pytest -q $(PYTEST_ARGS) tests; rc=$$?; \
	   if [ $$rc -ne 0 ] && [ $$rc -ne 5 ]; then exit $$rc; fi); \
	done

test-all: PYTEST_ARGS += -m "slow or not slow"
test-all: test  ## `make test` plus the slow tests.

fmt: sync  ## Format and auto-fix.
	$(UV) run --no-sync ruff format .
	$(UV) run --no-sync ruff check --fix .

bench: sync  ## Speed benchmarks (benchmarks/README.md explains each).
	$(UV) run --no-sync python benchmarks/speed/core_bench.py
	$(UV) run --no-sync python benchmarks/speed/env_speed.py --all

docs: sync  ## Regenerate docs/envs/ pages for every registered id.
	$(UV) run --no-sync python tools/gen_env_docs.py --all

results-doc: sync  ## Regenerate docs/results.md from the summaries in benchmarks/results/.
	$(UV) run --no-sync python tools/gen_results_doc.py

conformance-table: sync  ## Regenerate docs/conformance.md from the conformance tests (slow ones included).
	$(UV) run --no-sync python tools/conformance/table.py
DATASETS ?=
datasets: sync  ## Collect, build and describe the demo datasets (DATASETS="a b" for some; resumable).
	time nice -n 10 $(UV) run --no-sync kinder demos datasets $(DATASETS) --executor inline --no-progress

clean:  ## Remove caches and run outputs.
	rm -rf .mypy_cache .ruff_cache runs out **/.pytest_cache
