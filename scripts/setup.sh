#!/usr/bin/env bash
# One idempotent set-up for a fresh Debian 12 machine: system packages, the Python venv (.venv), the build.
# Re-running it only does what is missing or out of date. Usage: scripts/setup.sh
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

APT_PACKAGES=(build-essential cmake ninja-build ccache pkg-config git
  python3 python3-venv python3-dev
  libeigen3-dev libceres-dev libopencv-dev libopencv-contrib-dev libyaml-cpp-dev libpng-dev
  libgtest-dev libgmock-dev libbenchmark-dev valgrind)

missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "[setup] installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv"
  "$PY" -m venv .venv
fi
VPY=.venv/bin/python

# Python dependencies: reinstalled only when pyproject.toml changes.
stamp=.venv/.linnet-deps-$(sha1sum pyproject.toml | cut -c1-12)
if [ ! -f "$stamp" ]; then
  echo "[setup] installing Python dependencies"
  $VPY -m pip install -q --upgrade pip
  $VPY -m pip install -q "scikit-build-core>=0.10" "pybind11>=2.12" ninja
  $VPY -m pip install -q -r <($VPY - <<'PYEOF'
import tomllib
d = tomllib.load(open("pyproject.toml", "rb"))
extras = d["project"]["optional-dependencies"]
# The test suite exercises the optional Ray executor of linnet bench suite: the cluster extra comes along.
deps = list(d["project"]["dependencies"]) + list(extras["test"]) + list(extras["cluster"])
print("\n".join(deps))
PYEOF
)
  rm -f .venv/.linnet-deps-*
  touch "$stamp"
fi

# Build the C++ library, its tests and the Python module (one CMake build in build/, incremental).
echo "[setup] building (Release)"
# ccache keyed on paths relative to the checkout, so a fresh clone elsewhere reuses the cache.
export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
export CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)}
$VPY -m pip install -q --no-build-isolation --no-deps -e . \
  -Ccmake.define.LINNET_BUILD_TESTS=ON -Cbuild-dir=build
echo "[setup] done: activate with 'source .venv/bin/activate'"
