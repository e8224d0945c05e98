#!/usr/bin/env bash
# Installs what omcl needs to build and run, only where it is missing:
# Debian packages (Embree 3, libclang for bindgen, a C compiler).
# Everything comes from the package registries; nothing else is downloaded.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
[ -f /usr/include/embree3/rtcore.h ] || need_apt+=(libembree-dev)
# bindgen loads libclang.so or libclang-N.so*; libclang-cpp (C++ API, on
# some images by default) does not count.
have_libclang=no
for g in '/usr/lib/llvm-*/lib/libclang.so*' '/usr/lib/llvm-*/lib/libclang-[0-9]*.so*' \
  '/usr/lib/*-linux-gnu/libclang-[0-9]*.so*'; do
  compgen -G "$g" >/dev/null && have_libclang=yes
done
[ "$have_libclang" = yes ] || need_apt+=(libclang-dev)
command -v cc >/dev/null 2>&1 || need_apt+=(gcc)
# Open3D's native library (below) links libusb-1.0.
compgen -G '/usr/lib/*-linux-gnu/libusb-1.0.so.0' >/dev/null || need_apt+=(libusb-1.0-0)
command -v python3 >/dev/null 2>&1 || need_apt+=(python3 python3-pip)

if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi
echo "setup: system packages present (Embree 3, libclang, cc, libusb-1.0)"

# ONNX Runtime for the encoders (omcl loads it at run time, ort's
# `load-dynamic`): the shared library inside the PyPI `onnxruntime` wheel,
# installed into .deps/onnxruntime/ without its Python dependencies.
ORT_VERSION=1.31.1
ORT_DIR=.deps/onnxruntime
if ! ls "$ORT_DIR"/onnxruntime/capi/libonnxruntime.so* >/dev/null 2>&1; then
  if ! python3 -m pip --version >/dev/null 2>&1; then
    echo "setup: installing python3-pip"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3-pip >/dev/null
  fi
  echo "setup: installing onnxruntime $ORT_VERSION into $ORT_DIR"
  python3 -m pip install --quiet --disable-pip-version-check --no-deps \
    --target "$ORT_DIR" "onnxruntime==$ORT_VERSION"
fi
echo "setup: ONNX Runtime present: $(ls "$ORT_DIR"/onnxruntime/capi/libonnxruntime.so.* | head -1)"

# gRPC for the Python client of `omcl serve` (tools/omcl_client.py, and the
# test tests/serve_python.rs): grpcio and grpcio-tools (which generates the
# stubs from proto/omcl.proto at run time) into .deps/python/.
GRPC_VERSION=1.85.1
PY_DIR=.deps/python
if ! [ -f "$PY_DIR/grpcio_tools-$GRPC_VERSION.dist-info/METADATA" ] \
  || ! [ -f "$PY_DIR/grpcio-$GRPC_VERSION.dist-info/METADATA" ]; then
  echo "setup: installing grpcio and grpcio-tools $GRPC_VERSION into $PY_DIR"
  python3 -m pip install --quiet --disable-pip-version-check --target "$PY_DIR" \
    "grpcio==$GRPC_VERSION" "grpcio-tools==$GRPC_VERSION"
fi
echo "setup: Python gRPC present: grpcio $GRPC_VERSION in $PY_DIR"

# Open3D for the geometric RGB-D odometry baseline of Table I's 3-D block
# (tools/rgbd_odometry.py, tests/rgbd_odometry.rs): PyPI's CPU-only build
# `open3d-cpu` (a 105 MB wheel; `open3d`'s is 401 MB) with the
# dependencies it declares (numpy among them; about 610 MB unpacked), into
# .deps/open3d/. Installed into a temporary folder renamed into place, so an
# interrupted install is redone, not half used. pip may report conflicts with
# packages installed elsewhere on the machine (it checks them all); only the
# script puts this folder on its path.
O3D_VERSION=0.20.0
O3D_DIR=.deps/open3d
if ! [ -f "$O3D_DIR/open3d_cpu-$O3D_VERSION.dist-info/METADATA" ]; then
  echo "setup: installing open3d-cpu $O3D_VERSION into $O3D_DIR"
  rm -rf "$O3D_DIR.tmp"
  python3 -m pip install --quiet --disable-pip-version-check --target "$O3D_DIR.tmp" \
    "open3d-cpu==$O3D_VERSION"
  rm -rf "$O3D_DIR"
  mv "$O3D_DIR.tmp" "$O3D_DIR"
fi
echo "setup: Open3D present: open3d-cpu $O3D_VERSION in $O3D_DIR"
