#!/usr/bin/env bash
# Builds the FMU in release mode and packages target/fmu/ReciprocatingDrive.fmu:
#   modelDescription.xml, binaries/linux64/ReciprocatingDrive.so, resources/, documentation/
# Installs libclang (bindgen, for the fmi-sys FMI 2.0 types) when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib/ensure-build-deps.sh
ensure_build_deps

cargo build --release --lib
cargo run --release --quiet --bin gen-model-description > target/modelDescription.xml
if ! cmp -s target/modelDescription.xml modelDescription/modelDescription.xml; then
    echo "build-fmu.sh: modelDescription/modelDescription.xml is stale; regenerate it with" >&2
    echo "  cargo run --bin gen-model-description > modelDescription/modelDescription.xml" >&2
    exit 1
fi

stage=target/fmu/stage
rm -rf "$stage" && mkdir -p "$stage/binaries/linux64" "$stage/documentation" "$stage/resources"
cp modelDescription/modelDescription.xml "$stage/"
# cargo names the library lib<crate>.so; the FMU's binary must be named <modelIdentifier>.so.
cp target/release/libreciprocating_drive.so "$stage/binaries/linux64/ReciprocatingDrive.so"
cargo run --release --quiet --bin gen-model-description -- --doc > "$stage/documentation/index.html"
if compgen -G "resources/*" > /dev/null; then cp -r resources/. "$stage/resources/"; fi
rm -f target/fmu/ReciprocatingDrive.fmu
python3 - "$stage" target/fmu/ReciprocatingDrive.fmu <<'PY'
import os, sys, zipfile
stage, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
    for root, _, files in os.walk(stage):
        for f in sorted(files):
            p = os.path.join(root, f)
            z.write(p, os.path.relpath(p, stage).replace(os.sep, "/"))
PY
echo "wrote target/fmu/ReciprocatingDrive.fmu"
