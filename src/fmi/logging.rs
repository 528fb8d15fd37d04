//! Core layer (docs/architecture.md "The FMUs (Rust)").
//!
//! Messages through the importer's logger (docs/fmi-interface.md "State machine"): the caller's
//! componentEnvironment is passed back unchanged on every call; error messages always reach the
//! logger; other categories only while debug logging is on and the category is enabled.
//!
//! The per-call trace (`logCalls`) is opt-in by name (docs/fmi-interface.md "Logging
//! categories"): FMI 2.0 leaves the categories and their meaning to the FMU, and a master that
//! switches debug logging on without naming categories (libcosim through the FMI Library does so
//! at instantiation) wants the model's messages, not one line per fmi2DoStep of its own calls.

use fmi_sys::fmi2::{fmi2CallbackLogger, fmi2ComponentEnvironment, fmi2Status};
use fmi_sys::fmi3::fmi3LogMessageCallback;
use std::ffi::{c_char, CString};

/// Log categories declared in `<LogCategories>`, in declaration order.
pub static CATEGORIES: &[(&str, &str)] = &[
    ("logEvents", "Life-cycle events: initialization, steps with notable conditions, resets"),
    ("logStatusWarning", "Warnings (e.g. results near the validity limit of the model)"),
    ("logStatusError", "Errors: illegal calls, invalid parameters or inputs, failed steps"),
    ("logCalls", "One line per FMI function call (a trace for debugging an importer); only when this category or logAll is named in fmi2SetDebugLogging"),
    ("logAll", "Every category, including logCalls; only when named in fmi2SetDebugLogging"),
];

/// How many categories there are.
const N: usize = 5;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    Events = 0,
    Warning = 1,
    Error = 2,
    Calls = 3,
    All = 4,
}

/// The importer's logger: FMI 2.0's (printf-like, with the instance name) or FMI 3.0's (status,
/// category and message only). The status values of both standards are the same numbers
/// (OK 0 ... Fatal 4), so one instance core logs through either.
#[derive(Clone, Copy)]
enum Sink {
    Fmi2(fmi2CallbackLogger),
    Fmi3(fmi3LogMessageCallback),
}

/// The categories debug logging enables when none are named (fmi2Instantiate with
/// loggingOn = true, or fmi2SetDebugLogging with nCategories = 0): all but the per-call trace
/// and logAll, which includes it.
const DEFAULT_ENABLED: [bool; N] = [true, true, true, false, false];

pub struct Logger {
    callback: Sink,
    environment: fmi2ComponentEnvironment,
    instance_name: CString,
    debug_logging: bool,
    enabled: [bool; N],
}

impl Logger {
    pub fn new(
        callback: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
        instance_name: CString,
        logging_on: bool,
    ) -> Logger {
        Logger {
            callback: Sink::Fmi2(callback),
            environment,
            instance_name,
            debug_logging: logging_on,
            enabled: DEFAULT_ENABLED,
        }
    }

    /// A logger for an FMI 3.0 instance (fmi3Instantiate…'s logMessage and instanceEnvironment).
    pub fn new_fmi3(
        callback: fmi3LogMessageCallback,
        environment: fmi2ComponentEnvironment,
        instance_name: CString,
        logging_on: bool,
    ) -> Logger {
        let mut logger = Logger::new(None, environment, instance_name, logging_on);
        logger.callback = Sink::Fmi3(callback);
        logger
    }

    /// fmi2SetDebugLogging: no categories given means every category but the per-call trace
    /// (logCalls and logAll must be named).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Result<(), String> {
        let mut enabled = if categories.is_empty() { DEFAULT_ENABLED } else { [false; N] };
        for c in categories {
            match CATEGORIES.iter().position(|(n, _)| n == c) {
                Some(i) => enabled[i] = true,
                None => {
                    let known: Vec<&str> = CATEGORIES.iter().map(|c| c.0).collect();
                    return Err(format!(
                        "unknown log category \"{c}\"; known: {}",
                        known.join(", ")
                    ));
                }
            }
        }
        self.debug_logging = on;
        self.enabled = enabled;
        Ok(())
    }

    #[inline]
    pub fn wants(&self, category: Category) -> bool {
        category == Category::Error
            || (self.debug_logging
                && (self.enabled[category as usize] || self.enabled[Category::All as usize]))
    }

    #[inline]
    pub fn log(&self, status: fmi2Status, category: Category, message: &str) {
        if self.wants(category) {
            self.emit(status, category, message);
        }
    }

    #[cold]
    fn emit(&self, status: fmi2Status, category: Category, message: &str) {
        // Through an FMI 3.0 instance the message names the 3.0 functions.
        let text = match self.callback {
            Sink::Fmi3(_) => dialect(message),
            Sink::Fmi2(_) => std::borrow::Cow::Borrowed(message),
        };
        // Interior NULs cannot cross a C string; replace them rather than drop the message.
        let msg = CString::new(text.replace('\0', " ")).unwrap_or_default();
        let cat = CString::new(CATEGORIES[category as usize].0).unwrap_or_default();
        match self.callback {
            Sink::Fmi2(Some(callback)) => {
                // The message goes through "%s": it may contain '%' and must not be read as a
                // format.
                // SAFETY: every pointer is a valid NUL-terminated string living across the call;
                // the callback is the importer's, called with the arguments FMI 2.0 prescribes.
                unsafe {
                    callback(
                        self.environment,
                        self.instance_name.as_ptr(),
                        status,
                        cat.as_ptr(),
                        c"%s".as_ptr() as *const c_char,
                        msg.as_ptr(),
                    )
                };
            }
            Sink::Fmi3(Some(callback)) => {
                // SAFETY: as above, with the arguments FMI 3.0 prescribes (no format string).
                unsafe { callback(self.environment, status, cat.as_ptr(), msg.as_ptr()) };
            }
            Sink::Fmi2(None) | Sink::Fmi3(None) => {}
        }
    }
}

/// The instance core names the FMI 2.0 function a message comes from; through an FMI 3.0
/// instance's logger the message names the 3.0 function the importer called instead.
pub fn dialect(message: &str) -> std::borrow::Cow<'_, str> {
    const NAMES: &[(&str, &str)] = &[
        ("fmi2SetupExperiment", "fmi3EnterInitializationMode"),
        ("fmi2EnterInitializationMode", "fmi3EnterInitializationMode"),
        ("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"),
        ("fmi2Terminate", "fmi3Terminate"),
        ("fmi2Reset", "fmi3Reset"),
        ("fmi2DoStep", "fmi3DoStep"),
        ("fmi2GetFMUstate", "fmi3GetFMUState"),
        ("fmi2SetFMUstate", "fmi3SetFMUState"),
        ("fmi2FreeFMUstate", "fmi3FreeFMUState"),
        ("fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"),
        ("fmi2SerializeFMUstate", "fmi3SerializeFMUState"),
        ("fmi2GetReal", "fmi3GetFloat64"),
        ("fmi2SetReal", "fmi3SetFloat64"),
        ("fmi2GetInteger", "fmi3GetInt32"),
        ("fmi2SetInteger", "fmi3SetInt32"),
        ("fmi2GetBoolean", "fmi3GetBoolean"),
        ("fmi2SetBoolean", "fmi3SetBoolean"),
        ("fmi2Instantiate", "fmi3InstantiateCoSimulation"),
    ];
    if !message.contains("fmi2") {
        return std::borrow::Cow::Borrowed(message);
    }
    let mut s = message.to_string();
    for (from, to) in NAMES {
        if s.contains(from) {
            s = s.replace(from, to);
        }
    }
    std::borrow::Cow::Owned(s)
}
