//! Options out of range, and how messages name options. Every option check in the library returns
//! an [`OptionError`] naming the option by its field name in the library's options struct, the
//! value and what to give instead. A message that names options (an option error, or advice such
//! as "set `accept_any_bake`") is written through [`OptionWords`], so each front end says it in its
//! own terms: the library's [`Display`](std::fmt::Display) uses the field names, the command line
//! its flags, the C ABI its struct fields.

use std::borrow::Cow;

/// How a front end names the library's options in messages.
pub trait OptionWords {
    /// The option whose field in the library's options struct is `field` (`em_size`,
    /// `accept_any_bake`).
    fn option(&self, field: &str) -> String;

    /// The option `field` given `value`.
    fn setting(&self, field: &str, value: &str) -> String {
        format!("{} = {value}", self.option(field))
    }

    /// The library's entry point `call` (a function such as `bake`), for messages that say
    /// what to run: by default the function's name in backquotes; the command line names its
    /// command.
    fn call(&self, call: &str) -> String {
        format!("`{call}`")
    }

    /// Advice to turn on the switch `field` (`accept_any_bake`): "set `accept_any_bake`".
    fn switch_on(&self, field: &str) -> String {
        format!("set {}", self.option(field))
    }

    /// The command that bakes scene `scene` (`None`: the scene being loaded, unnamed) where this
    /// front end has one (the command line's); `None` where baking is a call of the library.
    fn bake_command(&self, scene: Option<&str>) -> Option<String> {
        let _ = scene;
        None
    }
}

/// The library's own words: options by their field names, in backquotes (`` `em_size` ``).
#[derive(Clone, Copy, Debug, Default)]
pub struct LibraryWords;

impl OptionWords for LibraryWords {
    fn option(&self, field: &str) -> String {
        format!("`{field}`")
    }
}

/// An error whose message names options: [`Worded::worded`] says it in a front end's terms, and
/// its `Display` is the same message in [`LibraryWords`].
pub trait Worded: std::error::Error {
    /// The message, with options named by `words`.
    fn worded(&self, words: &dyn OptionWords) -> String;
}

/// An option value the library cannot use.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub struct OptionError {
    /// The option's field name in the library's options struct (`t`, `angle_degrees`, `em_size`).
    pub option: &'static str,
    /// The value given, as text.
    pub value: String,
    /// What to give instead (the valid range, with an example).
    pub fix: Cow<'static, str>,
}

impl OptionError {
    /// The error for `option` = `value`, with `fix` saying what to give instead.
    pub fn new(
        option: &'static str,
        value: impl ToString,
        fix: impl Into<Cow<'static, str>>,
    ) -> OptionError {
        OptionError {
            option,
            value: value.to_string(),
            fix: fix.into(),
        }
    }

    /// `Ok` when `valid`, else the error for `option` = `value` with `fix`: the shape of every
    /// option check.
    pub fn require(
        valid: bool,
        option: &'static str,
        value: impl ToString,
        fix: impl Into<Cow<'static, str>>,
    ) -> Result<(), OptionError> {
        if valid {
            Ok(())
        } else {
            Err(OptionError::new(option, value, fix))
        }
    }
}

impl Worded for OptionError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        format!("{}: {}", words.setting(self.option, &self.value), self.fix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Flags;
    impl OptionWords for Flags {
        fn option(&self, field: &str) -> String {
            format!("--{}", field.replace('_', "-"))
        }
        fn setting(&self, field: &str, value: &str) -> String {
            format!("{} {value}", self.option(field))
        }
    }

    #[test]
    fn an_option_error_is_worded_by_each_front_end() {
        let error = OptionError::new("em_size", 7, "give a power of two, e.g. 128");
        assert_eq!(
            error.to_string(),
            "`em_size` = 7: give a power of two, e.g. 128"
        );
        assert_eq!(
            error.worded(&Flags),
            "--em-size 7: give a power of two, e.g. 128"
        );
    }
}
