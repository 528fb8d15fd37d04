#!/usr/bin/env bash
# Runs the C-ABI hardening tests (tests/hardening.rs: states left to fmi2FreeInstance, crafted
# states) and the FMI life-cycle tests under valgrind's memcheck: any invalid access or a
# definitely lost block is an error (docs/hardening.md). scripts/test.sh runs it.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v valgrind >/dev/null 2>&1; then
    source scripts/lib/apt.sh
    apt_install valgrind
fi
for t in hardening fmi_lifecycle; do
    bin=$(cargo test --release --test "$t" --no-run --message-format=json 2>/dev/null \
        | python3 -c 'import sys, json
name = sys.argv[1]
for line in sys.stdin:
    m = json.loads(line)
    t = m.get("target", {})
    if m.get("executable") and t.get("name") == name and "test" in t.get("kind", []):
        print(m["executable"])' "$t" | tail -1)
    if [ -z "$bin" ]; then
        echo "valgrind.sh: no test binary for $t" >&2
        exit 1
    fi
    echo "== valgrind $t"
    valgrind --quiet --leak-check=full --errors-for-leak-kinds=definite --show-leak-kinds=definite \
        --error-exitcode=1 "$bin" --test-threads=1 -q
done
