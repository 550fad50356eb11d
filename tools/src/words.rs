//! How the command line says the library's errors: options as flags (`em_size` is `--em-size`),
//! and an error chain as one line in which every library error that names options is worded so.

use lensmap::options::{OptionWords, Worded};

/// Options as the command line's flags: the field name with `_` written `-`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Flags;

impl OptionWords for Flags {
    fn option(&self, field: &str) -> String {
        format!("--{}", field.replace('_', "-"))
    }

    fn setting(&self, field: &str, value: &str) -> String {
        format!("{} {value}", self.option(field))
    }

    fn call(&self, call: &str) -> String {
        format!("lensmap {call}")
    }

    fn switch_on(&self, field: &str) -> String {
        format!("pass {}", self.option(field))
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
    downcast::<lensmap::render::ProgramError>,
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
