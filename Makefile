# Linnet: the two commands a fresh Debian 12 machine needs are `make demo` and `make test`.
# Each one runs scripts/setup.sh first (packages, .venv, incremental build).
VENV := .venv
PY := $(VENV)/bin/python
JOBS ?= $(shell nproc)

.PHONY: setup build test test-cpp test-py demo bench clean

setup:
	@bash scripts/setup.sh

build: setup

test: setup
	ctest --test-dir build -j $(JOBS) --output-on-failure --timeout 900
	$(PY) -m pytest -q python/tests

test-cpp: setup
	ctest --test-dir build -j $(JOBS) --output-on-failure --timeout 900

test-py: setup
	$(PY) -m pytest -q python/tests

demo: setup
	$(VENV)/bin/linnet demo

bench: setup
	$(VENV)/bin/linnet bench all

clean:
	rm -rf build
