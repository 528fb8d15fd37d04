// Shared build script of the FMU cdylib crates (`build = "../build.rs"` in each).
// Link the FMU with `-z nodelete` on Linux: importers (fmpy, the FMI Library behind libcosim)
// dlclose the library after each run; keeping it mapped makes any late destructor harmless.
// (fmi-sys contributes one extra exported helper, `callback_log`, which the FMU never calls;
// rustc's own export list for a cdylib cannot be narrowed by a second version script.)
// And with `-z defs`: every symbol the library uses must be resolved when it is linked. A shared
// object may otherwise keep undefined symbols for the loader, and that is how `no_panic` reports a
// path that could panic (fmi2DoStep's fast path, src/fmi/instance.rs `quick_step`): with the flag
// such a path fails the build instead of failing when the FMU is loaded. A PE link (the win64
// DLL) fails on undefined symbols anyway.
// The flags are ELF-only: they must not reach the Windows (PE) link of the win64 DLL.
fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-z,nodelete");
        println!("cargo:rustc-cdylib-link-arg=-Wl,-z,defs");
    }
    println!("cargo:rerun-if-changed=../build.rs");
}
