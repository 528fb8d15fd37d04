#!/usr/bin/env bash
# The main job: builds the FMU, prepares the Python environment and simulates a machine at
# constant crank speed for 3 s with fmpy (the crank motion supplied as input signals), writing
# results/<preset>.csv and results/<preset>.png (position, velocity, acceleration and inertia force
# against crank angle).
#
#   scripts/run.sh [preset]      preset: "default" (the FMU's start values, physics.md §8) or the
#                                name of a parameter set resources/presets/<preset>.ssv
set -euo pipefail
cd "$(dirname "$0")/.."

preset="${1:-default}"
if [ $# -gt 1 ]; then
    echo "usage: scripts/run.sh [preset]" >&2
    exit 2
fi
if [ "$preset" != "default" ] && [ ! -f "resources/presets/$preset.ssv" ]; then
    avail="default"
    for f in resources/presets/*.ssv; do [ -e "$f" ] && avail="$avail, $(basename "$f" .ssv)"; done
    echo "run.sh: unknown preset \"$preset\"; available: $avail" >&2
    exit 2
fi

bash scripts/build-fmu.sh
source scripts/lib/venv.sh
ensure_venv
"$VENV_PYTHON" scripts/simulate.py "$preset"
