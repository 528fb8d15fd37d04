#!/usr/bin/env bash
# Builds the installable Python package: target/wheel/reciprocating_drive-<version>-py3-none-<platform>.whl
# with both FMUs (linux64 + win64 binaries inside each), the twin's native batch library, the SSP
# system, the example studies and the twin's sample data (hatch_build.py, docs/install.md).
#   scripts/build-wheel.sh          then: pip install target/wheel/reciprocating_drive-*.whl
#   scripts/build-wheel.sh --no-build   package what scripts/build-fmu.sh already built
set -euo pipefail
cd "$(dirname "$0")/.."
[ "${1:-}" = --no-build ] || bash scripts/build-fmu.sh
source scripts/lib/venv.sh
ensure_venv
rm -rf target/wheel
# pip builds in an isolated environment with the pinned hatchling of pyproject.toml.
"$VENV_PYTHON" -m pip wheel --quiet --disable-pip-version-check --no-deps -w target/wheel .
ls target/wheel/*.whl
