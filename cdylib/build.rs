// Shared build script of the FMU cdylib crates (`build = "../build.rs"` in each).
// Link the FMU with `-z nodelete` on Linux: importers (fmpy, the FMI Library behind libcosim)
// dlclose the library after each run; keeping it mapped makes any late destructor harmless.
// (fmi-sys contributes one extra exported helper, `callback_log`, which the FMU never calls;
// rustc's own export list for a cdylib cannot be narrowed by a second version script.)
// The flag is ELF-only: it must not reach the Windows (PE) link of the win64 DLL.
fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-z,nodelete");
    }
    println!("cargo:rerun-if-changed=../build.rs");
}
