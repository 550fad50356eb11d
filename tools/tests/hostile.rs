//! Hostile input to the command line: a closed stdout, sizes that would exhaust memory, output
//! paths that cannot be honoured and a disk that fills mid-write. Each case asserts the
//! exit code, one line on stderr naming the option, no panic, and that earlier outputs survive.

mod common;
use common::{TINY_FRAME, TINY_RENDER, lensmap, lensmap_command, read, succeeds};

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::Stdio;
use std::time::{Duration, Instant};

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("hostile", name)
}

/// Exit code 2 and exactly one line on stderr that names `what`; no panic; quickly.
fn assert_bad_usage(args: &[&str], what: &str) {
    let start = Instant::now();
    let out = lensmap(args);
    let elapsed = start.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.contains(what),
        "{args:?} should name {what}: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    assert!(
        elapsed < Duration::from_secs(5),
        "{args:?} took {elapsed:?}"
    );
}

/// `lensmap passes … | head -1`: the plan of 256 layers is far larger than a pipe's buffer, so the
/// program is still writing when the reader goes; it ends quietly with 128 + SIGPIPE.
#[test]
fn a_closed_stdout_ends_the_program_quietly() {
    for extra in [&[][..], &["--json"][..]] {
        let mut args = vec!["passes", "--layers", "256", "--variant", "multipass"];
        args.extend_from_slice(extra);
        let mut child = lensmap_command(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        assert!(!first.is_empty());
        // The reader is dropped here: stdout is closed.
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(141), "{args:?}: {stderr}");
        assert!(stderr.is_empty(), "{args:?}: {stderr}");
    }
}

/// One number must not exhaust memory or time: refused at once, naming the option.
#[test]
fn sizes_beyond_the_limits_are_refused_before_any_work() {
    assert_bad_usage(&["passes", "--layers", "4000000000"], "--layers");
    assert_bad_usage(&["passes", "--layers", "2000"], "--layers");
    assert_bad_usage(&["passes", "--layers", "0"], "--layers");
    assert_bad_usage(&["bench", "passes", "--max-layers", "0"], "--max-layers");
    assert_bad_usage(
        &["bench", "passes", "--max-layers", "100000"],
        "--max-layers",
    );
    assert_bad_usage(&["bench", "hybrid", "--frames", "0"], "--frames");
    assert_bad_usage(
        &[
            "bench",
            "classes",
            "--supersampling",
            "15",
            "--validate-only",
        ],
        "the full tree's convergence renders at twice --supersampling",
    );
    let render = ["render", "--scene", "glass-sphere", "--projected"];
    for (extra, what) in [
        (
            &["--width", "100000"][..],
            "--width 100000: outside its range [1, 16384]",
        ),
        // Within --width's own range, but not with the scene's 3×3 supersampling.
        (
            &["--width", "10000"][..],
            "30000×1440 subpixels; the limit is 16384",
        ),
        (&["--supersampling", "1000"][..], "640000×480000 subpixels"),
        (&["--camera-position", "1e30,0,0"][..], "farther than 1e6 m"),
        (&["--t", "-1"][..], "--t -1"),
        // f32 options judged as the f32 they become: ∞ and 0.
        (&["--t", "1e39"][..], "--t 1e39: outside its range"),
        (&["--t", "1e-50"][..], "--t 1e-50: outside its range"),
        (
            &["--footprint", "1e39"][..],
            "--footprint 1e39: outside its range",
        ),
        (&["--max-vertices", "-5"][..], "--max-vertices"),
    ] {
        let mut args = render.to_vec();
        args.extend_from_slice(extra);
        assert_bad_usage(&args, what);
    }
    assert_bad_usage(
        &["bench", "hybrid", "--supersampling", "0"],
        "--supersampling",
    );
    assert_bad_usage(
        &[
            "render",
            "--scene",
            "glass-sphere",
            "--projected",
            "--em-size",
            "12",
        ],
        "em-size",
    );
    assert_bad_usage(
        &[
            "render",
            "--scene",
            "glass-sphere",
            "--projected",
            "--footprint",
            "-1",
        ],
        "footprint",
    );
}

/// `--out` takes what the command writes (.png, .exr, a folder) and says what it wrote; another
/// extension is refused before any work, and nothing is written.
#[test]
fn out_paths_are_honoured_or_refused() {
    let dir = temp_dir("out");
    let mut tiny = vec!["render", "--scene", "glass-sphere"];
    tiny.extend(TINY_RENDER);
    let jpg = dir.join("x.jpg");
    let mut args = tiny.to_vec();
    args.extend(["--out", jpg.to_str().unwrap()]);
    assert_bad_usage(&args, "--out");
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "nothing written"
    );

    let folder = dir.join("frames");
    std::fs::create_dir_all(&folder).unwrap();
    let mut args = tiny.to_vec();
    args.extend(["--out", folder.to_str().unwrap()]);
    let out = succeeds(&args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for name in ["hybrid.png", "hybrid.exr"] {
        let path = folder.join(name);
        assert!(path.is_file(), "{name}");
        assert!(
            stdout.contains(path.to_str().unwrap()),
            "says it wrote {name}: {stdout}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A bake written by `render --write-bake` carries its scene's identity: another scene (whatever
/// its lens objects are called) refuses it with one line naming the field and the fix.
#[test]
fn a_written_bake_is_refused_by_another_scene() {
    let dir = temp_dir("write-bake");
    let bake = dir.join("bake");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    let frame = dir.join("a.png");
    args.extend([
        "--write-bake",
        bake.to_str().unwrap(),
        "--out",
        frame.to_str().unwrap(),
    ]);
    succeeds(&args);
    let other = dir.join("b.png");
    assert_bad_usage(
        &[
            "render",
            "--scene",
            "mirror-teapot",
            "--bake",
            bake.to_str().unwrap(),
            "--out",
            other.to_str().unwrap(),
        ],
        "provenance.scene_hash",
    );
    // The scene it was written from reads it back.
    let again: Vec<&str> = ["render", "--scene", "glass-sphere"]
        .into_iter()
        .chain(["--bake", bake.to_str().unwrap()])
        .chain(TINY_FRAME)
        .chain(["--out", other.to_str().unwrap()])
        .collect();
    succeeds(&again);
    // A manifest that says nothing of its scene is refused, unless any bake is accepted.
    let manifest = bake.join("manifest.json");
    let mut json: serde_json::Value = serde_json::from_slice(&read(&manifest)).unwrap();
    json.as_object_mut()
        .unwrap()
        .remove("provenance")
        .expect("a provenance");
    std::fs::write(&manifest, serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    assert_bad_usage(&again, "--accept-any-bake");
    let mut accepting = again.clone();
    accepting.push("--accept-any-bake");
    succeeds(&accepting);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Options that do not apply are refused rather than ignored; `--report` is honoured; a misspelt
/// scene name gets a suggestion.
#[test]
fn options_say_what_they_do() {
    assert_bad_usage(
        &["demo", "--synthetic", "--supersampling", "0"],
        "--supersampling",
    );
    assert_bad_usage(&["demo", "--synthetic", "--em-size", "0"], "--em-size");
    assert_bad_usage(&["demo", "--synthetic", "--frames", "0"], "--frames");
    assert_bad_usage(
        &["render", "--scene", "teapot-rom", "--projected"],
        "did you mean teapot-room?",
    );
    assert_bad_usage(
        &["render", "--scene", "glass_sphere", "--projected"],
        "did you mean glass-sphere?",
    );
    let dir = temp_dir("synthetic");
    let report = dir.join("report.json");
    succeeds(&[
        "demo",
        "--synthetic",
        "--width",
        "32",
        "--height",
        "24",
        "--frames",
        "1",
        "--out",
        dir.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let json: serde_json::Value = serde_json::from_slice(&read(&report)).unwrap();
    assert_eq!(json["variants"].as_array().map(Vec::len), Some(2), "{json}");
    std::fs::remove_dir_all(&dir).unwrap();
}
