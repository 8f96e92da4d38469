#!/usr/bin/env bash
# Installs fracvi's build and test dependencies from Debian 12 packages.
# Idempotent: packages already present are skipped; apt is only touched when something is missing.
# Must run as root (or with sudo available) on a fresh machine.
set -euo pipefail

packages=(
  cmake g++ make ninja-build pkg-config   # build
  libeigen3-dev                           # linear algebra, AutoDiff module
  liblapacke-dev                          # banded Cholesky/LU (dpbtrf, dgbtrf) for chains
  libboost-dev                            # Boost.Math (special functions, tanh_sinh), Boost.Odeint
  libtomlplusplus-dev                     # problem files (TOML)
  libzip-dev                              # trajectory.npz (NumPy archives) from C++
  libcli11-dev                            # command line
  nlohmann-json3-dev                      # summary.json output
  libgtest-dev libgmock-dev               # unit tests
  libbenchmark-dev                        # benchmarks (bench/, not part of pass/fail)
  clang-format                            # formatting check
  python3 python3-numpy python3-matplotlib python3-pytest  # plots, CLI and Python tests
  python3-scipy                           # Python: sparse mass/damping as scipy.sparse matrices
  python3-mpmath                          # 50-digit reference RKCQ weights (tests/fractional/rkcq_reference.py)
  python3-dev pybind11-dev                # Python module (pybind11-dev does not pull Python.h)
  libopenmpi-dev openmpi-bin              # mpirun -n P fracvi sweep (optional at configure time)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "install-deps: missing packages (${missing[*]}) and not root; run as root" >&2
    exit 1
  fi
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
