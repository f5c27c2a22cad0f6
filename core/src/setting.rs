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
    /// The structure to inspect, instead of a plan's target voxels.
    pub const TARGET_BOXES: Key = Key::input("--target-boxes");
    pub const TARGET_CLOUD: Key = Key::input("--target-cloud");
    pub const TARGET_MAP: Key = Key::input("--target-map");
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

/// Declares a stage's settings once: each field with its doc comment, its
/// command-line flag (`#[arg(long ...)]`) and, where it has one, its
/// default. From that one declaration come:
///
/// - `$Settings`, every field optional: the `postflight.toml` table
///   (serde, unknown keys refused) and the stage command's flags (clap);
/// - `$Resolved`, what the stage runs with: a field with a default is its
///   value, one without stays an `Option`;
/// - `$Settings::resolve`, `$Settings::over` (layering: `flags.over(&file)`)
///   and `From<$Resolved>` (a resolved value as settings, to layer over);
/// - the module `$keys`, one [`Key`] per field, named as the field, which
///   errors use to name the setting.
///
/// ```ignore
/// postflight_core::settings! {
///     table = "detect", keys = keys;
///     /// `[detect]`: how the detector runs.
///     pub struct DetectSettings => pub struct DetectConfig {
///         /// Lowest score kept.
///         #[arg(long, value_name = "SCORE")]
///         confidence: f32 = 0.25,
///     }
/// }
/// ```
#[macro_export]
macro_rules! settings {
    (
        table = $table:literal, keys = $keys:ident;
        $(#[$smeta:meta])*
        $vis:vis struct $Settings:ident => $(#[$rmeta:meta])* struct $Resolved:ident {
            $(
                $(#[$fmeta:meta])*
                $field:ident : $ty:ty $(= $default:expr)?
            ),* $(,)?
        }
    ) => {
        $(#[$smeta])*
        #[derive(Debug, Clone, Default, PartialEq, ::serde::Serialize, ::serde::Deserialize, ::clap::Args)]
        #[serde(default, deny_unknown_fields)]
        $vis struct $Settings {
            $(
                $(#[$fmeta])*
                pub $field: Option<$ty>,
            )*
        }

        $(#[$rmeta])*
        #[doc = concat!("\n\nEach field is the setting of the same name in [`", stringify!($Settings), "`], resolved: as given, else its default.")]
        #[derive(Debug, Clone, PartialEq, ::serde::Serialize, ::serde::Deserialize)]
        #[serde(default)]
        $vis struct $Resolved {
            $(
                #[allow(missing_docs)]
                pub $field: $crate::settings!(@resolved $ty $(, $default)?),
            )*
        }

        impl Default for $Resolved {
            fn default() -> Self {
                $Settings::default().resolve()
            }
        }

        impl $Settings {
            /// The table's name in `postflight.toml`.
            pub const TABLE: &'static str = $table;

            /// Each setting as given, else its default.
            pub fn resolve(&self) -> $Resolved {
                $Resolved {
                    $( $field: $crate::settings!(@value self.$field.clone() $(, $default)?), )*
                }
            }

            /// Each setting from `self` where given, else from `under`
            /// (`flags.over(&file)`).
            pub fn over(&self, under: &Self) -> Self {
                Self {
                    $( $field: self.$field.clone().or_else(|| under.$field.clone()), )*
                }
            }
        }

        impl From<$Resolved> for $Settings {
            fn from(resolved: $Resolved) -> Self {
                Self {
                    $( $field: $crate::settings!(@given resolved.$field $(, $default)?), )*
                }
            }
        }

        /// Each setting's key, named as its field.
        #[allow(non_upper_case_globals)]
        $vis mod $keys {
            $(
                pub const $field: $crate::Key = $crate::Key::setting($table, stringify!($field));
            )*
        }
    };
    (@resolved $ty:ty) => { Option<$ty> };
    (@resolved $ty:ty, $default:expr) => { $ty };
    (@value $value:expr) => { $value };
    (@value $value:expr, $default:expr) => { $value.unwrap_or_else(|| $default) };
    (@given $value:expr) => { $value };
    (@given $value:expr, $default:expr) => { Some($value) };
}

/// A value given as a TOML inline table (a flag's: `--keep-out-zone
/// '{name = "deck", ...}'`), read as `T`; `what` says what was expected.
pub fn inline_table<T: serde::de::DeserializeOwned>(text: &str, what: &str) -> Result<T, String> {
    #[derive(serde::Deserialize)]
    struct One<T> {
        value: T,
    }
    toml::from_str::<One<T>>(&format!("value = {text}"))
        .map(|one| one.value)
        .map_err(|e| format!("expected {what}: {}", e.message()))
}

/// A setting whose value is a table (`[[replan.keep_out]]` entries) also
/// read from its flag as a TOML inline table (`--keep-out-zone '{name =
/// "deck", ...}'`): `FromStr` through [`inline_table`], `what` saying what
/// the value looks like when it cannot be read.
#[macro_export]
macro_rules! inline_table_setting {
    ($ty:ty, $what:literal) => {
        impl ::std::str::FromStr for $ty {
            type Err = String;

            fn from_str(text: &str) -> Result<Self, String> {
                $crate::setting::inline_table(text, $what)
            }
        }
    };
}

/// A point given as `X,Y,Z` in metres (`--home`).
pub fn point3(text: &str) -> Result<[f64; 3], String> {
    match comma_numbers(text).as_deref() {
        Some(&[x, y, z]) => Ok([x, y, z]),
        _ => Err(format!(
            "expected three numbers X,Y,Z in metres, not '{text}'"
        )),
    }
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
