//! Loads the built FMU library with libloading, as an importer does, and wraps the FMI 2.0 calls
//! the tests and the host-loop benchmark need. Shared by tests/*.rs and benches/host_loop.rs.
#![allow(dead_code, non_snake_case)]

use fmi_sys::fmi2::*;
use libloading::Library;
use std::ffi::{c_char, c_void, CStr, CString};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

pub const OK: fmi2Status = fmi2Status_fmi2OK;
pub const ERROR: fmi2Status = fmi2Status_fmi2Error;

/// The cdylib cargo built together with this test binary: target/<profile>/deps/. (The copy in
/// target/<profile>/ is only refreshed by `cargo build`, not when the library is built as a
/// dependency of tests or benches, so it can be stale.)
pub fn library_path() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("deps dir");
    deps.join("libReciprocatingDrive.so")
}

/// What the logger received, shared through componentEnvironment.
#[derive(Default, Debug)]
pub struct LogSink {
    pub lines: Mutex<Vec<(String, fmi2Status, String, String)>>, // instance, status, category, message
}

impl LogSink {
    pub fn messages(&self) -> Vec<String> {
        self.lines.lock().unwrap().iter().map(|l| l.3.clone()).collect()
    }
    pub fn last(&self) -> String {
        self.lines.lock().unwrap().last().map(|l| l.3.clone()).unwrap_or_default()
    }
    pub fn clear(&self) {
        self.lines.lock().unwrap().clear()
    }
}

/// The FMI logger is variadic; Rust cannot define variadic functions on stable. This FMU always
/// calls it as (env, name, status, category, "%s", message), and on x86_64 SysV a variadic call
/// passes these six pointer/integer arguments in the same registers as a plain call, so a
/// six-argument function read through the variadic type receives them correctly.
extern "C" fn logger6(
    env: fmi2ComponentEnvironment,
    name: fmi2String,
    status: fmi2Status,
    category: fmi2String,
    fmt: fmi2String,
    arg: *const c_char,
) {
    let s = |p: *const c_char| {
        if p.is_null() {
            String::new()
        } else {
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    assert_eq!(s(fmt), "%s", "the FMU must pass its message through a %s format");
    if env.is_null() {
        return;
    }
    let sink = unsafe { &*(env as *const LogSink) };
    sink.lines.lock().unwrap().push((s(name), status, s(category), s(arg)));
}

pub fn logger_fn() -> fmi2CallbackLogger {
    // SAFETY: see logger6.
    Some(unsafe {
        std::mem::transmute::<
            extern "C" fn(
                fmi2ComponentEnvironment,
                fmi2String,
                fmi2Status,
                fmi2String,
                fmi2String,
                *const c_char,
            ),
            unsafe extern "C" fn(
                fmi2ComponentEnvironment,
                fmi2String,
                fmi2Status,
                fmi2String,
                fmi2String,
                ...
            ),
        >(logger6)
    })
}

macro_rules! fns {
    ($($name:ident: $ty:ident),* $(,)?) => {
        pub struct Api { _lib: Library, $(pub $name: <$ty as OptionFn>::F,)* }
        impl Api {
            pub fn load() -> Api {
                let lib = unsafe { Library::new(library_path()) }.expect("load the FMU library (cargo builds it with the tests)");
                $(let $name = *unsafe { lib.get::<<$ty as OptionFn>::F>(concat!(stringify!($name), "\0").as_bytes()) }
                    .unwrap_or_else(|e| panic!("missing export {}: {e}", stringify!($name)));)*
                Api { _lib: lib, $($name,)* }
            }
        }
    };
}

/// `fmi2XTYPE` is `Option<unsafe extern "C" fn(..)>`; this names the inner function type.
pub trait OptionFn {
    type F: Copy;
}
impl<F: Copy> OptionFn for Option<F> {
    type F = F;
}

fns! {
    fmi2GetTypesPlatform: fmi2GetTypesPlatformTYPE, fmi2GetVersion: fmi2GetVersionTYPE,
    fmi2SetDebugLogging: fmi2SetDebugLoggingTYPE, fmi2Instantiate: fmi2InstantiateTYPE,
    fmi2FreeInstance: fmi2FreeInstanceTYPE, fmi2SetupExperiment: fmi2SetupExperimentTYPE,
    fmi2EnterInitializationMode: fmi2EnterInitializationModeTYPE,
    fmi2ExitInitializationMode: fmi2ExitInitializationModeTYPE, fmi2Terminate: fmi2TerminateTYPE,
    fmi2Reset: fmi2ResetTYPE, fmi2GetReal: fmi2GetRealTYPE, fmi2GetInteger: fmi2GetIntegerTYPE,
    fmi2GetBoolean: fmi2GetBooleanTYPE, fmi2GetString: fmi2GetStringTYPE, fmi2SetReal: fmi2SetRealTYPE,
    fmi2SetInteger: fmi2SetIntegerTYPE, fmi2SetBoolean: fmi2SetBooleanTYPE, fmi2SetString: fmi2SetStringTYPE,
    fmi2GetFMUstate: fmi2GetFMUstateTYPE, fmi2SetFMUstate: fmi2SetFMUstateTYPE,
    fmi2FreeFMUstate: fmi2FreeFMUstateTYPE, fmi2SerializedFMUstateSize: fmi2SerializedFMUstateSizeTYPE,
    fmi2SerializeFMUstate: fmi2SerializeFMUstateTYPE, fmi2DeSerializeFMUstate: fmi2DeSerializeFMUstateTYPE,
    fmi2GetDirectionalDerivative: fmi2GetDirectionalDerivativeTYPE,
    fmi2SetRealInputDerivatives: fmi2SetRealInputDerivativesTYPE,
    fmi2GetRealOutputDerivatives: fmi2GetRealOutputDerivativesTYPE, fmi2DoStep: fmi2DoStepTYPE,
    fmi2CancelStep: fmi2CancelStepTYPE, fmi2GetStatus: fmi2GetStatusTYPE,
    fmi2GetRealStatus: fmi2GetRealStatusTYPE, fmi2GetIntegerStatus: fmi2GetIntegerStatusTYPE,
    fmi2GetBooleanStatus: fmi2GetBooleanStatusTYPE, fmi2GetStringStatus: fmi2GetStringStatusTYPE,
}

pub fn vr(name: &str) -> u32 {
    reciprocating_drive::fmus::reciprocating_drive::value_reference(name)
        .unwrap_or_else(|| panic!("no variable {name}")) as u32
}

/// One instance with its log sink; freed on drop.
pub struct Inst<'a> {
    pub api: &'a Api,
    pub c: fmi2Component,
    pub log: Arc<LogSink>,
    callbacks: Box<fmi2CallbackFunctions>,
}

impl<'a> Inst<'a> {
    pub fn new(api: &'a Api, name: &str) -> Inst<'a> {
        Self::with(api, name, Some("file:///nonexistent/resources"), true)
    }

    pub fn with(api: &'a Api, name: &str, resources: Option<&str>, logging_on: bool) -> Inst<'a> {
        Self::try_with(
            api,
            name,
            resources,
            logging_on,
            reciprocating_drive::fmi2::model_description::guid::<
                reciprocating_drive::fmus::reciprocating_drive::ReciprocatingDrive,
            >(),
        )
        .expect("fmi2Instantiate returned NULL")
    }

    pub fn try_with(
        api: &'a Api,
        name: &str,
        resources: Option<&str>,
        logging_on: bool,
        guid: &str,
    ) -> Result<Inst<'a>, Arc<LogSink>> {
        let log = Arc::new(LogSink::default());
        let callbacks = Box::new(fmi2CallbackFunctions {
            logger: logger_fn(),
            allocateMemory: None,
            freeMemory: None,
            stepFinished: None,
            componentEnvironment: Arc::as_ptr(&log) as *mut c_void,
        });
        let name = CString::new(name).unwrap();
        let guid = CString::new(guid).unwrap();
        let res = resources.map(|r| CString::new(r).unwrap());
        let c = unsafe {
            (api.fmi2Instantiate)(
                name.as_ptr(),
                fmi2Type_fmi2CoSimulation,
                guid.as_ptr(),
                res.as_ref().map_or(std::ptr::null(), |r| r.as_ptr()),
                &*callbacks,
                0,
                logging_on as i32,
            )
        };
        if c.is_null() {
            Err(log)
        } else {
            Ok(Inst { api, c, log, callbacks })
        }
    }

    pub fn setup(&self, start: f64) -> fmi2Status {
        unsafe { (self.api.fmi2SetupExperiment)(self.c, 0, 0.0, start, 0, 0.0) }
    }
    pub fn enter(&self) -> fmi2Status {
        unsafe { (self.api.fmi2EnterInitializationMode)(self.c) }
    }
    pub fn exit(&self) -> fmi2Status {
        unsafe { (self.api.fmi2ExitInitializationMode)(self.c) }
    }
    /// setup + enter + exit, asserting success.
    pub fn init(&self) {
        assert_eq!(self.setup(0.0), OK, "{}", self.log.last());
        assert_eq!(self.enter(), OK, "{}", self.log.last());
        assert_eq!(self.exit(), OK, "{}", self.log.last());
    }
    pub fn set(&self, name: &str, v: f64) -> fmi2Status {
        let r = vr(name);
        unsafe { (self.api.fmi2SetReal)(self.c, &r, 1, &v) }
    }
    pub fn set_int(&self, name: &str, v: i32) -> fmi2Status {
        let r = vr(name);
        unsafe { (self.api.fmi2SetInteger)(self.c, &r, 1, &v) }
    }
    /// Turns the guide-friction model off (every support kind 0, docs/model.md §5.2), for tests of
    /// the kinematics and loads alone. Only before fmi2ExitInitializationMode.
    pub fn frictionless(&self) {
        for x in ["support_A.kind", "support_B.kind", "support_C.kind"] {
            assert_eq!(self.set_int(x, 0), OK);
        }
    }
    /// Keeps only support A (a clamp at the reference axis): no redundant supports, so no
    /// friction, as the sk8-3.5-4000 preset.
    pub fn single_clamp(&self) {
        for x in ["support_B.kind", "support_C.kind"] {
            assert_eq!(self.set_int(x, 0), OK);
        }
    }
    pub fn get(&self, name: &str) -> f64 {
        self.try_get(name)
            .unwrap_or_else(|s| panic!("fmi2GetReal({name}) = {s}: {}", self.log.last()))
    }
    pub fn try_get(&self, name: &str) -> Result<f64, fmi2Status> {
        let r = vr(name);
        let mut v = f64::NAN;
        let s = unsafe { (self.api.fmi2GetReal)(self.c, &r, 1, &mut v) };
        if s == OK {
            Ok(v)
        } else {
            Err(s)
        }
    }
    pub fn get_many(&self, names: &[&str]) -> Vec<f64> {
        let vrs: Vec<u32> = names.iter().map(|n| vr(n)).collect();
        let mut v = vec![f64::NAN; vrs.len()];
        let s = unsafe { (self.api.fmi2GetReal)(self.c, vrs.as_ptr(), vrs.len(), v.as_mut_ptr()) };
        assert_eq!(s, OK, "{}", self.log.last());
        v
    }
    pub fn step(&self, t: f64, h: f64) -> fmi2Status {
        unsafe { (self.api.fmi2DoStep)(self.c, t, h, 1) }
    }
    pub fn get_state(&self) -> fmi2FMUstate {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        assert_eq!(unsafe { (self.api.fmi2GetFMUstate)(self.c, &mut s) }, OK);
        s
    }
    pub fn set_state(&self, s: fmi2FMUstate) -> fmi2Status {
        unsafe { (self.api.fmi2SetFMUstate)(self.c, s) }
    }
    pub fn free_state(&self, mut s: fmi2FMUstate) {
        assert_eq!(unsafe { (self.api.fmi2FreeFMUstate)(self.c, &mut s) }, OK);
        assert!(s.is_null());
    }
    pub fn serialize(&self, s: fmi2FMUstate) -> Vec<u8> {
        let mut n = 0usize;
        assert_eq!(unsafe { (self.api.fmi2SerializedFMUstateSize)(self.c, s, &mut n) }, OK);
        let mut buf = vec![0u8; n];
        assert_eq!(
            unsafe {
                (self.api.fmi2SerializeFMUstate)(self.c, s, buf.as_mut_ptr() as *mut c_char, n)
            },
            OK
        );
        buf
    }
    pub fn deserialize(&self, bytes: &[u8]) -> Result<fmi2FMUstate, fmi2Status> {
        let mut s: fmi2FMUstate = std::ptr::null_mut();
        let st = unsafe {
            (self.api.fmi2DeSerializeFMUstate)(
                self.c,
                bytes.as_ptr() as *const c_char,
                bytes.len(),
                &mut s,
            )
        };
        if st == OK {
            Ok(s)
        } else {
            Err(st)
        }
    }
}

impl Drop for Inst<'_> {
    fn drop(&mut self) {
        unsafe { (self.api.fmi2FreeInstance)(self.c) };
        let _ = &self.callbacks;
    }
}

/// (name, type, value) of every `<ssv:Parameter>` of an SSP parameter-value file.
pub fn parse_ssv(text: &str) -> Vec<(String, String, String)> {
    let mut out = vec![];
    for line in text.lines().map(str::trim).filter(|l| l.starts_with("<ssv:Parameter ")) {
        let attr = |s: &str, key: &str| -> String {
            let k = format!("{key}=\"");
            let i = s.find(&k).expect("attribute") + k.len();
            s[i..i + s[i..].find('"').expect("closing quote")].to_string()
        };
        let name = attr(line, "name");
        let inner = &line[line.find("><ssv:").expect("value element") + 6..];
        let ty = inner[..inner.find(' ').expect("type")].to_string();
        out.push((name, ty, attr(inner, "value")));
    }
    out
}

/// The entries of the shipped preset resources/presets/<name>.ssv (docs/model.md §8).
pub fn preset(name: &str) -> Vec<(String, String, String)> {
    let path = format!("{}/resources/presets/{name}.ssv", env!("CARGO_MANIFEST_DIR"));
    parse_ssv(&std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}")))
}

impl Inst<'_> {
    /// Sets every entry of a preset (in initialization mode), asserting each is accepted.
    pub fn apply_preset(&self, entries: &[(String, String, String)]) {
        for (name, ty, value) in entries {
            let st = match ty.as_str() {
                "Real" => self.set(name, value.parse().unwrap()),
                "Integer" => self.set_int(name, value.parse().unwrap()),
                _ => {
                    let (r, b) = (vr(name), (value == "true") as i32);
                    unsafe { (self.api.fmi2SetBoolean)(self.c, &r, 1, &b) }
                }
            };
            assert_eq!(st, OK, "{name}: {}", self.log.last());
        }
    }
}
