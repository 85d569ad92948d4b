#!/usr/bin/env bash
# Installs the Debian 12 packages probebake needs to build, test and run (as root, or with sudo).
# Idempotent and quick when everything is present: it asks dpkg first and calls apt-get only for
# what is missing.
set -euo pipefail

PACKAGES=(
  # toolchain
  cmake ninja-build g++ pkg-config git ca-certificates
  # RPC and data formats
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libabsl-dev libssl-dev
  # rendering and volumes
  libembree-dev libopenvdb-dev libboost-iostreams-dev libopenexr-dev libassimp-dev libpng-dev libstb-dev
  # runtime services
  libspdlog-dev libtbb-dev libsqlite3-dev libcli11-dev
  # tests and benchmarks
  libgtest-dev libbenchmark-dev
  # the viewer and engine exports (web/): node + npm bundle three.js at build time and run it in
  # the three.js export test; headless chromium renders the viewer in its test and runs the
  # shader includes (the HLSL one compiled by glslang and cross-compiled by spirv-cross)
  nodejs npm chromium glslang-tools spirv-cross
  # third-party models every importer path is tested against (tests/server/testmodels_test.cpp)
  assimp-testmodels
  # Python-side interop tests (Debian's interpreter: /usr/bin/python3)
  python3 python3-grpcio python3-protobuf python3-numpy python3-openvdb
  # the Slurm backend and its end-to-end test (a one-node cluster: scripts/slurm-cluster.sh)
  slurm-wlm munge
  # the offline check of the Kubernetes manifests (deploy/k8s) against the API's schema
  python3-kubernetes python3-yaml
)

missing=()
for p in "${PACKAGES[@]}"; do
  # A nodejs from NodeSource bundles npm and conflicts with Debian's npm package: an npm command
  # that is already there is enough.
  if [ "$p" = npm ] && command -v npm >/dev/null 2>&1; then continue; fi
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
