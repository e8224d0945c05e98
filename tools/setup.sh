#!/usr/bin/env bash
# Installs what omcl needs to build and run, only where it is missing:
# Debian packages (Embree 3, libclang for bindgen, a C compiler).
# Everything comes from the package registries; nothing else is downloaded.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
[ -f /usr/include/embree3/rtcore.h ] || need_apt+=(libembree-dev)
ls /usr/lib/llvm-*/lib/libclang*.so* >/dev/null 2>&1 || need_apt+=(libclang-dev)
command -v cc >/dev/null 2>&1 || need_apt+=(gcc)
command -v python3 >/dev/null 2>&1 || need_apt+=(python3 python3-pip)

if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi
echo "setup: system packages present (Embree 3, libclang, cc)"
