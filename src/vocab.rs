//! One vocabulary for the settings that the command line, scene files, JSON output and the demo
//! panel all name. Each enum derives `clap::ValueEnum` and serde with lowercase names; this module
//! gives them a `Display` that prints that same name, so no second table of strings exists.

/// `impl Display` printing a `clap::ValueEnum`'s own name for the value (`Strategy::Paper` ->
/// `paper`), so `to_string()`, `format!` and the CLI's `--help` always agree.
macro_rules! display_as_value_enum {
    ($t:ty) => {
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                let v = clap::ValueEnum::to_possible_value(self)
                    .expect("every variant has a name (none is skipped)");
                f.write_str(v.get_name())
            }
        }
    };
}
pub(crate) use display_as_value_enum;
