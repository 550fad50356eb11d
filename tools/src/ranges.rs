//! The range of every numeric option, stated once in its help and enforced from there: a numeric
//! option's help ends with `Range: R.`, where R is an interval (`[1, 16384]`, `(0, 180)`,
//! `[0, ∞)`), a set (`one of 12, 42, 162`) or `any` (every value of its type, for seeds). A value
//! given outside it is refused with exit 2 in one line naming the option and the range, before
//! any command runs; NaN lies in no range, and ∞ only where the help closes an interval on it.
//! Limits that join two options (width × supersampling ≤ 16384 subpixels a side) stay with the
//! command, which says them in the same help. The option walk (tools/tests/option_walk.rs) tries
//! every numeric option against its stated range, so a new option cannot go without one.
//!
//! (clap's `value_parser!(u32).range(…)` does not serve: it takes integers only, and its bound
//! is not visible in the help or to the walk, so the two could drift apart.)

use clap::parser::ValueSource;
use clap::{Arg, ArgMatches, Command};

/// One end of an interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// The value (±∞ for an open end).
    pub value: f64,
    /// Whether the value itself is in the range.
    pub inclusive: bool,
}

/// What a numeric option accepts.
#[derive(Clone, Debug, PartialEq)]
pub enum Range {
    /// Every value between the two ends.
    Interval(Bound, Bound),
    /// Exactly these values.
    OneOf(Vec<f64>),
    /// Every value of the option's type.
    Any,
}

impl Range {
    /// Whether `value` lies in the range (NaN never does).
    pub fn contains(&self, value: f64) -> bool {
        match self {
            Range::Interval(low, high) => {
                let above = if low.inclusive {
                    value >= low.value
                } else {
                    value > low.value
                };
                let below = if high.inclusive {
                    value <= high.value
                } else {
                    value < high.value
                };
                above && below
            }
            Range::OneOf(values) => values.contains(&value),
            Range::Any => !value.is_nan(),
        }
    }
}

impl Range {
    /// The range as `lensmap option-tree` prints it: `{"low", "low_inclusive", "high",
    /// "high_inclusive"}` (null for an infinite end), `{"one_of": […]}` or `"any"`.
    pub fn to_json(&self) -> serde_json::Value {
        let end = |b: &Bound| b.value.is_finite().then_some(b.value);
        match self {
            Range::Interval(low, high) => serde_json::json!({
                "low": end(low),
                "low_inclusive": low.inclusive,
                "high": end(high),
                "high_inclusive": high.inclusive,
            }),
            Range::OneOf(values) => serde_json::json!({ "one_of": values }),
            Range::Any => serde_json::json!("any"),
        }
    }
}

/// A number of a range: digits, `∞`, `-∞`, or a power `2^N`.
fn number(text: &str) -> Option<f64> {
    let text = text.trim().replace('_', "");
    match text.as_str() {
        "∞" => Some(f64::INFINITY),
        "-∞" | "−∞" => Some(f64::NEG_INFINITY),
        _ => match text.split_once('^') {
            Some(("2", power)) => power.parse::<i32>().ok().map(|p| 2f64.powi(p)),
            _ => text.parse::<f64>().ok().filter(|v| v.is_finite()),
        },
    }
}

/// The range a help states in its `Range: R.` sentence (see the module), if any.
pub fn stated(help: &str) -> Option<Range> {
    let (_, rest) = help.rsplit_once("Range: ")?;
    let text = rest.trim_end().trim_end_matches('.').trim();
    let text = text.split(" (").next().unwrap_or(text).trim();
    if text == "any" {
        return Some(Range::Any);
    }
    if let Some(list) = text.strip_prefix("one of ") {
        return list
            .split(',')
            .map(number)
            .collect::<Option<Vec<f64>>>()
            .map(Range::OneOf);
    }
    let low_inclusive = match text.chars().next()? {
        '[' => true,
        '(' => false,
        _ => return None,
    };
    let high_inclusive = match text.chars().last()? {
        ']' => true,
        ')' => false,
        _ => return None,
    };
    let inner = &text[1..text.len() - 1];
    let (low, high) = inner.split_once(", ")?;
    let (low, high) = (number(low)?, number(high)?);
    // An end at infinity is never a value: `[0, ∞]` would admit `inf`.
    let infinite_end =
        (low_inclusive && low.is_infinite()) || (high_inclusive && high.is_infinite());
    (low <= high && !infinite_end).then_some(Range::Interval(
        Bound {
            value: low,
            inclusive: low_inclusive,
        },
        Bound {
            value: high,
            inclusive: high_inclusive,
        },
    ))
}

/// Whether `arg` takes a number (an unsigned, signed or floating-point value).
pub fn is_numeric(arg: &Arg) -> bool {
    numeric_kind(arg).is_some()
}

/// `unsigned`, `signed` or `float` for an option that takes numbers; `None` otherwise.
pub fn numeric_kind(arg: &Arg) -> Option<&'static str> {
    use std::any::TypeId;
    if !arg.get_action().takes_values() {
        return None;
    }
    let id = arg.get_value_parser().type_id();
    let any = |types: &[TypeId]| types.iter().any(|t| id == *t);
    if any(&[
        TypeId::of::<u8>(),
        TypeId::of::<u16>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
    ]) {
        Some("unsigned")
    } else if any(&[TypeId::of::<i32>(), TypeId::of::<i64>()]) {
        Some("signed")
    } else if any(&[TypeId::of::<f32>(), TypeId::of::<f64>()]) {
        Some("float")
    } else {
        None
    }
}

/// Whether `arg` takes an f32.
fn is_f32(arg: &Arg) -> bool {
    arg.get_value_parser().type_id() == std::any::TypeId::of::<f32>()
}

/// The range `arg`'s help states, for a numeric option.
pub fn of(arg: &Arg) -> Option<Range> {
    let help = arg.get_long_help().or(arg.get_help())?.to_string();
    stated(&help)
}

/// The range as its help says it, for messages: the text after `Range: `.
fn said(arg: &Arg) -> String {
    let help = arg
        .get_long_help()
        .or(arg.get_help())
        .map(ToString::to_string)
        .unwrap_or_default();
    help.rsplit_once("Range: ")
        .map(|(_, r)| r.trim_end().trim_end_matches('.').to_owned())
        .unwrap_or_default()
}

/// Checks every numeric option given to the chosen command against its stated range.
pub fn check(command: &Command, matches: &ArgMatches) -> Result<(), clap::Error> {
    if let Some((name, sub)) = matches.subcommand()
        && let Some(subcommand) = command.find_subcommand(name)
    {
        return check(subcommand, sub);
    }
    for arg in command.get_arguments().filter(|a| is_numeric(a)) {
        let id = arg.get_id().as_str();
        if matches.value_source(id) != Some(ValueSource::CommandLine) {
            continue;
        }
        let (Some(range), Some(long)) = (of(arg), arg.get_long()) else {
            continue;
        };
        let Some(values) = matches.get_raw(id) else {
            continue;
        };
        for raw in values {
            let text = raw.to_string_lossy();
            // clap parsed it as the option's type, so it reads as a number (an unsigned one of
            // 2^64 − 1 rounds to 2^64, which no finite stated bound admits anyway). An f32
            // option is judged by the f32 it becomes: 1e39 is ∞ there, 1e-50 is 0.
            let value = if is_f32(arg) {
                text.trim().parse::<f32>().map_or(f64::NAN, f64::from)
            } else {
                text.trim().parse::<f64>().unwrap_or(f64::NAN)
            };
            if !range.contains(value) {
                return Err(clap::Error::raw(
                    clap::error::ErrorKind::ValueValidation,
                    format!(
                        "--{long} {text}: outside its range {}; give a value in it\n",
                        said(arg)
                    ),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    fn interval(low: f64, low_in: bool, high: f64, high_in: bool) -> Range {
        Range::Interval(
            Bound {
                value: low,
                inclusive: low_in,
            },
            Bound {
                value: high,
                inclusive: high_in,
            },
        )
    }

    #[test]
    fn ranges_are_read_from_the_help() {
        assert_eq!(
            stated("Frame width, pixels. Range: [1, 16384]."),
            Some(interval(1.0, true, 16384.0, true))
        );
        assert_eq!(
            stated("An angle. Range: (0, 180) (degrees)."),
            Some(interval(0.0, false, 180.0, false))
        );
        assert_eq!(
            stated("Range: [0, ∞)."),
            Some(interval(0.0, true, f64::INFINITY, false))
        );
        assert_eq!(
            stated("Range: [1, 2^26]."),
            Some(interval(1.0, true, 67108864.0, true))
        );
        assert_eq!(
            stated("Views. Range: one of 12, 42, 162."),
            Some(Range::OneOf(vec![12.0, 42.0, 162.0]))
        );
        assert_eq!(stated("A seed. Range: any."), Some(Range::Any));
        assert_eq!(stated("No range here."), None);
        assert_eq!(stated("Range: [0, ∞]."), None, "∞ is never a value");
        assert_eq!(stated("Range: [5, 1]."), None);
    }

    #[test]
    fn values_outside_a_range_and_nan_are_not_in_it() {
        let angle = interval(0.0, false, 180.0, false);
        assert!(angle.contains(1.0) && !angle.contains(0.0) && !angle.contains(180.0));
        assert!(!angle.contains(f64::NAN));
        let open = stated("Range: (0, ∞).").unwrap();
        assert!(open.contains(1e300) && !open.contains(f64::INFINITY));
        assert!(!Range::Any.contains(f64::NAN));
    }

    /// Every numeric option of every command states a range, and its default lies in it.
    #[test]
    fn every_numeric_option_states_a_range_that_holds_its_default() {
        fn walk(command: &Command, path: &str, problems: &mut Vec<String>) {
            for arg in command.get_arguments().filter(|a| is_numeric(a)) {
                let long = arg.get_long().unwrap_or("?");
                let Some(range) = of(arg) else {
                    problems.push(format!("{path} --{long}: no `Range:` in its help"));
                    continue;
                };
                for default in arg.get_default_values() {
                    let text = default.to_string_lossy();
                    let value = text.parse::<f64>().unwrap_or(f64::NAN);
                    if !range.contains(value) {
                        problems.push(format!(
                            "{path} --{long}: default {text} outside {}",
                            said(arg)
                        ));
                    }
                }
            }
            for sub in command.get_subcommands() {
                walk(sub, &format!("{path} {}", sub.get_name()), problems);
            }
        }
        let mut command = crate::Cli::command();
        command.build();
        let mut problems = Vec::new();
        walk(&command, "lensmap", &mut problems);
        assert!(problems.is_empty(), "{}", problems.join("\n"));
    }
}
