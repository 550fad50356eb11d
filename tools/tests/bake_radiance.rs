//! `lensmap bake --radiance-maps` as a user runs it, on tiny maps of glossy-studio: two shards
//! merged and a resumed bake hold the same map bytes as one bake, `lensmap render --radiance`
//! draws from it (and refuses an incomplete one), and bad input exits 2 with one line.

mod common;
use common::{assert_success, lensmap, temp_dir};

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

/// 4² maps, 4 directions a texel: seconds for all twelve samples.
const TINY: [&str; 5] = ["--map-size", "4", "--map-samples", "4", "--json"];

fn bake(samples: &str, out: &Path, extra: &[&str]) -> Output {
    let out = out.to_str().expect("UTF-8 temp path");
    let mut args = vec![
        "bake",
        "--radiance-maps",
        "--scene",
        "glossy-studio",
        "--samples",
        samples,
        "--out",
        out,
    ];
    args.extend_from_slice(&TINY);
    args.extend_from_slice(extra);
    lensmap(&args)
}

/// The map files of a bake, name → bytes (the manifest's timings differ from run to run).
fn maps(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap())
        .filter(|entry| entry.file_name().to_string_lossy().ends_with(".exr"))
        .map(|entry| {
            (
                entry.file_name().to_string_lossy().into_owned(),
                std::fs::read(entry.path()).unwrap(),
            )
        })
        .collect()
}

fn complete_samples(dir: &Path) -> Vec<u64> {
    let text = std::fs::read_to_string(dir.join("radiance.json")).expect("a manifest");
    let manifest: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    manifest["samples"]
        .as_array()
        .expect("samples")
        .iter()
        .map(|r| r["sample"].as_u64().expect("an index"))
        .collect()
}

#[test]
fn shards_merged_and_a_resumed_bake_hold_the_maps_of_one_bake() {
    let root = temp_dir("bake_radiance", "shards");
    let whole = root.join("whole");
    assert_success("one bake", &bake("all", &whole, &[]));
    let all: Vec<u64> = (0..12).collect();
    assert_eq!(complete_samples(&whole), all);
    // Sphere: diffuse and specular; teapot (car paint): diffuse, specular, coat.
    assert_eq!(maps(&whole).len(), 12 * 5);

    let (a, b, merged) = (root.join("a"), root.join("b"), root.join("merged"));
    assert_success("shard 1/2", &bake("all", &a, &["--shard", "1/2"]));
    assert_success("shard 2/2", &bake("all", &b, &["--shard", "2/2"]));
    assert_eq!(complete_samples(&a), [0, 2, 4, 6, 8, 10]);
    let output = lensmap(&[
        "bake",
        "--radiance-maps",
        "--merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert_success("merge", &output);
    assert_eq!(complete_samples(&merged), all);
    assert!(maps(&merged) == maps(&whole), "merged maps differ");
    // The same shard twice: a sample repeated.
    let twice = lensmap(&[
        "bake",
        "--radiance-maps",
        "--merge",
        a.to_str().unwrap(),
        a.to_str().unwrap(),
        "--out",
        root.join("twice").to_str().unwrap(),
    ]);
    assert_eq!(twice.status.code(), Some(2), "{twice:?}");
    assert!(String::from_utf8_lossy(&twice.stderr).contains("repeats sample 0"));

    let resumed = root.join("resumed");
    assert_success("two samples", &bake("0,1", &resumed, &[]));
    let output = bake("all", &resumed, &["--resume"]);
    assert_success("the rest", &output);
    let report: serde_json::Value =
        serde_json::from_slice(&output.stdout).expect("--json prints one document");
    assert_eq!(report["resumed"], serde_json::json!([0, 1]));
    assert_eq!(report["baked"].as_array().map(Vec::len), Some(10));
    assert!(maps(&resumed) == maps(&whole), "resumed maps differ");
    // Other options do not resume: everything is baked again.
    let output = bake("all", &resumed, &["--resume", "--map-seed", "1"]);
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert_eq!(report["resumed"], serde_json::json!([]));
}

#[test]
fn render_draws_from_the_maps_and_refuses_an_incomplete_bake() {
    let root = temp_dir("bake_radiance", "render");
    let (full, part) = (root.join("full"), root.join("part"));
    assert_success("bake", &bake("all", &full, &[]));
    let render = |dir: &Path| {
        lensmap(&[
            "render",
            "--scene",
            "glossy-studio",
            "--projected",
            "--radiance",
            dir.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--supersampling",
            "1",
            "--out",
            root.join("frame.png").to_str().unwrap(),
            "--json",
        ])
    };
    let output = render(&full);
    assert_success("render", &output);
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    // The scene camera sees both objects, each inside a triangle: 3 samples × (2 + 3) lobes.
    let read = report["hybrid"]["glossy_maps_read"]
        .as_u64()
        .expect("a count");
    assert!((5..=15).contains(&read), "{read} maps read");

    // A map removed: a bad bake (exit 2, as a layered bake's missing map), naming the file and
    // where radiance.json lists it.
    let removed = maps(&full).into_keys().next().expect("a map");
    let kept = std::fs::read(full.join(&removed)).expect("the map");
    std::fs::remove_file(full.join(&removed)).expect("removed");
    let output = render(&full);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains(&removed)
            && stderr.contains("not found (listed in radiance.json at samples[")
            && stderr.lines().count() == 1,
        "{stderr}"
    );
    std::fs::write(full.join(&removed), kept).expect("restored");

    // A manifest whose stated options were edited is refused, not read as other maps.
    let manifest = full.join("radiance.json");
    let text = std::fs::read_to_string(&manifest).expect("a manifest");
    std::fs::write(&manifest, text.replace("\"seed\": 0", "\"seed\": 7")).expect("edited");
    let output = render(&full);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    assert!(String::from_utf8_lossy(&output.stderr).contains("identity.options_hash"));

    assert_success("part", &bake("0..6", &part, &[]));
    let output = render(&part);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("radiance.json") && stderr.contains("holds 6 of the 12 view samples"),
        "{stderr}"
    );
}

#[test]
fn bad_input_is_one_line() {
    let root = temp_dir("bake_radiance", "bad");
    for (args, expected) in [
        (vec!["--views", "13"], "--views 13"),
        (vec!["--map-samples", "1"], "--map-samples 1"),
    ] {
        let out = root.join("x");
        let mut all = vec![
            "bake",
            "--radiance-maps",
            "--scene",
            "glossy-studio",
            "--out",
            out.to_str().unwrap(),
        ];
        all.extend_from_slice(&args);
        let output = lensmap(&all);
        assert_eq!(output.status.code(), Some(2), "{output:?}");
        assert!(String::from_utf8_lossy(&output.stderr).contains(expected));
    }
    let output = lensmap(&[
        "bake",
        "--radiance-maps",
        "--scene",
        "glass-sphere",
        "--out",
        root.join("y").to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2), "{output:?}");
    assert!(String::from_utf8_lossy(&output.stderr).contains("has no glossy object"));
}
