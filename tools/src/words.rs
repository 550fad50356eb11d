//! How the command line says the library's errors: options as flags (each option's own, from its
//! [`OptionName`]: `ProjectedOptions.size` is `--em-size`), and an error chain as one line in
//! which every library error that names options is worded so.

use lensmap::options::{OptionName, OptionWords, Worded};

/// Options as the command line's flags: each option's [`OptionName::flag`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Flags;

impl OptionWords for Flags {
    fn option(&self, name: OptionName) -> String {
        match name.flag {
            Some(flag) => format!("--{flag}"),
            // An option no flag sets (the tests keep the table and the flags in step).
            None => format!("`{}.{}`", name.owner, name.field),
        }
    }

    fn setting(&self, name: OptionName, value: &str) -> String {
        format!("{} {value}", self.option(name))
    }

    fn call(&self, call: &str) -> String {
        format!("lensmap {call}")
    }

    fn switch_on(&self, name: OptionName) -> String {
        format!("pass {}", self.option(name))
    }

    fn bake_command(&self, scene: Option<&str>) -> Option<String> {
        Some(format!(
            "lensmap bake --scene {} --out DIR",
            scene.unwrap_or("S")
        ))
    }
}

/// A look at whether an error is one of the library's errors that name options.
type Downcast = for<'a> fn(&'a (dyn std::error::Error + 'static)) -> Option<&'a dyn Worded>;

/// `cause` as a [`Worded`] error, when it is a `T`.
fn downcast<'a, T: Worded + 'static>(
    cause: &'a (dyn std::error::Error + 'static),
) -> Option<&'a dyn Worded> {
    cause.downcast_ref::<T>().map(|e| e as &dyn Worded)
}

/// The library's errors that name options.
/// The library's errors that name options, and those that wrap them: a `#[error(transparent)]`
/// wrapper's source is its inner error's source, so the chain shows the wrapper, never the inner
/// error, and the wrapper words it.
const WORDED_ERRORS: [Downcast; 11] = [
    downcast::<lensmap::options::OptionError>,
    downcast::<lensmap::render::RenderError>,
    downcast::<lensmap::render::CompositingError>,
    downcast::<lensmap::render::FramebufferError>,
    downcast::<lensmap::render::MapBudgetError>,
    downcast::<lensmap::hybrid::BakeIdentityError>,
    downcast::<lensmap::hybrid::HybridError>,
    downcast::<lensmap::runner::RunError>,
    downcast::<lensmap_baker::bake::BakeInputError>,
    downcast::<lensmap_baker::bake::MergeError>,
    downcast::<lensmap_baker::bake::BakeFailure>,
];

/// `cause` in the command line's words, where it is a library error that names options.
fn worded(cause: &(dyn std::error::Error + 'static)) -> Option<String> {
    WORDED_ERRORS
        .into_iter()
        .find_map(|as_worded| as_worded(cause))
        .map(|error| error.worded(&Flags))
}

/// The error chain in one line, in the command line's words: each cause once (a cause whose text
/// its outer message already holds, as a `#[error(transparent)]` or a `{0}` wrapper repeats it, is
/// not said again; where the outer message holds it in the library's words, those are replaced).
pub fn error_line(error: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for cause in error.chain() {
        let text = cause.to_string();
        let said = worded(cause).unwrap_or_else(|| text.clone());
        match parts.iter_mut().find(|outer| outer.contains(&text)) {
            Some(outer) => *outer = outer.replace(&text, &said),
            None => {
                if !parts.iter().any(|outer| outer.contains(&said)) {
                    parts.push(said);
                }
            }
        }
    }
    parts.join(": ")
}

#[cfg(test)]
mod tests {
    use super::error_line;

    /// Every long flag of every command (subcommands included), without its dashes.
    fn flags(command: &clap::Command, into: &mut std::collections::BTreeSet<String>) {
        into.extend(
            command
                .get_arguments()
                .filter_map(|a| a.get_long())
                .map(String::from),
        );
        for sub in command.get_subcommands() {
            flags(sub, into);
        }
    }

    /// Front ends → library: every option the library and the baker name has the flag its
    /// name gives on some command, so a message never tells a user to pass a flag that does
    /// not exist.
    #[test]
    fn every_options_flag_is_a_flag_of_the_command_line() {
        use clap::CommandFactory;
        let mut all = std::collections::BTreeSet::new();
        flags(&crate::Cli::command(), &mut all);
        let options = lensmap::options::names::ALL
            .iter()
            .chain(lensmap_baker::bake::names::ALL);
        let missing: Vec<String> = options
            .filter_map(|option| option.flag.filter(|flag| !all.contains(*flag)))
            .map(|flag| format!("--{flag}"))
            .collect();
        assert!(missing.is_empty(), "flags no command has: {missing:?}");
    }
    use lensmap::render::{MapBudgetError, MapBytes, RenderError};

    /// Maps over the device's budget, in the command line's words: the flags that shrink them.
    #[test]
    fn maps_over_the_budget_name_the_flags() {
        let error = anyhow::Error::from(RenderError::from(MapBudgetError {
            maps: MapBytes {
                cube_maps: 9,
                largest_em_size: 512,
                layered_em_bytes: 9 * 6 * 16 * 349_525,
                light_maps: 1,
                light_map_texels: 1 << 22,
                light_map_bytes: 8 << 22,
            },
            budget: 200 << 20,
        }))
        .context("rendering teapot-room");
        let line = error_line(&error);
        assert!(
            line.starts_with("rendering teapot-room: frame input: the frame's maps need 320.0 MiB")
                && line.contains(
                    "budget for maps of 200.0 MiB (20% of its largest device-local heap)"
                )
                && line.contains("a smaller --em-size")
                && line.contains("a smaller --light-map-max-texels")
                && !line.contains('`'),
            "{line}"
        );
    }
}
