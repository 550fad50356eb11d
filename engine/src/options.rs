//! A per-call option out of its range: the one error type every option check in the library
//! returns (tessellation threshold, angle threshold, projected EM size), naming the option, the
//! value and the fix. Front ends map the option name to their own spelling (the command line's
//! flags are the names with `_` written `-`).

/// An option value the library cannot use.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{option} = {value}: {fix}")]
pub struct OptionError {
    /// The option's name in the library (`t`, `angle_degrees`, `em_size`).
    pub option: &'static str,
    /// The value given, as text.
    pub value: String,
    /// What to give instead.
    pub fix: &'static str,
}

impl OptionError {
    /// `Ok` when `valid`, else the error for `option` = `value` with `fix`: the shape of every
    /// option check.
    pub fn require(
        valid: bool,
        option: &'static str,
        value: impl ToString,
        fix: &'static str,
    ) -> Result<(), OptionError> {
        if valid {
            Ok(())
        } else {
            Err(OptionError {
                option,
                value: value.to_string(),
                fix,
            })
        }
    }
}
