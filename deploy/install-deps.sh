#!/usr/bin/env bash
# Installs, from Debian 12 packages, everything Tessera needs to build, test and run.
# Idempotent: when every package is already installed it returns in about a second
# without touching the network. Run as root (or with sudo available).
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config ccache git
  # Vulkan: loader, headers, lavapipe (CPU driver), validation layers, shader compiler
  libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers vulkan-tools
  glslang-tools spirv-tools
  # math, glTF import (tinygltf uses nlohmann-json and stb_image)
  libglm-dev libtinygltf-dev nlohmann-json3-dev libstb-dev
  # compressed glTF meshes: KHR_draco_mesh_compression, EXT_meshopt_compression
  libdraco-dev libmeshoptimizer-dev
  # service: gRPC + Protobuf with protoc and the C++ grpc plugin
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc libabsl-dev
  # SHA-256 of uploaded files (scene ids)
  libssl-dev
  # Prometheus metrics endpoint of tesserad (prometheus-cpp core + pull, civetweb HTTP)
  prometheus-cpp-dev
  # image encoding, logging
  libturbojpeg0-dev libpng-dev zlib1g-dev libspdlog-dev libfmt-dev
  # WebP textures (EXT_texture_webp)
  libwebp-dev
  # video streams (h264 sessions; libavcodec with libx264, swscale for RGB->YUV, libavformat for
  # the CLI's .mp4; Debian builds these with --enable-gpl: see the README's licence section)
  libavcodec-dev libavformat-dev libswscale-dev libavutil-dev
  # tests and benchmarks; deploy/validate.sh (YAML, kustomize patches, systemd unit)
  libgtest-dev libgmock-dev libbenchmark-dev python3-yaml python3-jsonpatch systemd
  # fuzzing (tests/fuzz/run.sh): clang with libFuzzer and the sanitizer runtimes
  clang libclang-rt-14-dev
  # the web viewer's browser tests (tests/web): headless Chromium, driven by playwright-core
  chromium
)
# The web gateway (clients/web) runs on Node.js with npm. A newer Node already on the machine
# (e.g. from NodeSource) is kept; otherwise Debian's is installed.
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  PACKAGES+=(nodejs npm)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
