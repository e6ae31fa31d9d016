# Linnet: the two commands a fresh Debian 12 machine needs are `make demo` and `make test`.
# Each one runs scripts/setup.sh first (packages, .venv, incremental build).
VENV := .venv
PY := $(VENV)/bin/python
JOBS ?= $(shell nproc)

.PHONY: setup build test test-cpp test-py demo bench profile clean

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

# Per-function CPU profile of one run on one core (perf, from the linux-perf package):
#   make profile [PROFILE_DATA=path/to/euroc_folder] [PROFILE_FRAMES=400]
PROFILE_DATA ?= runs/demo/sim_room_1_30s
PROFILE_FRAMES ?= 400
profile: setup
	@command -v perf >/dev/null || { echo "make profile: perf not found (apt install linux-perf)"; exit 1; }
	@test -d $(PROFILE_DATA) || { echo "make profile: $(PROFILE_DATA) not found (run make demo, or set PROFILE_DATA)"; exit 1; }
	taskset -c 1 perf record -o runs/profile.data -- build/cpp/linnet_run $(PROFILE_DATA) --max-frames $(PROFILE_FRAMES)
	perf report -i runs/profile.data --no-children --percent-limit 1 --stdio | grep -E '^ +[0-9]'
	perf report -i runs/profile.data --no-children --sort dso --percent-limit 1 --stdio | grep -E '^ +[0-9]'

clean:
	rm -rf build
