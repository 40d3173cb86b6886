//! One vocabulary for the settings that the command line, scene files, JSON output and the demo
//! panel all name. Each enum derives serde with lowercase names (and `clap::ValueEnum`, whose
//! names are the same, with the `clap` feature); this module gives them a `Display` that prints
//! that serde name, so no second table of strings exists.

/// `impl Display` printing the value's serde name (`Strategy::Paper` -> `paper`), so
/// `to_string()`, `format!`, scene files and the CLI's `--help` always agree.
#[macro_export]
#[doc(hidden)]
macro_rules! display_as_serde_name {
    ($t:ty) => {
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                match $crate::vocab::serde_name(self) {
                    Some(name) => f.write_str(&name),
                    None => write!(f, "{self:?}"),
                }
            }
        }
    };
}

/// The name serde gives a unit variant (a JSON string), `None` for any other shape.
#[doc(hidden)]
pub fn serde_name<T: serde::Serialize>(value: &T) -> Option<String> {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(s)) => Some(s),
        _ => None,
    }
}
