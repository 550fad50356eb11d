//! Every numeric option of every command (as `lensmap option-tree` lists clap's tree) states
//! its range in its help (`Range: [1, 16384].`, tools/src/ranges.rs), and is tried with 0, 1,
//! 2³², 2⁶⁴ − 1, −1 and NaN, with values just outside each end of its range, and with its
//! default, under `--validate-only` (every check, no work): each value is accepted (exit 0) or
//! refused with exit 2 and one line naming the option, never a panic, an abort or a signal; a
//! value outside the range is always refused, and the default always accepted. And every
//! option whose help says `With --x:` is refused without `--x`, naming both. An option added
//! later is in the tree, so in the walk.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// One option as `lensmap option-tree` prints it.
struct TreeOption {
    command: Vec<String>,
    option: String,
    kind: String,
    needs: Vec<String>,
    /// The range its help states (`lensmap option-tree`'s `range`; null where none).
    range: Value,
    /// Its default values.
    defaults: Vec<String>,
    /// The options clap refuses beside it (`conflicts_with`).
    conflicts: Vec<String>,
}

fn tree() -> Vec<TreeOption> {
    let out = Command::new(env!("CARGO_BIN_EXE_lensmap"))
        .arg("option-tree")
        .output()
        .expect("lensmap runs");
    assert!(out.status.success());
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|line| {
            let v: Value = serde_json::from_str(line).unwrap();
            let strings = |key: &str| -> Vec<String> {
                v[key]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|s| s.as_str().unwrap().to_owned())
                    .collect()
            };
            TreeOption {
                command: strings("command"),
                option: v["option"].as_str().unwrap().to_owned(),
                kind: v["kind"].as_str().unwrap().to_owned(),
                needs: strings("needs"),
                range: v["range"].clone(),
                defaults: strings("default"),
                conflicts: strings("conflicts"),
            }
        })
        .collect()
}

/// What a command needs on its command line to reach its checks of `option`: its required
/// options, and the mode `option` applies in.
fn base(command: &[String], needs: &[String], work: &Path) -> Vec<String> {
    let out = |name: &str| work.join(name).display().to_string();
    let words: Vec<&str> = command.iter().map(String::as_str).collect();
    let mut args: Vec<String> = match words[..] {
        ["reference"] => vec![
            "--scene".into(),
            "glass-sphere".into(),
            "--out".into(),
            out("reference"),
        ],
        ["render" | "view"] => vec![
            "--scene".into(),
            "glass-sphere".into(),
            "--projected".into(),
        ],
        ["bake"] if needs.iter().any(|n| n == "compress") => vec!["--compress".into(), out("bake")],
        ["bake"] if needs.iter().any(|n| n == "radiance-maps") => vec![
            "--radiance-maps".into(),
            "--scene".into(),
            "glossy-studio".into(),
            "--out".into(),
            out("radiance"),
        ],
        ["bake"] => vec![
            "--scene".into(),
            "glass-sphere".into(),
            "--out".into(),
            out("bake"),
        ],
        ["bench", "bake"] => vec!["--bake".into(), out("no-bake")],
        _ => Vec::new(),
    };
    for need in needs {
        let flag = format!("--{need}");
        if !args.contains(&flag) {
            args.push(flag);
            // The value a mode's option takes, where it takes one.
            match need.as_str() {
                "scene" => args.push("glass-sphere".into()),
                "record" => args.push(out("view")),
                _ => {}
            }
        }
    }
    let mut all: Vec<String> = command.to_vec();
    all.append(&mut args);
    all
}

/// Values just outside `range` (as `option-tree` prints it) for an option of `kind`: below
/// and above each finite end (the end itself where it is open), and between two members of a
/// set; plus ∞ and NaN for floats, which no range holds.
fn outside(range: &Value, kind: &str) -> Vec<String> {
    let float = kind == "float";
    let mut values = Vec::new();
    if float {
        values.extend(["inf".to_owned(), "NaN".to_owned()]);
    }
    let step = |v: f64| if float { 1e-6 * v.abs().max(1.0) } else { 1.0 };
    let push = |values: &mut Vec<String>, v: f64| {
        if float || v >= 0.0 || kind == "signed" {
            values.push(if float {
                format!("{v:e}")
            } else {
                format!("{v}")
            });
        }
    };
    if let Some(members) = range["one_of"].as_array() {
        let members: Vec<f64> = members.iter().filter_map(Value::as_f64).collect();
        let (low, high) = (members[0], members[members.len() - 1]);
        push(&mut values, low - step(low));
        push(&mut values, high + step(high));
        if members.len() > 1 && members[1] - members[0] > 1.0 {
            push(&mut values, members[0] + 1.0);
        }
    } else if range.is_object() {
        if let Some(low) = range["low"].as_f64() {
            if range["low_inclusive"] == true {
                push(&mut values, low - step(low));
            } else {
                push(&mut values, low);
            }
        }
        if let Some(high) = range["high"].as_f64() {
            if range["high_inclusive"] == true {
                push(&mut values, high + step(high));
            } else {
                push(&mut values, high);
            }
        }
    }
    values
}

struct Outcome {
    args: Vec<String>,
    code: Option<i32>,
    stderr: String,
}

fn run(args: &[String]) -> Outcome {
    let out = Command::new(env!("CARGO_BIN_EXE_lensmap"))
        .args(args)
        .arg("--validate-only")
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("lensmap runs");
    Outcome {
        args: args.to_vec(),
        code: out.status.code(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn work_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensmap-option-walk-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `cases` on two threads, in order of the cases.
fn run_all(cases: Vec<Vec<String>>) -> Vec<Outcome> {
    let chunks: Vec<Vec<Vec<String>>> = cases
        .chunks(cases.len().div_ceil(2).max(1))
        .map(<[_]>::to_vec)
        .collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = chunks
            .iter()
            .map(|chunk| scope.spawn(move || chunk.iter().map(|c| run(c)).collect::<Vec<_>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    })
}

/// What a value must get.
#[derive(Clone, Copy, PartialEq)]
enum Expect {
    /// Accepted or refused (naming the option).
    Either,
    /// Refused: it lies outside the range the option's help states.
    Refused,
    /// Accepted: it is the option's default.
    Accepted,
}

/// Whether `outcome` was accepted, or refused in one line naming `option` with exit 2, as
/// `expect` allows.
fn judged(outcome: &Outcome, option: &str, expect: Expect) -> Result<(), String> {
    let lines: Vec<&str> = outcome
        .stderr
        .lines()
        .filter(|l| !l.starts_with("warning:"))
        .collect();
    let refused = lines.len() == 1 && lines[0].contains(&format!("--{option}"));
    match (outcome.code, expect) {
        (Some(0), Expect::Either | Expect::Accepted) => Ok(()),
        (Some(2), Expect::Either | Expect::Refused) if refused => Ok(()),
        (code, _) => Err(format!(
            "lensmap {} --validate-only: exit {code:?}{}, stderr {:?}",
            outcome.args.join(" "),
            match expect {
                Expect::Refused => " (outside the stated range: must be exit 2)",
                Expect::Accepted => " (the default: must be accepted)",
                Expect::Either => "",
            },
            outcome.stderr.trim()
        )),
    }
}

#[test]
fn every_numeric_option_is_bounded_and_every_mode_option_needs_its_mode() {
    let work = work_dir();
    let options = tree();
    let numeric: Vec<&TreeOption> = options
        .iter()
        .filter(|o| matches!(o.kind.as_str(), "unsigned" | "float"))
        .collect();
    assert!(numeric.len() > 100, "{} numeric options", numeric.len());
    let values = ["0", "1", "4294967296", "18446744073709551615", "-1", "NaN"];
    // (args, option, whether the value lies outside the option's stated range, or is its
    // default and must be accepted)
    let mut cases = Vec::new();
    let mut about: Vec<(String, Expect)> = Vec::new();
    let mut without_range = Vec::new();
    for o in &numeric {
        let mut tried: Vec<(String, Expect)> = values
            .iter()
            .map(|v| ((*v).to_owned(), Expect::Either))
            .collect();
        if o.range.is_null() {
            without_range.push(format!("{} --{}", o.command.join(" "), o.option));
        }
        tried.extend(
            outside(&o.range, &o.kind)
                .into_iter()
                .map(|v| (v, Expect::Refused)),
        );
        tried.extend(o.defaults.iter().map(|d| (d.clone(), Expect::Accepted)));
        for (value, expect) in tried {
            let mut args = base(&o.command, &o.needs, &work);
            args.push(format!("--{}={value}", o.option));
            cases.push(args);
            about.push((o.option.clone(), expect));
        }
    }
    // Each option that needs a mode, given without it.
    let moded: Vec<&TreeOption> = options.iter().filter(|o| !o.needs.is_empty()).collect();
    let mut mode_cases = Vec::new();
    for o in &moded {
        let mut args = base(&o.command, &[], &work);
        args.push(format!("--{}", o.option));
        if o.kind != "flag" {
            // A value it takes, so that the mode is what is refused: its default, else a guess.
            args.push(match o.defaults.first() {
                Some(default) => default.clone(),
                None if o.kind == "text" => "1,1,1".into(),
                None => "1".into(),
            });
        }
        mode_cases.push(args);
    }
    let outcomes = run_all(cases.clone());
    let mut failures: Vec<String> = outcomes
        .iter()
        .zip(&about)
        .filter_map(|(outcome, (option, expect))| judged(outcome, option, *expect).err())
        .collect();
    let mode_outcomes = run_all(mode_cases);
    for (outcome, o) in mode_outcomes.iter().zip(&moded) {
        let named = o
            .needs
            .iter()
            .all(|n| outcome.stderr.contains(&format!("--{n}")));
        if outcome.code != Some(2) || !outcome.stderr.contains(&format!("--{}", o.option)) || !named
        {
            failures.push(format!(
                "lensmap {}: given without {:?}, exit {:?}: {}",
                outcome.args.join(" "),
                o.needs,
                outcome.code,
                outcome.stderr.trim()
            ));
        }
    }
    let accepted = outcomes.iter().filter(|o| o.code == Some(0)).count();
    println!(
        "{} (command, option, value) triples over {} numeric options: {accepted} accepted, {} refused; {} options needing a mode tried without it; {} numeric options state no range: {}",
        outcomes.len(),
        numeric.len(),
        outcomes.len() - accepted,
        moded.len(),
        without_range.len(),
        without_range.join(", ")
    );
    let _ = std::fs::remove_dir_all(&work);
    failures.extend(
        without_range
            .iter()
            .map(|o| format!("lensmap {o}: its help states no `Range:`")),
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// `--option` and a value it parses (its default, or one of its kind), as arguments.
fn given(o: &TreeOption) -> Vec<String> {
    let mut args = vec![format!("--{}", o.option)];
    if o.kind != "flag" {
        args.push(match (o.defaults.first(), o.kind.as_str()) {
            (Some(default), _) => default.clone(),
            (None, "text") => "1,1,1".into(),
            (None, _) => "1".into(),
        });
    }
    args
}

/// Every pair of options clap's `conflicts_with` declares (the options a mode cannot take, as
/// docs/cli.md lists them) given together is refused with exit 2 in one line naming both.
#[test]
fn every_pair_that_does_not_go_together_is_refused_naming_both() {
    let options = tree();
    let find = |command: &[String], long: &str| {
        options
            .iter()
            .find(|o| o.command == command && o.option == long)
    };
    let mut pairs: Vec<(&TreeOption, &TreeOption)> = Vec::new();
    for o in &options {
        for other in &o.conflicts {
            let b = find(&o.command, other).expect("a conflict names an option of the command");
            let seen = pairs.iter().any(|(x, y)| {
                (x.option == b.option && y.option == o.option && x.command == o.command)
                    || (x.option == o.option && y.option == b.option && x.command == o.command)
            });
            if !seen {
                pairs.push((o, b));
            }
        }
    }
    assert!(pairs.len() >= 30, "{} pairs", pairs.len());
    let cases: Vec<Vec<String>> = pairs
        .iter()
        .map(|(a, b)| {
            let mut args = a.command.clone();
            args.extend(given(a));
            args.extend(given(b));
            args
        })
        .collect();
    let failures: Vec<String> = run_all(cases)
        .iter()
        .zip(&pairs)
        .filter(|(outcome, (a, b))| {
            outcome.code != Some(2)
                || outcome.stderr.trim().lines().count() != 1
                || !outcome.stderr.contains(&format!("--{}", a.option))
                || !outcome.stderr.contains(&format!("--{}", b.option))
        })
        .map(|(outcome, _)| {
            format!(
                "lensmap {}: exit {:?}, stderr {:?}",
                outcome.args.join(" "),
                outcome.code,
                outcome.stderr.trim()
            )
        })
        .collect();
    println!("{} pairs that clap refuses together tried", pairs.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
