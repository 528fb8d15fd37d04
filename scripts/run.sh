#!/usr/bin/env bash
# The main job: builds the FMU, prepares the Python environment and simulates a machine at
# constant crank speed with fmpy over whole revolutions. Writes results/<preset>.png (acceleration,
# inertia load, guide friction, rod force, crank torque against crank angle; for an elastic rod
# its cage angle and stress, for a beam unit its card), results/<preset>.json (the summary,
# docs/results.md) and results/<preset>.csv, and prints the summary.
#
#   scripts/run.sh [preset]      preset: "default" (the FMU's start values, docs/model.md §8), the
#                                name of a parameter set resources/presets/<preset>.ssv, or "all"
set -euo pipefail
cd "$(dirname "$0")/.."

preset="${1:-default}"
if [ $# -gt 1 ]; then
    echo "usage: scripts/run.sh [preset|all]" >&2
    exit 2
fi
presets=("$preset")
if [ "$preset" = all ]; then
    presets=(default)
    for f in resources/presets/*.ssv; do presets+=("$(basename "$f" .ssv)"); done
elif [ "$preset" != "default" ] && [ ! -f "resources/presets/$preset.ssv" ]; then
    avail="default"
    for f in resources/presets/*.ssv; do [ -e "$f" ] && avail="$avail, $(basename "$f" .ssv)"; done
    echo "run.sh: unknown preset \"$preset\"; available: $avail, all" >&2
    exit 2
fi

# Only for this machine: the main job needs no cross toolchain, neither Windows nor aarch64
# (scripts/test.sh and scripts/build-wheel.sh build those binaries too).
RD_WIN64=0 RD_AARCH64=0 bash scripts/build-fmu.sh
source scripts/lib/venv.sh
ensure_venv
for p in "${presets[@]}"; do
    "$VENV_PYTHON" scripts/simulate.py "$p"
done
