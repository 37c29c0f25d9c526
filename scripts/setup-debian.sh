#!/usr/bin/env bash
# Installs the Debian 12 packages cwbvh needs. Idempotent: does nothing when all are present.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libembree-dev libopenmesh-dev libdraco-dev libtinygltf-dev nlohmann-json3-dev libglm-dev
  libtbb-dev libxxhash-dev libpng-dev libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev
  glmark2-data assimp-testmodels
  python3 python3-matplotlib python3-dev python3-numpy python3-pybind11 python3-pytest
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "setup: all Debian packages present"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
