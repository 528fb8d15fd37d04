#!/usr/bin/env bash
# A sweep on a cluster that shares no disk with the client, on this machine (docs/sweeps.md,
# "A cluster that shares no disk"): a Dask scheduler and two workers started from their own folder
# in a fresh venv where only the wheel is installed (Debian's python3, no PYTHONPATH, no RD_*
# variables; as the user nobody when run as root), the client the checkout's `rdrive sweep
# --scheduler`. Prints who each worker is and where its package comes from, then the study's
# table with the worker that computed each row. Stops the cluster and removes the folder at the end.
#
#   scripts/cluster_demo.sh [STUDY]      (default studies/default_balancer.toml)
#
# Needs target/wheel/*.whl (scripts/build-wheel.sh) and the package registry for the wheel's
# dependencies. Exit code: the sweep's (docs/sweeps.md "Errors and exit codes"); 2 without a wheel.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
STUDY=${1:-studies/default_balancer.toml}
WHEEL=$(ls target/wheel/reciprocating_drive-*.whl 2>/dev/null | tail -n 1 || true)
if [ -z "$WHEEL" ]; then
    echo "cluster_demo.sh: target/wheel/reciprocating_drive-*.whl not found; build it with scripts/build-wheel.sh" >&2
    exit 2
fi
source scripts/lib/venv.sh
ensure_venv
CLIENT_BIN=$(dirname "$VENV_PYTHON")

WORK=$(mktemp -d /tmp/rdrive-cluster-XXXXXX)
PIDS=()
cleanup() {
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${PIDS[@]}"; do timeout 20 tail --pid="$p" -f /dev/null 2>/dev/null || kill -9 "$p" 2>/dev/null || true; done
    rm -rf "$WORK"
}
trap cleanup EXIT
chmod 755 "$WORK"

# The cluster's machine: its own venv with the wheel and its dependencies only.
echo "== a venv with only the wheel: $WORK/venv"
timeout 120 /usr/bin/python3 -m venv "$WORK/venv"
env -u PYTHONPATH timeout 900 "$WORK/venv/bin/python" -m pip install -q --disable-pip-version-check \
    --no-input "$WHEEL"
chmod -R a+rX "$WORK/venv"
mkdir -m 777 "$WORK/run"

AS=()
if [ "$(id -u)" = 0 ]; then AS=(runuser -u nobody --); fi
PORT=$("$VENV_PYTHON" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
ADDRESS=tcp://127.0.0.1:$PORT
clean_env=(env -i PATH=/usr/bin:/bin HOME="$WORK/run" LANG=C.UTF-8)
echo "== scheduler and 2 workers at $ADDRESS, from $WORK/run${AS:+ as nobody}"
(cd "$WORK/run" && exec "${AS[@]}" "${clean_env[@]}" "$WORK/venv/bin/dask" scheduler \
    --host 127.0.0.1 --port "$PORT" --dashboard-address :0 --no-show >"$WORK/run/scheduler.log" 2>&1) &
PIDS+=($!)
for i in 1 2; do
    (cd "$WORK/run" && exec "${AS[@]}" "${clean_env[@]}" "$WORK/venv/bin/dask" worker "$ADDRESS" \
        --nthreads 1 --nworkers 1 --no-nanny --local-directory "$WORK/run" \
        --dashboard-address :0 >"$WORK/run/worker$i.log" 2>&1) &
    PIDS+=($!)
done

# Who the workers are and where their code comes from (not the checkout).
timeout 120 "$VENV_PYTHON" - "$ADDRESS" <<'EOF'
import sys
import warnings

from dask.distributed import Client
from distributed.versions import VersionMismatchWarning

# The workers' Python may be another patch release; what must agree is checked by the sweep.
warnings.simplefilter("ignore", VersionMismatchWarning)


def view():
    import os
    import pwd

    import reciprocating_drive

    return pwd.getpwuid(os.geteuid()).pw_name, reciprocating_drive.__file__, os.getcwd()


with Client(sys.argv[1], timeout=60) as c:
    c.wait_for_workers(2, timeout=90)
    for addr, (user, package, cwd) in sorted(c.run(view).items()):
        print(f"{addr}: user {user}, package {package}, folder {cwd}")
EOF

echo "== $CLIENT_BIN/rdrive sweep $STUDY --scheduler $ADDRESS"
set +e
timeout 1800 "$CLIENT_BIN/rdrive" sweep "$STUDY" --scheduler "$ADDRESS" --out-dir "$WORK/out" \
    --no-progress
code=$?
set -e
if [ $code = 0 ]; then
    "$VENV_PYTHON" - "$ROOT/$STUDY" "$WORK/out" <<'EOF'
import pathlib
import sys

import pyarrow.parquet as pq

from reciprocating_drive.sweeps.study import load_study

study = load_study(sys.argv[1])
rows = pq.read_table(pathlib.Path(sys.argv[2]) / f"{study.name}.parquet").to_pylist()
cols = ["case", *study.varied, *study.metrics, "status", "worker"]
cells = [[f"{r[c]:.6g}" if isinstance(r[c], float) else str(r[c]) for c in cols] for r in rows]
width = [max(len(c), *(len(x[i]) for x in cells)) for i, c in enumerate(cols)]
print("  ".join(c.rjust(w) for c, w in zip(cols, width)))
for x in cells:
    print("  ".join(v.rjust(w) for v, w in zip(x, width)))
print(f"{len(rows)} rows; by worker: " + ", ".join(
    f"{w} {sum(r['worker'] == w for r in rows)}" for w in sorted({r["worker"] for r in rows})))
EOF
fi
exit $code
