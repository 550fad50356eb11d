//! Every numeric option of every command (as `lensmap option-tree` lists clap's tree), tried
//! with 0, 1, 2³², 2⁶⁴ − 1, −1, NaN and, where its help states a range, its maximum plus one,
//! under `--validate-only` (every check, no work): each value is accepted (exit 0) or refused
//! with exit 2 and one line naming the option; never a panic, an abort or a signal. And every
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
    help: String,
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
                help: v["help"].as_str().unwrap().to_owned(),
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

/// The largest value the help states: `… to B`, `[A, B]` or `A..=B`.
fn stated_maximum(help: &str) -> Option<f64> {
    let number = |s: &str| {
        s.trim_matches(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
            .replace(['_', ','], "")
            .parse::<f64>()
            .ok()
    };
    let words: Vec<&str> = help.split_whitespace().collect();
    for (i, w) in words.iter().enumerate() {
        if *w == "to"
            && i > 0
            && number(words[i - 1]).is_some()
            && let Some(b) = words.get(i + 1).and_then(|b| number(b))
        {
            return Some(b);
        }
    }
    None
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

/// Whether `outcome` was accepted, or refused in one line naming `option` with exit 2.
fn judged(outcome: &Outcome, option: &str) -> Result<(), String> {
    let lines: Vec<&str> = outcome
        .stderr
        .lines()
        .filter(|l| !l.starts_with("warning:"))
        .collect();
    match outcome.code {
        Some(0) => Ok(()),
        Some(2) if lines.len() == 1 && lines[0].contains(&format!("--{option}")) => Ok(()),
        code => Err(format!(
            "lensmap {} --validate-only: exit {code:?}, stderr {:?}",
            outcome.args.join(" "),
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
    let mut cases = Vec::new();
    let mut about = Vec::new();
    let mut without_range = Vec::new();
    for o in &numeric {
        let mut tried: Vec<String> = values.iter().map(|v| (*v).to_owned()).collect();
        match stated_maximum(&o.help) {
            Some(max) => tried.push(format!("{}", max + 1.0)),
            None => without_range.push(format!("{} --{}", o.command.join(" "), o.option)),
        }
        for value in tried {
            let mut args = base(&o.command, &o.needs, &work);
            args.push(format!("--{}={value}", o.option));
            cases.push(args);
            about.push(o.option.clone());
        }
    }
    // Each option that needs a mode, given without it.
    let moded: Vec<&TreeOption> = options.iter().filter(|o| !o.needs.is_empty()).collect();
    let mut mode_cases = Vec::new();
    for o in &moded {
        let mut args = base(&o.command, &[], &work);
        args.push(format!("--{}", o.option));
        if o.kind != "flag" {
            args.push(if o.kind == "text" {
                "1,1,1".into()
            } else {
                "1".into()
            });
        }
        mode_cases.push(args);
    }
    let outcomes = run_all(cases.clone());
    let mut failures: Vec<String> = outcomes
        .iter()
        .zip(&about)
        .filter_map(|(outcome, option)| judged(outcome, option).err())
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
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
