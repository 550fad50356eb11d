//! `lensmap bake` as a user runs it, on a tiny glass-sphere bake (validation layer on): shards
//! merged and a killed-then-resumed bake give the same bytes as one uninterrupted bake, the
//! previous bake survives a kill, a second bake into one directory is refused, SIGTERM stops a
//! bake at once keeping its finished samples, and bad input exits 2 with one line naming the fix.

mod common;
use common::{lensmap, lensmap_command};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

/// Small enough for CI: 48×36 views at 1×1, 16² maps, two clustered layers, two views a sample.
const TINY: [&str; 14] = [
    "--width",
    "48",
    "--height",
    "36",
    "--supersampling",
    "1",
    "--em-size",
    "16",
    "--layers",
    "2",
    "--multi-view",
    "2",
    "--no-judge",
    "--json",
];

fn bake(scene: &str, samples: &str, out: &Path, extra: &[&str]) -> Output {
    let out = out.to_str().expect("UTF-8 temp path");
    let mut args = vec!["bake", "--scene", scene, "--samples", samples, "--out", out];
    args.extend_from_slice(&TINY);
    args.extend_from_slice(extra);
    lensmap(&args)
}

/// `lensmap bake --merge A B --out OUT`.
fn merge(a: &Path, b: &Path, out: &Path) -> Output {
    lensmap(&[
        "bake",
        "--merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
}

/// The run succeeded ([`common::assert_success`]).
fn succeeded(output: &Output) {
    common::assert_success("lensmap bake", output);
}

/// Every file of a directory, name → bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| {
            let entry = entry.unwrap();
            (
                entry.file_name().to_string_lossy().into_owned(),
                std::fs::read(entry.path()).unwrap(),
            )
        })
        .collect()
}

fn same_bytes(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "{} vs {}",
        a.display(),
        b.display()
    );
    for (name, bytes) in &fa {
        assert!(
            bytes == &fb[name],
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

fn temp_dir(name: &str) -> PathBuf {
    common::temp_dir("bake", name)
}

fn manifest_samples(dir: &Path) -> Vec<u64> {
    let text = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["provenance"]["samples"]
        .as_array()
        .expect("a lensmap bake has provenance")
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect()
}

#[test]
fn shards_and_a_killed_resumed_bake_equal_one_uninterrupted_bake() {
    let root = temp_dir("shards");
    let whole = root.join("whole");
    let output = bake("glass-sphere", "0..3", &whole, &[]);
    succeeded(&output);
    assert_eq!(manifest_samples(&whole), vec![0, 1, 2]);
    let summary: serde_json::Value =
        serde_json::from_slice(&output.stdout).expect("--json prints one JSON summary");
    let layers = &summary["summary"]["plan"]["lenses"][0]["shells"];
    assert_eq!(layers.as_array().map(Vec::len), Some(2), "{summary}");
    assert!(summary["summary"]["reports"][0]["lenses"][0]["nonzeros"][0].as_u64() > Some(0));

    // Two shards, merged: the same bytes.
    let (one, two, merged) = (root.join("s1"), root.join("s2"), root.join("merged"));
    succeeded(&bake("glass-sphere", "0..3", &one, &["--shard", "1/2"]));
    succeeded(&bake("glass-sphere", "0..3", &two, &["--shard", "2/2"]));
    assert_eq!(manifest_samples(&one), vec![0, 2]);
    assert_eq!(manifest_samples(&two), vec![1]);
    succeeded(&merge(&one, &two, &merged));
    same_bytes(&merged, &whole);

    // A previous bake (sample 0), then a fresh bake of four samples killed after its first.
    let dir = root.join("killed");
    succeeded(&bake("glass-sphere", "0", &dir, &[]));
    let previous = files(&dir);
    let mut args: Vec<String> = ["bake", "--scene", "glass-sphere", "--samples", "0..4"]
        .map(String::from)
        .to_vec();
    args.extend(["--out".into(), dir.to_str().unwrap().into()]);
    args.extend(TINY.map(String::from));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut child = lensmap_command(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_staged(&mut child, &root.join(".killed.baking"), 1);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert_eq!(files(&dir), previous, "the previous bake is untouched");
    // Resume: the staged sample is kept, the rest baked, and the result is the whole bake's.
    let resumed = bake("glass-sphere", "0..3", &dir, &["--resume"]);
    succeeded(&resumed);
    let json: serde_json::Value = serde_json::from_slice(&resumed.stdout).unwrap();
    assert!(
        !json["summary"]["resumed"].as_array().unwrap().is_empty(),
        "{json}"
    );
    // The killed run staged sample 0..4's first ones; the bake holds what is complete.
    let samples = manifest_samples(&dir);
    assert!(samples.starts_with(&[0, 1, 2]), "{samples:?}");
    if samples == [0, 1, 2] {
        same_bytes(&dir, &whole);
    } else {
        // Sample 3 was staged too before the kill: every file of the whole bake is still equal.
        let (got, want) = (files(&dir), files(&whole));
        for (name, bytes) in &want {
            if name != "manifest.json" {
                assert!(got.get(name) == Some(bytes), "{name}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&root);
}

/// Waits until `staging` holds at least `count` sample reports (a sample's report is written
/// last), while `child` runs.
fn wait_for_staged(child: &mut std::process::Child, staging: &Path, count: usize) {
    let start = Instant::now();
    loop {
        let staged = std::fs::read_dir(staging).map_or(0, |entries| {
            entries
                .filter_map(Result::ok)
                .filter(|e| e.file_name().to_string_lossy().starts_with("sample-"))
                .count()
        });
        if staged >= count {
            return;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the bake finished before {count} sample(s) were staged"
        );
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no sample staged"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Two bakes into one directory: the second is refused at once, naming the lock and the first's
/// pid. SIGTERM stops the first within seconds with exit code 143, keeping its finished sample,
/// releasing the lock and saying how to resume; `--resume` then gives an uninterrupted bake's
/// bytes.
#[test]
fn a_second_bake_is_refused_and_sigterm_keeps_the_finished_samples() {
    let root = temp_dir("sigterm");
    let whole = root.join("whole");
    succeeded(&bake("glass-sphere", "0..6", &whole, &[]));
    let dir = root.join("bake");
    let out = dir.to_str().unwrap();
    let mut args = vec![
        "bake",
        "--scene",
        "glass-sphere",
        "--samples",
        "0..6",
        "--out",
        out,
    ];
    args.extend_from_slice(&TINY[..TINY.len() - 1]); // not --json: the human line
    let mut first = lensmap_command(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let staging = root.join(".bake.baking");
    wait_for_staged(&mut first, &staging, 1);

    // The second writer: refused at once with one line naming the lock and its holder.
    let second = bake("glass-sphere", "0..6", &dir, &[]);
    fails_with_2(&second, &format!("pid {}", first.id()));
    fails_with_2(&second, ".bake.lock");
    assert!(
        first.try_wait().unwrap().is_none(),
        "the first bake goes on"
    );

    let sent = Instant::now();
    let kill = std::process::Command::new("kill")
        .args(["-TERM", &first.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = first.wait().unwrap();
    let stopped_in = sent.elapsed();
    let mut stderr = String::new();
    std::io::Read::read_to_string(first.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    eprintln!("SIGTERM to exit: {:.1} ms", stopped_in.as_secs_f64() * 1e3);
    assert_eq!(status.code(), Some(143), "{stderr}");
    assert!(
        stopped_in < Duration::from_secs(5),
        "stopped in {stopped_in:?}"
    );
    let said = stderr.trim().lines().last().unwrap_or_default();
    assert!(
        said.contains("interrupted by SIGTERM")
            && said.contains("finished sample(s) kept")
            && said.contains("--resume"),
        "{stderr}"
    );
    assert!(!dir.exists(), "nothing swapped in for an unfinished bake");
    assert!(!root.join(".bake.lock").exists(), "the lock is released");
    assert!(staging.join("sample-000.json").is_file());

    // Resumed: the finished sample kept, the rest baked, the bytes of one bake.
    let resumed = bake("glass-sphere", "0..6", &dir, &["--resume"]);
    succeeded(&resumed);
    let json: serde_json::Value = serde_json::from_slice(&resumed.stdout).unwrap();
    assert!(
        json["summary"]["resumed"]
            .as_array()
            .is_some_and(|r| r.contains(&0.into())),
        "{json}"
    );
    same_bytes(&dir, &whole);
    let _ = std::fs::remove_dir_all(&root);
}

/// A 2D view space bakes as a 1D one does: sample by sample, its views taken from the
/// triangulation; two shards merged are the bytes of one bake, and the bake renders a camera
/// inside a triangle blending three samples.
#[test]
fn a_patch_bakes_in_shards_that_merge_into_one_bake() {
    let root = temp_dir("patch");
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/glass-sphere-patch.toml"
    );
    let whole = root.join("whole");
    succeeded(&bake(scene, "0,1,3,4", &whole, &[]));
    assert_eq!(manifest_samples(&whole), vec![0, 1, 3, 4]);
    let (one, two, merged) = (root.join("s1"), root.join("s2"), root.join("merged"));
    succeeded(&bake(scene, "0,1,3,4", &one, &["--shard", "1/2"]));
    succeeded(&bake(scene, "0,1,3,4", &two, &["--shard", "2/2"]));
    succeeded(&merge(&one, &two, &merged));
    same_bytes(&merged, &whole);
    // Azimuth −4°, elevation 20° about the look-at point: inside the lower-left cell (samples
    // 0, 1, 3, 4), off its diagonal, so three samples.
    let image = root.join("frame.png");
    // A 32×24 frame of the bake from `position`: its JSON report and its stderr.
    let render_at = |position: &str| {
        let output = lensmap(&[
            "render",
            "--scene",
            scene,
            "--bake",
            whole.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "24",
            "--supersampling",
            "1",
            "--camera-position",
            position,
            "--out",
            image.to_str().unwrap(),
            "--json",
        ]);
        common::assert_success("lensmap render", &output);
        let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        (json, String::from_utf8_lossy(&output.stderr).into_owned())
    };
    let (json, _) = render_at("-0.342,2.785,4.893");
    let viewpoints = json["hybrid"]["viewpoints"].as_array().unwrap();
    assert_eq!(viewpoints.len(), 3, "{json}");
    assert_eq!(json["hybrid"]["outside_view_space"], false, "{json}");
    // Straight above the look-at point, far outside the patch: still a frame, blending the
    // nearest point of the region (on its top edge, samples 3 and 4: the bake's viewpoints 2
    // and 3), said in one warning line, with every value finite.
    let (json, stderr) = render_at("0.01,6.0,0.2");
    assert_eq!(json["hybrid"]["outside_view_space"], true, "{json}");
    let samples: Vec<u64> = json["hybrid"]["viewpoints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["viewpoint"].as_u64().unwrap())
        .collect();
    assert!(
        !samples.is_empty() && samples.iter().all(|s| [2, 3].contains(s)),
        "{json}"
    );
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("outside the view space"))
        .collect();
    assert_eq!(warnings.len(), 1, "{stderr}");
    let exr = image::open(image.with_extension("exr"))
        .expect("the frame's EXR")
        .into_rgba32f();
    assert!(exr.pixels().all(|p| p.0.iter().all(|v| v.is_finite())));
    let _ = std::fs::remove_dir_all(&root);
}

fn fails_with_2(output: &Output, wanted: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "one line: {stderr}");
    assert!(stderr.contains(wanted), "'{wanted}' not in: {stderr}");
}

#[test]
fn bad_input_exits_2_with_one_line_naming_the_fix() {
    let root = temp_dir("bad");
    let out = root.join("never");
    fails_with_2(
        &bake("glass-sphere", "99", &out, &[]),
        "sample 99 does not exist",
    );
    for shard in ["3/2", "0/0"] {
        fails_with_2(
            &bake("glass-sphere", "0", &out, &["--shard", shard]),
            "give I/N with 1 ≤ I ≤ N",
        );
    }
    fails_with_2(
        &lensmap(&[
            "bake",
            "--scene",
            "glass-sphere",
            "--em-size",
            "100",
            "--out",
            out.to_str().unwrap(),
        ]),
        "--em-size 100",
    );
    fails_with_2(
        &bake("glass-sphere", "0", &out, &["--confidence-degrees", "0"]),
        "--confidence-degrees 0",
    );
    fails_with_2(
        &bake("glass-sphere", "0", &out, &["--tolerance", "0"]),
        "--tolerance 0",
    );
    fails_with_2(
        &bake("glass-sphere", "0..=18446744073709551615", &out, &[]),
        "does not exist",
    );
    assert!(!out.exists(), "nothing written for bad input");

    let (glass, mirror) = (root.join("glass"), root.join("mirror"));
    succeeded(&bake("glass-sphere", "0", &glass, &[]));
    succeeded(&bake("mirror-teapot", "0", &mirror, &[]));
    fails_with_2(&merge(&glass, &mirror, &out), "the scenes differ");
    fails_with_2(&merge(&glass, &glass, &out), "both hold sample 0");
    let render = lensmap(&[
        "render",
        "--scene",
        "mirror-teapot",
        "--bake",
        glass.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        root.join("render.png").to_str().unwrap(),
    ]);
    fails_with_2(&render, "bake this scene");
    assert!(!out.exists(), "nothing written for bad input");
    let _ = std::fs::remove_dir_all(&root);
}

/// A bake written before lensmap had a canonical bake identity: its provenance has no
/// `identity_version` (read as 0) and hashes of another encoding. Rendering it, resuming into it
/// and merging it are each refused with one line naming the version and the fix; accepting any
/// bake still renders it.
#[test]
fn a_bake_of_an_older_identity_is_refused_with_the_version_and_the_fix() {
    let root = temp_dir("older-identity");
    let (older, other) = (root.join("older"), root.join("other"));
    succeeded(&bake("glass-sphere", "0", &older, &[]));
    succeeded(&bake("glass-sphere", "1", &other, &[]));
    let manifest_path = older.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest_path).unwrap()).unwrap();
    let provenance = manifest["provenance"]
        .as_object_mut()
        .expect("a provenance");
    assert_eq!(provenance.remove("identity_version"), Some(1.into()));
    // What the earlier encoding wrote (SHA-256 of `Debug` text): other hex digits.
    provenance.insert("scene_hash".into(), "ab".repeat(32).into());
    provenance.insert("options_hash".into(), "cd".repeat(32).into());
    std::fs::write(
        &manifest_path,
        serde_json::to_string_pretty(&manifest).unwrap(),
    )
    .unwrap();

    let render = |extra: &[&str]| {
        let out = root.join("render.png");
        let mut args = vec!["render", "--scene", "glass-sphere", "--bake"];
        args.push(older.to_str().unwrap());
        args.extend_from_slice(&["--width", "32", "--height", "24"]);
        args.extend_from_slice(&["--out", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        lensmap(&args)
    };
    let refused = render(&[]);
    fails_with_2(&refused, "provenance.identity_version");
    fails_with_2(&refused, "identity version 0, this lensmap in version 1");
    fails_with_2(&refused, "or pass --accept-any-bake to use it anyway");
    succeeded(&render(&["--accept-any-bake"]));
    let resumed = bake("glass-sphere", "0,1", &older, &["--resume"]);
    fails_with_2(
        &resumed,
        "so its samples cannot be resumed; bake again without --resume",
    );
    let merged = merge(&older, &other, &root.join("merged"));
    fails_with_2(&merged, "so it cannot be merged");
    assert!(!root.join("merged").exists(), "nothing written");
    let _ = std::fs::remove_dir_all(&root);
}

/// The names of the map files lens object `lens`'s layer `layer` lists, and its own EM origin.
fn layer_maps(dir: &Path, lens: usize, layer: usize) -> (Vec<String>, serde_json::Value) {
    let text = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let listed = &json["lenses"][lens]["layers"][layer];
    let maps = listed["maps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap().to_owned())
        .collect();
    (maps, listed["em_origin"].clone())
}

#[test]
fn lens_objects_sharing_a_far_layer_store_it_once_through_shards_and_resume() {
    // mirror-teapot at two layers each: the lid's farthest layer holds walls its body's holds.
    let root = temp_dir("shared");
    let whole = root.join("whole");
    let share = ["--share-layers", "on"];
    let output = bake("mirror-teapot", "0..2", &whole, &share);
    succeeded(&output);
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let plan = &summary["summary"]["plan"];
    let shared = plan["shared"]
        .as_array()
        .expect("the plan lists shared layers");
    assert_eq!(shared.len(), 1, "{plan}");
    let members: Vec<(usize, usize)> = shared[0]["members"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            (
                m[0].as_u64().unwrap() as usize,
                m[1].as_u64().unwrap() as usize,
            )
        })
        .collect();
    assert_eq!(members.len(), 2);
    let [(owner, owner_layer), (member, member_layer)] = [members[0], members[1]];
    let (owner_maps, owner_origin) = layer_maps(&whole, owner, owner_layer);
    let (member_maps, member_origin) = layer_maps(&whole, member, member_layer);
    assert_eq!(member_maps, owner_maps, "one file per sample for both");
    assert!(
        owner_origin.is_null(),
        "the owner's layer uses its own origin"
    );
    assert_eq!(
        member_origin, plan["lenses"][owner]["em_origin"],
        "the member reads the map about the owner's origin"
    );
    // Every listed file exists once: (layers of both lens objects − 1 shared) × 2 samples.
    let layers: usize = plan["lenses"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["shells"].as_array().unwrap().len())
        .sum();
    assert_eq!(
        files(&whole).len(),
        (layers - 1) * 2 + 1,
        "and the manifest"
    );

    // Shards merged give the same bytes; the runtime renders the bake.
    let (one, two, merged) = (root.join("s1"), root.join("s2"), root.join("merged"));
    succeeded(&bake(
        "mirror-teapot",
        "0..2",
        &one,
        &["--shard", "1/2", "--share-layers", "on"],
    ));
    succeeded(&bake(
        "mirror-teapot",
        "0..2",
        &two,
        &["--shard", "2/2", "--share-layers", "on"],
    ));
    succeeded(&merge(&one, &two, &merged));
    same_bytes(&merged, &whole);
    let frame = root.join("frame.png");
    succeeded(&lensmap(&[
        "render",
        "--scene",
        "mirror-teapot",
        "--bake",
        whole.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        frame.to_str().unwrap(),
    ]));
    // Resuming into a larger sample range keeps the shared files of the finished samples.
    let before = files(&whole);
    succeeded(&bake(
        "mirror-teapot",
        "0..3",
        &whole,
        &["--resume", "--share-layers", "on"],
    ));
    assert_eq!(manifest_samples(&whole), vec![0, 1, 2]);
    let after = files(&whole);
    for (name, bytes) in before.iter().filter(|(n, _)| *n != "manifest.json") {
        assert!(after.get(name) == Some(bytes), "{name} changed on resume");
    }
    assert_eq!(after.len(), (layers - 1) * 3 + 1);
    let _ = std::fs::remove_dir_all(&root);
}

/// A bake records the device and driver that baked each sample (provenance, not identity: the
/// driver `bake --json` names), and `--merge` of shards baked on different drivers succeeds with
/// one warning naming both. The second driver is written into a shard's manifest: one machine
/// has one driver per process.
#[test]
fn a_bake_records_its_driver_and_a_merge_across_drivers_warns_naming_them() {
    let root = temp_dir("drivers");
    let (one, two, merged) = (root.join("s1"), root.join("s2"), root.join("merged"));
    let output = bake("glass-sphere", "0..2", &one, &["--shard", "1/2"]);
    succeeded(&output);
    succeeded(&bake("glass-sphere", "0..2", &two, &["--shard", "2/2"]));
    let said: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let driver = said["driver"]
        .as_str()
        .expect("bake --json names the driver");
    assert!(!driver.is_empty(), "{said}");
    let manifest_of = |dir: &Path| -> serde_json::Value {
        serde_json::from_slice(&common::read(&dir.join("manifest.json"))).unwrap()
    };
    let recorded = &manifest_of(&one)["provenance"]["baked_on"];
    assert_eq!(recorded.as_array().map(Vec::len), Some(1), "{recorded}");
    let device = &recorded[0]["device"];
    assert_eq!(
        format!(
            "{}, {}",
            device["driver"].as_str().unwrap(),
            device["driver_info"].as_str().unwrap()
        ),
        driver
    );
    assert_eq!(recorded[0]["samples"], serde_json::json!([0]));

    let mut other = manifest_of(&two);
    other["provenance"]["baked_on"][0]["device"]["driver_info"] =
        "Mesa 99.0 (a second driver)".into();
    std::fs::write(
        two.join("manifest.json"),
        serde_json::to_vec_pretty(&other).unwrap(),
    )
    .unwrap();
    let output = merge(&one, &two, &merged);
    succeeded(&output);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("warning: ")
            && stderr.contains(device["driver_info"].as_str().unwrap())
            && stderr.contains("Mesa 99.0 (a second driver)"),
        "{stderr}"
    );
    let baked_on = &manifest_of(&merged)["provenance"]["baked_on"];
    assert_eq!(baked_on.as_array().map(Vec::len), Some(2), "{baked_on}");
    let _ = std::fs::remove_dir_all(&root);
}

/// `lensmap bake --compress DIR --out OUT`.
fn compress(dir: &Path, out: &Path) -> Output {
    lensmap(&[
        "bake",
        "--compress",
        dir.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--keyframe-interval",
        "2",
    ])
}

/// Compressed shards merge, and a compressed bake resumes, into the bytes of one uncompressed
/// bake: the lossless coding decodes bit-exact, and both write EXR maps (compress again after).
#[test]
fn compressed_shards_merge_and_a_compressed_bake_resumes_into_the_uncompressed_bake() {
    let root = temp_dir("compressed");
    let whole = root.join("whole");
    succeeded(&bake("glass-sphere", "0..3", &whole, &[]));
    let (one, two) = (root.join("s1"), root.join("s2"));
    succeeded(&bake("glass-sphere", "0..3", &one, &["--shard", "1/2"]));
    succeeded(&bake("glass-sphere", "0..3", &two, &["--shard", "2/2"]));
    let (one_z, two_z) = (root.join("s1z"), root.join("s2z"));
    succeeded(&compress(&one, &one_z));
    succeeded(&compress(&two, &two_z));
    for dir in [&one_z, &two_z] {
        let names = files(dir);
        assert!(
            names.keys().any(|n| n.ends_with(".lmz")) && !names.keys().any(|n| n.ends_with(".exr")),
            "{}: {:?}",
            dir.display(),
            names.keys().collect::<Vec<_>>()
        );
    }
    // A compressed bake missing a map is a bad bake (exit 2, one line naming the file and where
    // the manifest lists it), as a layered bake's and a radiance bake's are.
    let damaged = root.join("damaged");
    succeeded(&compress(&one, &damaged));
    let gone = files(&damaged)
        .into_keys()
        .find(|name| name.ends_with(".lmz"))
        .expect("a compressed map");
    std::fs::remove_file(damaged.join(&gone)).unwrap();
    let output = merge(&damaged, &two, &root.join("not-merged"));
    fails_with_2(&output, "not found (listed in manifest.json at ");
    assert!(String::from_utf8_lossy(&output.stderr).contains(&gone));
    // One shard compressed, one not; and both compressed.
    let (mixed, merged) = (root.join("mixed"), root.join("merged"));
    succeeded(&merge(&one_z, &two, &mixed));
    same_bytes(&mixed, &whole);
    succeeded(&merge(&one_z, &two_z, &merged));
    same_bytes(&merged, &whole);

    // A compressed bake of sample 0, resumed to 0..3: sample 0 is kept (decoded), 1 and 2 baked.
    let first = root.join("first");
    succeeded(&bake("glass-sphere", "0", &first, &[]));
    let resumed = root.join("resumed");
    succeeded(&compress(&first, &resumed));
    let output = bake("glass-sphere", "0..3", &resumed, &["--resume"]);
    succeeded(&output);
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["summary"]["resumed"], serde_json::json!([0]), "{json}");
    same_bytes(&resumed, &whole);
    let _ = std::fs::remove_dir_all(&root);
}

/// The glass ball at the class bake test's size: 64×48 at 2×2, for the bake and its frames.
const BALL: [&str; 8] = [
    "--scene",
    "glass-sphere",
    "--width",
    "64",
    "--height",
    "48",
    "--supersampling",
    "2",
];

/// A frame of 4 classes of `scene` (its flags) drawn from a bake of `terms` at sample 0, judged
/// by `render --compare` against `reference` (a `--reference-tree`): its lens PSNR and light
/// ratio. Checks the bake's manifest names its classes and that a frame of other terms than the
/// bake's says so.
fn four_class_frame(dir: &Path, scene: &[&str], terms: &str, reference: &str) -> (f64, f64) {
    let out = dir.join(format!("bake-{terms}"));
    let out_text = out.to_str().expect("UTF-8 temp path");
    if !out.exists() {
        let mut command = vec!["bake", "--samples", "0", "--no-judge", "--json"];
        command.extend_from_slice(scene);
        command.extend_from_slice(&["--terms", terms, "--out", out_text]);
        succeeded(&lensmap(&command));
    }
    let image = dir.join(format!("frame-{terms}-{reference}.png"));
    let mut command = vec!["render", "--bake", out_text, "--view", "0", "--terms", "4"];
    command.extend_from_slice(scene);
    command.extend_from_slice(&[
        "--compare",
        "--reference-tree",
        reference,
        "--reference-supersampling",
        "4",
        "--json",
        "--out",
        image.to_str().unwrap(),
    ]);
    let render = lensmap(&command);
    common::assert_success("lensmap render", &render);
    // The manifest names a bake's classes (nothing for greedy's), and a frame of other terms
    // than the bake's says so.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).expect("the manifest"))
            .expect("JSON");
    let recorded = manifest["provenance"]["terms"].as_str();
    assert_eq!(recorded, (terms != "greedy").then_some(terms));
    let stderr = String::from_utf8_lossy(&render.stderr);
    assert_eq!(
        stderr.contains("give --terms greedy"),
        terms == "greedy",
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&render.stdout).expect("one JSON document");
    (
        report["lens_psnr_db"].as_f64().expect("a lens PSNR"),
        report["lens_radiance_ratio"]
            .as_f64()
            .expect("a radiance ratio"),
    )
}

/// `bake --terms 4` solves one EM per layer over the four path classes' equations (targets traced
/// per class): the frame of 4 classes drawn from it comes closer to the full ray tree than the
/// same frame drawn from a greedy bake, whose maps were fitted through the two greedy terms
/// (measured at this size: 37.5 against 32.4 dB, and 1.005 against 1.060 of the light). The
/// bake's manifest names its classes, and a frame drawing a bake with other terms warns.
#[test]
fn a_bake_of_path_classes_brings_their_frame_closer_to_the_full_tree() {
    let dir = temp_dir("classes");
    let frame_against_full_tree = |terms: &str| four_class_frame(&dir, &BALL, terms, "full");
    let (greedy_db, greedy_ratio) = frame_against_full_tree("greedy");
    let (classes_db, classes_ratio) = frame_against_full_tree("4");
    eprintln!(
        "4 classes from a greedy bake {greedy_db:.2} dB (×{greedy_ratio:.3}), from a bake of 4 classes {classes_db:.2} dB (×{classes_ratio:.3})"
    );
    assert!(
        classes_db > greedy_db + 2.0,
        "{classes_db} against {greedy_db}"
    );
    assert!((classes_ratio - 1.0).abs() < 0.02, "{classes_ratio}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// On a mirror the classes R, RR, RRR, RRRR split a pixel's supersamples between them: each
/// class's equations cover only the vertices where its path exists, as its targets do, so the
/// bake of 4 classes fits the frames of its own model better than a greedy bake at its sample
/// (mirror-teapot at 64×48, 2×2: 21.94 against 21.44 dB; drawn over every vertex, the class
/// bake fitted them at 19.59 dB, and 3.95 dB worse than the greedy bake against the full tree
/// at 640×480).
#[test]
fn a_mirror_bake_of_path_classes_fits_its_own_model() {
    let dir = temp_dir("mirror-classes");
    let scene = [
        "--scene",
        "mirror-teapot",
        "--width",
        "64",
        "--height",
        "48",
        "--supersampling",
        "2",
    ];
    let (greedy_db, _) = four_class_frame(&dir, &scene, "greedy", "4");
    let (classes_db, _) = four_class_frame(&dir, &scene, "4", "4");
    eprintln!(
        "mirror-teapot, 4 classes against their own model: from a greedy bake {greedy_db:.2} dB, from a bake of 4 classes {classes_db:.2} dB"
    );
    assert!(
        classes_db > greedy_db + 0.25,
        "{classes_db} against {greedy_db}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
