#!/usr/bin/env bash
# Builds the Python package into a fresh virtual environment (maturin and NumPy from PyPI) and
# runs its tests, which compare it with `cargo xtask eval` (built here if it is not already).
set -euo pipefail
cd "$(dirname "$0")/.."
target="${CARGO_TARGET_DIR:-target}"
venv="$target/python-venv"
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet "./python[test]"
"$venv/bin/pip" install --quiet -r python/mitsuba/requirements.txt
cargo build --release --quiet -p xtask
GLINT_XTASK="$target/release/xtask" "$venv/bin/python" -m pytest -q python/tests
