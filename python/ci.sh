#!/usr/bin/env bash
# Builds the Python package's wheel once (maturin from PyPI) into a fresh virtual environment,
# installs it with NumPy, pytest and Dask's `distributed` (the farm's workers import this same
# installed wheel), and runs its tests, which compare it with `cargo xtask eval` and
# `cargo xtask render` (built here if they are not already).
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
GLINT_XTASK="$target/release/xtask" "$venv/bin/python" -m pytest -q python/tests
