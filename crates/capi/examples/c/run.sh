#!/usr/bin/env bash
# Builds libglint.a, compiles query.c and the README's C snippet against it with the system's C
# compiler (strict C11) and runs them; exits non-zero if any step or any check fails.
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

# The README's C snippet, as it stands there, inside a main that checks what it computed.
snippet=$(awk '/^## From C/{inside=1} inside && /^```c$/{grab=1; next} grab && /^```$/{exit} grab{print}' README.md)
if [ -z "$snippet" ]; then
    echo "README.md: no C snippet under '## From C'" >&2
    exit 1
fi
{
    printf '#include <stdio.h>\n#include "glint.h"\nint main(void) {\n'
    printf '%s\n' "$snippet"
    printf '    printf("README snippet: f_hat %%g, count %%g, footprint_weight %%g, smooth_weight %%g\\n",\n'
    printf '           e.f_hat[0], e.count, x.footprint_weight[0], x.smooth_weight[0]);\n'
    printf '    return !(e.count >= 0.0 && x.valid == 1 && x.smooth_weight[0] > 0.0);\n}\n'
} > "$out/readme_snippet.c"
"${CC:-cc}" -std=c11 -Wall -Wextra -Werror -pedantic -O2 \
    -I crates/capi/include \
    "$out/readme_snippet.c" \
    "$target_dir/release/libglint.a" \
    -lm -lpthread -ldl \
    -o "$out/readme_snippet"
"$out/readme_snippet"
