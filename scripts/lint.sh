#!/usr/bin/env bash
# The linters a Rust and Python contributor expects, as scripts/test.sh runs them: rustfmt
# (rustfmt.toml), clippy over every target of the workspace with warnings as errors, ruff's
# check and format (pyproject.toml) over the Python, and import-linter's contracts on the Python
# package's layers (pyproject.toml [tool.importlinter], docs/architecture.md). Exits non-zero on
# the first finding.
#   scripts/lint.sh          check
#   scripts/lint.sh --fix    rewrite the formatting (cargo fmt, ruff format, ruff check --fix)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib/ensure-build-deps.sh
ensure_build_deps  # clippy builds the crates, and fmi-sys's bindgen needs libclang
source scripts/lib/venv.sh
ensure_venv

for comp in rustfmt clippy; do
    if ! rustup component list --installed 2>/dev/null | grep -q "^$comp"; then
        echo "lint.sh: adding the rustup component $comp" >&2
        rustup component add "$comp" >&2
    fi
done
ruff="$(dirname "$VENV_PYTHON")/ruff"

if [ "${1:-}" = "--fix" ]; then
    cargo fmt --all
    "$ruff" check --fix .
    "$ruff" format .
    exit 0
fi

echo "== cargo fmt --check"
cargo fmt --all --check
echo "== cargo clippy --workspace --all-targets -D warnings"
cargo clippy --release --workspace --all-targets --quiet -- -D warnings
echo "== ruff check, ruff format --check"
"$ruff" check --quiet .
"$ruff" format --check --quiet .
echo "== lint-imports (the Python package's layers)"
# --no-cache: no cache folder in the checkout; the graph of the package takes about a second.
"$(dirname "$VENV_PYTHON")/lint-imports" --no-cache --no-logo
echo "lint.sh: clean"
