#!/usr/bin/env bash
# Builds the Python package's wheel once (maturin from PyPI) into a fresh virtual environment,
# installs it with NumPy, pytest and Dask's `distributed` (the farm's workers import this same
# installed wheel), and runs its tests, which compare it with `cargo xtask eval` and
# `cargo xtask render` (built here if they are not already), and the Mitsuba 3 plugins in
# scalar_rgb and (with LLVM 19, installed here where it can be) llvm_ad_rgb.
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
venv="$target/python-venv"
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet maturin
wheels="$target/python-wheels"
rm -rf "$wheels"
"$venv/bin/maturin" build --release --quiet -m python/Cargo.toml -i "$venv/bin/python" -o "$wheels"
wheel=$(ls "$wheels"/glint-*.whl)
"$venv/bin/pip" install --quiet "$wheel[test,farm]"
"$venv/bin/pip" install --quiet -r python/mitsuba/requirements.txt
cargo build --release --quiet -p xtask
# Mitsuba 3.9's llvm_ad_rgb variant needs LLVM 19 (its JIT aborts with LLVM 15 or 16): install
# Debian's libllvm19 where this runs as root with apt, and point Dr.Jit at it. Elsewhere the
# llvm tests (python/tests/test_mitsuba_vectorized.py) skip, saying why.
if [ -z "${DRJIT_LIBLLVM_PATH:-}" ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 \
      && ! dpkg -s libllvm19 >/dev/null 2>&1; then
    apt-get install -y -q libllvm19 >/dev/null 2>&1 \
      || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q libllvm19 >/dev/null 2>&1; } \
      || true
  fi
  llvm=$(dpkg -L libllvm19 2>/dev/null | grep 'libLLVM\.so\.19\.1$' | head -n 1 || true)
  if [ -n "$llvm" ]; then
    export DRJIT_LIBLLVM_PATH="$llvm"
  else
    echo "python/ci.sh: libllvm19 is not installed and cannot be (needs root and apt-get):" \
      "the llvm_ad_rgb tests are skipped" >&2
  fi
fi
GLINT_XTASK="$target/release/xtask" "$venv/bin/python" -m pytest -q python/tests
