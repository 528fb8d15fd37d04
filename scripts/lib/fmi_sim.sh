# Sourced by scripts/test.sh: rust-fmi's `fmi-sim` (crates.io, a second FMI 3.0 importer besides
# fmpy; tests/python/test_fmi_sim.py), installed into the project-local root target/tools/ so
# that nothing outside the checkout changes. An existing install of the pinned version is kept.
# RD_FMI_SIM=0 skips it (the test then skips with the reason).

FMI_SIM_VERSION=0.7.0
FMI_SIM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)/target/tools"
FMI_SIM="$FMI_SIM_ROOT/bin/fmi-sim"

fmi_sim_enabled() {
    [ "${RD_FMI_SIM:-1}" != 0 ]
}

# Installs fmi-sim $FMI_SIM_VERSION unless that version is installed already. A failed install
# is reported in one line and does not stop the caller (the test reports it as the skip reason,
# from target/tools/fmi-sim-install.log).
ensure_fmi_sim() {
    # (fmi-sim 0.7.0 prints its version on standard error and exits with 1: its output is taken
    # first, so that a caller's `set -o pipefail` does not read the exit status as "not there".)
    local have=""
    [ -x "$FMI_SIM" ] && have=$("$FMI_SIM" --version 2>&1 || true)
    if grep -q "fmi-sim $FMI_SIM_VERSION\$" <<<"$have"; then
        return 0
    fi
    mkdir -p "$FMI_SIM_ROOT"
    local log="$FMI_SIM_ROOT/fmi-sim-install.log" start=$SECONDS
    echo "fmi_sim.sh: cargo install fmi-sim $FMI_SIM_VERSION into $FMI_SIM_ROOT" >&2
    # --locked: the crate's own Cargo.lock, as published (reproducible).
    if cargo install --locked fmi-sim --version "$FMI_SIM_VERSION" --root "$FMI_SIM_ROOT" \
        >"$log" 2>&1; then
        echo "fmi_sim.sh: installed in $((SECONDS - start)) s" >&2
    else
        echo "fmi_sim.sh: cargo install fmi-sim $FMI_SIM_VERSION failed (see $log)" >&2
    fi
}
