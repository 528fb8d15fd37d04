#!/usr/bin/env bash
# Builds the FMUs in release mode and packages each as target/fmu/<modelIdentifier>.fmu:
#   modelDescription.xml, binaries/linux64/<modelIdentifier>.so, binaries/win64/<modelIdentifier>.dll
#   (cross-compiled; RD_WIN64=0 skips it, docs/win64.md), resources/, documentation/ (the
#   variable table and docs/ as HTML with its figures)
# and its FMI 3.0 variant as target/fmu/<modelIdentifier>-fmi3.fmu: the same binaries (they export
# both standards' functions) under FMI 3.0's platform names (x86_64-linux, x86_64-windows), plus
# aarch64-linux (cross-compiled with Debian's aarch64 toolchain; RD_AARCH64=0 skips it; FMI 2.0
# has no platform name for it), the
# FMI 3.0 modelDescription.xml (modelDescription/fmi3/<modelIdentifier>.xml), the same resources/
# and documentation/ (docs/fmi-interface.md "FMI 3.0").
# Installs libclang (bindgen, for the fmi-sys FMI 2.0 types) when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib/ensure-build-deps.sh
ensure_build_deps
source scripts/lib/win64.sh
source scripts/lib/aarch64.sh

# The FMUs this repository builds, by modelIdentifier. Each has a cdylib crate
# cdylib/<modelIdentifier>/ (cargo names its library lib<modelIdentifier>.so) and a checked-in
# modelDescription (see model_description_file).
MODELS=(ReciprocatingDrive DriveTrain)

# Where the generated modelDescription.xml of a model is checked in.
model_description_file() {
    if [ "$1" = ReciprocatingDrive ]; then
        echo modelDescription/modelDescription.xml
    else
        echo "modelDescription/$1.xml"
    fi
}

cargo build --release --workspace --lib
if win64_enabled; then
    ensure_win64_build
    cargo build --release --target "$WIN64_TARGET" $(for id in "${MODELS[@]}"; do echo -n " -p fmu-$(echo "$id" | sed -E 's/([a-z])([A-Z])/\1-\2/g' | tr 'A-Z' 'a-z')"; done)
fi
if aarch64_enabled; then
    ensure_aarch64_build
    cargo build --release --target "$AARCH64_TARGET" $(for id in "${MODELS[@]}"; do echo -n " -p fmu-$(echo "$id" | sed -E 's/([a-z])([A-Z])/\1-\2/g' | tr 'A-Z' 'a-z')"; done)
fi
cargo build --release --quiet --bin gen-model-description
gen=target/release/gen-model-description

for id in "${MODELS[@]}"; do
    md=$(model_description_file "$id")
    "$gen" --model "$id" > "target/modelDescription-$id.xml"
    if ! cmp -s "target/modelDescription-$id.xml" "$md"; then
        echo "build-fmu.sh: $md is stale; regenerate it with" >&2
        echo "  cargo run --bin gen-model-description -- --model $id > $md" >&2
        exit 1
    fi
    md3=modelDescription/fmi3/$id.xml
    "$gen" --fmi3 --model "$id" > "target/modelDescription3-$id.xml"
    if ! cmp -s "target/modelDescription3-$id.xml" "$md3"; then
        echo "build-fmu.sh: $md3 is stale; regenerate it with" >&2
        echo "  cargo run --bin gen-model-description -- --fmi3 --model $id > $md3" >&2
        exit 1
    fi

    stage=target/fmu/stage-$id
    rm -rf "$stage" && mkdir -p "$stage/binaries/linux64" "$stage/documentation" "$stage/resources"
    cp "$md" "$stage/modelDescription.xml"
    # cargo names the library lib<crate>.so; the FMU's binary must be named <modelIdentifier>.so.
    cp "target/release/lib$id.so" "$stage/binaries/linux64/$id.so"
    if win64_enabled; then
        mkdir -p "$stage/binaries/win64"
        cp "target/$WIN64_TARGET/release/$id.dll" "$stage/binaries/win64/$id.dll"
    fi
    # documentation/: the generated variable table (index.html) and the project's documentation
    # (docs/*.md as HTML, with its figures), so users of the FMU alone have the model reference.
    "$gen" --model "$id" --doc --pages docs > "$stage/documentation/index.html"
    for page in docs/*.md; do
        "$gen" --page "$page" > "$stage/documentation/$(basename "$page" .md).html"
    done
    # The pages' images (docs/figures/, docs/sweeps/, ...), at the same relative paths.
    for sub in docs/*/; do
        [ -d "$sub" ] && cp -r "$sub" "$stage/documentation/$(basename "$sub")"
    done
    # Resources (presets, data) belong to the ReciprocatingDrive FMU.
    if [ "$id" = ReciprocatingDrive ] && compgen -G "resources/*" > /dev/null; then
        cp -r resources/. "$stage/resources/"
    fi
    # The FMI 3.0 variant: the same files, FMI 3.0's model description and platform names.
    stage3=target/fmu/stage3-$id
    rm -rf "$stage3" && cp -r "$stage" "$stage3"
    cp "$md3" "$stage3/modelDescription.xml"
    rm -rf "$stage3/binaries" && mkdir -p "$stage3/binaries/x86_64-linux"
    cp "$stage/binaries/linux64/$id.so" "$stage3/binaries/x86_64-linux/$id.so"
    if win64_enabled; then
        mkdir -p "$stage3/binaries/x86_64-windows"
        cp "$stage/binaries/win64/$id.dll" "$stage3/binaries/x86_64-windows/$id.dll"
    fi
    if aarch64_enabled; then
        mkdir -p "$stage3/binaries/aarch64-linux"
        cp "target/$AARCH64_TARGET/release/lib$id.so" "$stage3/binaries/aarch64-linux/$id.so"
    fi
    for pair in "$stage:target/fmu/$id.fmu" "$stage3:target/fmu/$id-fmi3.fmu"; do
        rm -f "${pair#*:}"
        python3 - "${pair%%:*}" "${pair#*:}" <<'PY'
import os, sys, zipfile
stage, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
    for root, _, files in os.walk(stage):
        for f in sorted(files):
            p = os.path.join(root, f)
            z.write(p, os.path.relpath(p, stage).replace(os.sep, "/"))
PY
        echo "wrote ${pair#*:}"
    done
done
