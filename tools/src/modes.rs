//! Options that one mode of a command reads and the others would ignore: refused where given
//! without that mode, by one rule that every option follows. An option whose help begins
//! `With --x:` (or `With --x or --y:`) is read only with `--x` (or `--y`); given on the command
//! line without any of them, it is refused with exit 2, naming it and the options it needs.
//! (clap's `requires` does not serve: it is not checked for an option with a default value,
//! which most of these have.) Options that a mode must not have say so with clap's
//! `conflicts_with`, whose message names both.

use clap::parser::ValueSource;
use clap::{ArgMatches, Command};

/// The options an option's help says it needs (`With --x or --y:` gives `["x", "y"]`); none
/// for help that does not begin so.
pub fn needed(help: &str) -> Vec<&str> {
    let Some(rest) = help.strip_prefix("With --") else {
        return Vec::new();
    };
    let Some((modes, _)) = rest.split_once(':') else {
        return Vec::new();
    };
    modes
        .split(" or --")
        .map(str::trim)
        .filter(|m| !m.is_empty() && m.chars().all(|c| c.is_ascii_alphanumeric() || c == '-'))
        .collect()
}

/// Whether the option `long` of `command` was given on the command line.
fn given(command: &Command, matches: &ArgMatches, long: &str) -> bool {
    command
        .get_arguments()
        .find(|a| a.get_long() == Some(long))
        .is_some_and(|a| {
            matches.value_source(a.get_id().as_str()) == Some(ValueSource::CommandLine)
        })
}

/// Checks the chosen command's options against the modes their help names (see the module).
pub fn check(command: &Command, matches: &ArgMatches) -> Result<(), clap::Error> {
    if let Some((name, sub)) = matches.subcommand()
        && let Some(subcommand) = command.find_subcommand(name)
    {
        return check(subcommand, sub);
    }
    for arg in command.get_arguments() {
        let (Some(long), Some(help)) = (arg.get_long(), arg.get_help()) else {
            continue;
        };
        let help = help.to_string();
        let needs = needed(&help);
        if needs.is_empty() || !given(command, matches, long) {
            continue;
        }
        if !needs.iter().any(|m| given(command, matches, m)) {
            let modes = needs
                .iter()
                .map(|m| format!("--{m}"))
                .collect::<Vec<_>>()
                .join(" or ");
            return Err(clap::Error::raw(
                clap::error::ErrorKind::MissingRequiredArgument,
                format!(
                    "--{long} applies only with {modes}, which the command line does not give; add {modes} or remove --{long}\n"
                ),
            ));
        }
    }
    Ok(())
}

/// Prints every option of `command` and its subcommands as JSON lines: the command's words,
/// the option's long name, the kind of value it takes (`unsigned`, `signed`, `float`, `flag`
/// or `text`), the options its help says it needs, its help, the range its help states
/// ([`crate::ranges`]; null where none), its default values and the options clap's
/// `conflicts_with` refuses beside it.
pub fn print_tree(command: &Command) {
    fn walk(command: &Command, path: &mut Vec<String>) {
        for arg in command.get_arguments() {
            let Some(long) = arg.get_long() else { continue };
            if matches!(long, "help" | "version") {
                continue;
            }
            let kind = if !arg.get_action().takes_values() {
                "flag"
            } else {
                crate::ranges::numeric_kind(arg).unwrap_or("text")
            };
            let help = arg
                .get_long_help()
                .or(arg.get_help())
                .map(ToString::to_string)
                .unwrap_or_default();
            let line = serde_json::json!({
                "command": path,
                "option": long,
                "kind": kind,
                "required": arg.is_required_set(),
                "needs": needed(&arg.get_help().map(ToString::to_string).unwrap_or_default()),
                "help": help,
                "range": crate::ranges::of(arg).map(|r| r.to_json()),
                "default": arg.get_default_values().iter().map(|d| d.to_string_lossy()).collect::<Vec<_>>(),
                "conflicts": command
                    .get_arg_conflicts_with(arg)
                    .iter()
                    .filter_map(|other| other.get_long())
                    .collect::<Vec<_>>(),
            });
            crate::common::write_stdout(format_args!("{line}"));
        }
        for sub in command.get_subcommands() {
            if sub.is_hide_set() || sub.get_name() == "help" {
                continue;
            }
            path.push(sub.get_name().to_owned());
            walk(sub, path);
            path.pop();
        }
    }
    let mut command = command.clone();
    command.build();
    walk(&command, &mut Vec::new());
}

#[cfg(test)]
mod tests {
    use super::needed;

    #[test]
    fn the_modes_an_option_needs_come_from_its_help() {
        assert_eq!(needed("With --compress: a keyframe every"), ["compress"]);
        assert_eq!(
            needed("With --record or --script: the path"),
            ["record", "script"]
        );
        assert!(needed("Views per sample, with --x: no").is_empty());
        assert!(needed("With the GPU tracer only").is_empty());
    }
}
