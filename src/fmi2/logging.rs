//! Messages through the importer's logger (docs/fmi-interface.md "State machine"): the caller's
//! componentEnvironment is passed back unchanged on every call; error messages always reach the
//! logger; other categories only while debug logging is on and the category is enabled.

use fmi_sys::fmi2::{fmi2CallbackLogger, fmi2ComponentEnvironment, fmi2Status};
use std::ffi::{c_char, CString};

/// Log categories declared in `<LogCategories>`, in declaration order.
pub static CATEGORIES: &[(&str, &str)] = &[
    ("logEvents", "Life-cycle events: initialization, steps with notable conditions, resets"),
    ("logStatusWarning", "Warnings (e.g. results near the validity limit of the model)"),
    ("logStatusError", "Errors: illegal calls, invalid parameters or inputs, failed steps"),
    ("logAll", "Everything, including every FMI call"),
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    Events = 0,
    Warning = 1,
    Error = 2,
    All = 3,
}

pub struct Logger {
    callback: fmi2CallbackLogger,
    environment: fmi2ComponentEnvironment,
    instance_name: CString,
    debug_logging: bool,
    enabled: [bool; 4],
}

impl Logger {
    pub fn new(
        callback: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
        instance_name: CString,
        logging_on: bool,
    ) -> Logger {
        Logger {
            callback,
            environment,
            instance_name,
            debug_logging: logging_on,
            enabled: [true; 4],
        }
    }

    /// fmi2SetDebugLogging: no categories given means all of them.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Result<(), String> {
        let mut enabled = [categories.is_empty(); 4];
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
        let Some(callback) = self.callback else { return };
        // Interior NULs cannot cross a C string; replace them rather than drop the message.
        let msg = CString::new(message.replace('\0', " ")).unwrap_or_default();
        let cat = CString::new(CATEGORIES[category as usize].0).unwrap_or_default();
        // The message goes through "%s": it may contain '%' and must not be read as a format.
        // SAFETY: every pointer is a valid NUL-terminated string living across the call; the
        // callback is the importer's, called with the arguments FMI 2.0 prescribes.
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
}
