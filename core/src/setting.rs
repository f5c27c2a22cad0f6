//! Settings by their key, and the error of a setting whose value cannot work.
//!
//! Libraries name a setting by its key in `postflight.toml`
//! (`[detect] image_size`), never by a command-line flag: the same setting
//! reaches a stage from `postflight detect --imgsz` or from the config file
//! of `postflight run`. How a key is worded for the person running
//! postflight is the binary's choice, made once at start-up
//! ([`word_keys_with`]); errors hold [`Key`]s and ask for that wording when
//! they are displayed.

use std::fmt;
use std::sync::OnceLock;

/// A setting or an input, as errors name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Key {
    /// A stage setting: its table and key in `postflight.toml`.
    Setting {
        table: &'static str,
        name: &'static str,
    },
    /// An input every command that takes it names with the same flag
    /// (`--map`, `--model`), with no key in `postflight.toml`.
    Input(&'static str),
}

impl Key {
    pub const fn setting(table: &'static str, name: &'static str) -> Self {
        Self::Setting { table, name }
    }

    pub const fn input(flag: &'static str) -> Self {
        Self::Input(flag)
    }
}

/// The inputs every command names with the same flag.
pub mod inputs {
    use super::Key;

    pub const FLIGHT: Key = Key::input("--flight");
    pub const MAP: Key = Key::input("--map");
    pub const PLAN: Key = Key::input("--plan");
    pub const YAW_DEGREES: Key = Key::input("--yaw-degrees");
    pub const MODEL: Key = Key::input("--model");
    pub const ONNXRUNTIME: Key = Key::input("--onnxruntime");
    pub const RUN: Key = Key::input("--run");
}

type Wording = Box<dyn Fn(&Key) -> Option<String> + Send + Sync>;

static WORDING: OnceLock<Wording> = OnceLock::new();

/// Word keys with `wording` from now on (where it returns `None`, as the
/// config file names them). Set once per process; later calls are ignored.
pub fn word_keys_with(wording: impl Fn(&Key) -> Option<String> + Send + Sync + 'static) {
    let _ = WORDING.set(Box::new(wording));
}

impl fmt::Display for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(word) = WORDING.get().and_then(|w| w(self)) {
            return f.write_str(&word);
        }
        match self {
            Self::Setting { table, name } => write!(f, "[{table}] {name}"),
            Self::Input(flag) => f.write_str(flag),
        }
    }
}

/// A setting whose value cannot work.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key} must be {expected} (it is {value})")]
pub struct InvalidSetting {
    pub key: Key,
    pub value: String,
    /// What it must be: `a multiple of 32`.
    pub expected: String,
}

impl InvalidSetting {
    pub fn new(key: Key, value: impl fmt::Display, expected: impl Into<String>) -> Self {
        Self {
            key,
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    /// `Err` unless `ok`.
    pub fn check(ok: bool, key: Key, value: impl fmt::Display, expected: &str) -> Result<(), Self> {
        if ok {
            Ok(())
        } else {
            Err(Self::new(key, value, expected))
        }
    }
}

/// A value given as comma-separated numbers (`0.5,-2,1.2`, spaces allowed),
/// as flags such as a point or an offset take it; `None` unless every item
/// is a finite number.
pub fn comma_numbers(text: &str) -> Option<Vec<f64>> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_worded_as_the_config_file_names_them_by_default() {
        let e = InvalidSetting::new(Key::setting("detect", "image_size"), 33, "a multiple of 32");
        assert_eq!(
            e.to_string(),
            "[detect] image_size must be a multiple of 32 (it is 33)"
        );
        assert_eq!(Key::input("--model").to_string(), "--model");
    }
}
