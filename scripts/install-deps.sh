#!/usr/bin/env bash
# Install every Debian 12 package SonicBoom needs to build, test and plot.
# Idempotent: when everything is present it only runs dpkg-query (well under a second).
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake pkg-config git ca-certificates
  # simulation; MuJoCo's CMake config calls find_dependency(OpenGL), which needs the GLVND
  # headers and the libOpenGL / libGLX link libraries even though nothing here renders
  libmujoco-dev libqhull-dev libembree-dev libgl-dev libglx-dev libopengl-dev
  # numerics
  libeigen3-dev libspectra-dev libfftw3-dev libtbb-dev libnanoflann-dev
  # learning (CPU libtorch); OpenBLAS replaces the reference BLAS libtorch would otherwise use
  libtorch-dev libopenblas0-openmp
  # I/O and CLI
  libsndfile1-dev libhdf5-dev libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
  libspdlog-dev libfmt-dev
  # live capture (sonicboom listen): PortAudio over ALSA
  portaudio19-dev
  # several processes: mpirun launches generation shards (tests, scripts/cluster/); Gloo's
  # headers for libtorch's c10d data-parallel training
  openmpi-bin libgloo-dev
  # fuzzing (scripts/fuzz.sh): clang with libFuzzer and the sanitizer runtimes
  clang-14 libclang-rt-14-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # plots and reference values (Debian's python, /usr/bin/python3)
  python3 python3-numpy python3-scipy python3-h5py python3-matplotlib python3-torchaudio
)

# which packages are not yet installed
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

if [ "$(id -u)" -ne 0 ]; then
  SUDO=sudo
else
  SUDO=
fi

echo "install-deps: installing ${#missing[@]} missing packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
