//! The command-line conventions every command keeps: `--json` means the same everywhere (one JSON
//! document on stdout and nothing else there; an error as one JSON line on stderr), `--quiet`
//! silences all but errors and warnings, every `--help` carries an example, the exit codes and the
//! environment variables, and progress shows the stages on a terminal.

mod common;
use common::{TINY_RENDER, lensmap};

use std::path::PathBuf;

/// `render` of glass-sphere at [`common::TINY_RENDER`]'s size, then `extra`.
fn tiny_render<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let base = ["render", "--scene", "glass-sphere"];
    base.iter()
        .chain(&TINY_RENDER)
        .chain(extra)
        .copied()
        .collect()
}

/// `bench passes` small enough for CI.
const TINY_BENCH: [&str; 10] = [
    "bench",
    "passes",
    "--width",
    "16",
    "--height",
    "12",
    "--frames",
    "1",
    "--max-layers",
    "1",
];

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("conventions", name)
}

fn with<'a>(base: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
    base.iter().chain(extra).copied().collect()
}

/// Every command, as a user types it.
const COMMANDS: [&[&str]; 12] = [
    &["demo"],
    &["passes"],
    &["reference"],
    &["render"],
    &["bake"],
    &["bench", "passes"],
    &["bench", "hybrid"],
    &["bench", "trace"],
    &["bench", "infer"],
    &["bench", "bake"],
    &["bench", "fresnel"],
    &["bench", "classes"],
];

#[test]
fn every_help_has_an_example_the_exit_codes_and_the_environment() {
    for command in COMMANDS {
        for flag in ["--help", "-h"] {
            let out = lensmap(&with(command, &[flag]));
            let help = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "{command:?} {flag}");
            for needed in [
                "Example",
                "lensmap ",
                "Exit codes",
                "141",
                "LENSMAP_VALIDATION",
                "--json",
                "--quiet",
            ] {
                assert!(
                    help.contains(needed),
                    "{command:?} {flag} lacks {needed}: {help}"
                );
            }
        }
    }
}

/// `--json` on each kind of command: the whole of stdout is one JSON document.
#[test]
fn json_is_the_only_thing_on_stdout_for_every_command() {
    let dir = temp_dir("json");
    let frame = dir.join("frame.png");
    let reference = dir.join("reference");
    let synthetic = dir.join("synthetic");
    let runs: Vec<(Vec<&str>, &str)> = vec![
        (vec!["passes", "--layers", "2", "--json"], "counts"),
        (
            tiny_render(&["--out", frame.to_str().unwrap(), "--json"]),
            "hybrid",
        ),
        (
            vec![
                "reference",
                "--scene",
                "glass-sphere",
                "--width",
                "12",
                "--height",
                "9",
                "--supersampling",
                "1",
                "--out",
                reference.to_str().unwrap(),
                "--json",
            ],
            "all_rays",
        ),
        (
            vec![
                "--json",
                "demo",
                "--synthetic",
                "--width",
                "16",
                "--height",
                "12",
                "--frames",
                "1",
                "--out",
                synthetic.to_str().unwrap(),
            ],
            "variants",
        ),
        (with(&TINY_BENCH, &["--json"]), "rows"),
    ];
    for (args, key) in runs {
        let out = lensmap(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {stderr}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
            panic!(
                "{args:?}: stdout is not one JSON document ({e}): {}",
                String::from_utf8_lossy(&out.stdout)
            )
        });
        assert!(json.get(key).is_some(), "{args:?}: no {key} in {json}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A benchmark writes no file unless asked (`--report FILE`), and then exactly that one.
#[test]
fn benchmarks_write_files_only_when_asked() {
    let dir = temp_dir("bench-files");
    let bench = TINY_BENCH;
    let out = common::lensmap_command(&bench)
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "no file written"
    );
    let out = common::lensmap_command(&with(&bench, &["--report", "r.json"]))
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    let written: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(written, ["r.json"]);
    serde_json::from_slice::<serde_json::Value>(&std::fs::read(dir.join("r.json")).unwrap())
        .expect("the report is JSON");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Under `--json` an error is one JSON line on stderr with the message and the exit code, for
/// bad input, a usage error the parser catches, and one it cannot.
#[test]
fn errors_are_json_lines_under_json() {
    for (args, names) in [
        (
            vec![
                "render",
                "--scene",
                "no-such-scene",
                "--projected",
                "--json",
            ],
            "no-such-scene",
        ),
        (vec!["passes", "--layers", "many", "--json"], "--layers"),
        (vec!["passes", "--layers", "0", "--json"], "--layers"),
    ] {
        let out = lensmap(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}: nothing on stdout");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        let json: serde_json::Value = serde_json::from_str(stderr.trim())
            .unwrap_or_else(|e| panic!("{args:?}: not a JSON line ({e}): {stderr}"));
        assert_eq!(json["exit_code"], 2, "{args:?}: {json}");
        assert!(
            json["error"].as_str().is_some_and(|e| e.contains(names)),
            "{args:?}: {json}"
        );
    }
}

/// `-q` prints nothing at all on success (the files are still written); with `--json` the
/// document alone.
#[test]
fn quiet_prints_nothing_but_what_was_asked_for() {
    let dir = temp_dir("quiet");
    let frame = dir.join("frame.png");
    let out = lensmap(&tiny_render(&["--out", frame.to_str().unwrap(), "-q"]));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(frame.is_file() && frame.with_extension("exr").is_file());
    let out = lensmap(&["passes", "--quiet", "--json"]);
    assert!(out.status.success());
    serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("the document alone");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// On a terminal (a pseudo-terminal from `script`), each stage is shown as "step i of n";
/// `--quiet` hides it, and so does a stderr that is not a terminal.
#[test]
fn progress_names_each_step_on_a_terminal() {
    let dir = temp_dir("progress");
    let frame = dir.join("frame.png");
    let quote = |args: &[&str]| -> String {
        args.iter()
            .map(|a| format!("'{a}'"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let args = tiny_render(&["--out", frame.to_str().unwrap(), "--compare"]);
    lensmap_tests::name_the_binarys_driver_on_failure();
    let line = format!(
        "LENSMAP_VALIDATION=1 '{}' {}",
        env!("CARGO_BIN_EXE_lensmap"),
        quote(&args)
    );
    let on_terminal = |command: &str| -> String {
        let out = std::process::Command::new("script")
            .args(["-qec", command, "/dev/null"])
            .output()
            .expect("script (util-linux) runs");
        assert!(out.status.success(), "{command}");
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let shown = on_terminal(&line);
    for step in ["step 1 of 3", "step 2 of 3", "step 3 of 3"] {
        assert!(shown.contains(step), "{step} not shown: {shown}");
    }
    let quiet = on_terminal(&format!("{line} --quiet"));
    assert!(!quiet.contains("step "), "{quiet}");
    // Not a terminal: no progress in the captured stderr.
    let out = lensmap(&args);
    assert!(out.status.success());
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
