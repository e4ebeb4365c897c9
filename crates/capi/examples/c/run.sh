#!/usr/bin/env bash
# Builds libglint.a, compiles query.c against it with the system's C compiler (strict C11) and
# runs it; exits non-zero if any step or any of the example's checks fails.
# Honours CARGO_TARGET_DIR (default: target/ at the repository's root) and CC (default: cc).
set -euo pipefail
cd "$(dirname "$0")/../../../.."

cargo build --release -p glint-capi
target_dir="${CARGO_TARGET_DIR:-target}"
out="$target_dir/c-example"
mkdir -p "$out"
# A Rust static library needs the C runtime's math, thread and dynamic-loading libraries.
"${CC:-cc}" -std=c11 -Wall -Wextra -Werror -pedantic -O2 \
    -I crates/capi/include \
    crates/capi/examples/c/query.c \
    "$target_dir/release/libglint.a" \
    -lm -lpthread -ldl \
    -o "$out/query"
"$out/query"
