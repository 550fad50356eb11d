//! The `lensmap` binary as a user runs it: plan counts from `lensmap passes`, exit codes and the
//! one-line message when no Vulkan driver exists.

use std::process::Command;

mod common;

fn lensmap(args: &[&str]) -> std::process::Output {
    lensmap_tests::name_the_binarys_driver_on_failure();
    Command::new(env!("CARGO_BIN_EXE_lensmap"))
        .args(args)
        .output()
        .expect("the lensmap binary runs")
}

/// `lensmap ARGS` (with `--json` among them) run to success with validation silent: its JSON
/// report.
fn json_report(args: &[&str]) -> serde_json::Value {
    let out = common::lensmap_command(args)
        .output()
        .expect("the lensmap binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("validation"), "{stderr}");
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

fn passes_counts(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["passes", "--json"];
    all.extend_from_slice(args);
    let out = lensmap(&all);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("passes --json prints JSON");
    json["counts"].clone()
}

#[test]
fn passes_prints_the_papers_counts() {
    for n in 1..=4u64 {
        let layers = n.to_string();
        let c = passes_counts(&[
            "--layers",
            &layers,
            "--viewpoints",
            "2",
            "--terms",
            "greedy",
        ]);
        assert_eq!(
            (
                c["prime"].as_u64(),
                c["layer"].as_u64(),
                c["alpha_clear"].as_u64()
            ),
            (Some(1), Some(4 * n), Some(3))
        );
        let c = passes_counts(&[
            "--layers",
            &layers,
            "--viewpoints",
            "1",
            "--terms",
            "greedy",
        ]);
        assert_eq!(
            (c["layer"].as_u64(), c["alpha_clear"].as_u64()),
            (Some(2 * n), Some(1))
        );
        // Three viewpoints (inside a spherical triangle): 2·3·n layer passes, five clears.
        let c = passes_counts(&[
            "--layers",
            &layers,
            "--viewpoints",
            "3",
            "--terms",
            "greedy",
        ]);
        assert_eq!(
            (c["layer"].as_u64(), c["alpha_clear"].as_u64()),
            (Some(6 * n), Some(5))
        );
        let c = passes_counts(&["--layers", &layers, "--viewpoints", "1", "--terms", "R"]);
        assert_eq!(
            (c["layer"].as_u64(), c["alpha_clear"].as_u64()),
            (Some(n), Some(0))
        );
        let c = passes_counts(&[
            "--layers",
            &layers,
            "--variant",
            "single-pass",
            "--format",
            "rgba16f",
        ]);
        assert_eq!(
            (c["single_pass"].as_u64(), c["layer"].as_u64()),
            (Some(1), Some(0))
        );
    }
    // A lens object tessellated on the GPU: every pass of its parts' tessellations first (per
    // part: three transfers, the begin and classify passes, eight a level over the default 13
    // levels, five for the leaves, texgen, six for the draw list, three copies of the counts and
    // the host's read), then every lens pass as before, waiting for each part's data, indices
    // and draws once.
    let gpu = passes_counts(&["--layers", "2", "--gpu-parts", "2"]);
    let cpu = passes_counts(&["--layers", "2"]);
    let per_part = 3 + 2 + 8 * 13 + 5 + 1 + 6 + 3 + 1;
    assert_eq!(
        (gpu["tessellation"].as_u64(), cpu["tessellation"].as_u64()),
        (Some(2 * per_part), Some(0))
    );
    assert_eq!(gpu["layer"], cpu["layer"]);
    let plan = lensmap(&["passes", "--layers", "2", "--gpu-parts", "2"]);
    let plan = String::from_utf8_lossy(&plan.stdout);
    for part in ["object0 output0", "object1 output0"] {
        for buffer in ["data", "indices", "draws"] {
            let waits = format!("{part} {buffer}: compute->vertex");
            assert_eq!(plan.matches(&waits).count(), 1, "{waits}:\n{plan}");
        }
    }
    let table = lensmap(&["passes", "--layers", "2"]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("src*(1-dstA)+dst") && text.contains("alpha-clear"),
        "{text}"
    );
    assert!(text.contains("1 prime + 8 layer + 3 alpha clear"), "{text}");
    // Four viewpoints is bad usage, naming the range.
    let four = lensmap(&["passes", "--viewpoints", "4"]);
    assert_eq!(four.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&four.stderr);
    assert!(
        stderr.contains("1..=3") || stderr.contains("1..4"),
        "{stderr}"
    );
    // The other blending schemes: the same layer passes, arranged as each describes.
    let blended = |blend: &str| passes_counts(&["--layers", "3", "--blend", blend]);
    let c = blended("back-to-front");
    assert_eq!(
        (
            c["layer"].as_u64(),
            c["scratch_clear"].as_u64(),
            c["group_sum"].as_u64()
        ),
        (Some(12), Some(4), Some(4))
    );
    let c = blended("group-targets");
    assert_eq!(
        (
            c["layer"].as_u64(),
            c["alpha_clear"].as_u64(),
            c["group_sum"].as_u64()
        ),
        (Some(12), Some(0), Some(1))
    );
    let c = blended("programmable");
    assert_eq!(
        (c["layer"].as_u64(), c["rendering_instances"].as_u64()),
        (Some(12), Some(13))
    );
}

#[test]
fn bad_usage_exits_2_with_one_line() {
    let out = lensmap(&["passes", "--layers", "9", "--variant", "single-pass"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("--layers") && stderr.contains("multipass"),
        "{stderr}"
    );
}

#[test]
fn a_blending_scheme_for_the_single_pass_exits_2_naming_the_fix() {
    let out = lensmap(&[
        "passes",
        "--variant",
        "single-pass",
        "--blend",
        "programmable",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("--blend programmable") && stderr.contains("--variant multipass"),
        "{stderr}"
    );
}

#[test]
fn no_vulkan_driver_exits_2_naming_the_package() {
    let out = Command::new(env!("CARGO_BIN_EXE_lensmap"))
        .args([
            "demo",
            "--out",
            &std::env::temp_dir()
                .join("lensmap-no-driver")
                .to_string_lossy(),
        ])
        .env("VK_ICD_FILENAMES", "/nonexistent")
        .env("VK_DRIVER_FILES", "/nonexistent")
        .output()
        .expect("the lensmap binary runs");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("mesa-vulkan-drivers"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn render_with_a_missing_bake_exits_2_naming_it() {
    let out = lensmap(&[
        "render",
        "--scene",
        "glass-sphere",
        "--bake",
        "/nonexistent/lensmap-bake",
        "--out",
        "/tmp/lensmap-cli-render.png",
    ]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("/nonexistent/lensmap-bake"), "{stderr}");
}

#[test]
fn render_with_an_unknown_scene_exits_2() {
    let out = lensmap(&["render", "--scene", "no-such-scene", "--projected"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no-such-scene"));
}

#[test]
fn a_malformed_scene_file_exits_2_with_file_and_line() {
    let dir = std::env::temp_dir().join(format!("lensmap-cli-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.toml");
    std::fs::write(&path, "[camera]\nposition = [0, 1, 2\n").unwrap();
    let scene = path.to_string_lossy().to_string();
    for command in [
        &[
            "reference",
            "--scene",
            &scene,
            "--out",
            "/tmp/lensmap-cli-ref",
        ][..],
        &["render", "--scene", &scene, "--projected"][..],
    ] {
        let out = lensmap(command);
        assert_eq!(out.status.code(), Some(2), "{command:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains("broken.toml") && !stderr.contains("panicked"),
            "{stderr}"
        );
    }
}

#[test]
fn passes_prints_the_golden_plans() {
    // The golden plans the engine's unit test checks (engine/src/render/golden), as the command
    // prints them: every n, viewpoint count, material and variant.
    let golden_dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../engine/src/render/golden");
    let trimmed =
        |text: &str| -> Vec<String> { text.lines().map(|l| l.trim_end().to_owned()).collect() };
    for variant in ["multipass", "single-pass"] {
        for viewpoints in ["1", "2", "3"] {
            for (material, terms) in [("glass", "greedy"), ("mirror", "mirror")] {
                let golden = std::fs::read_to_string(
                    golden_dir.join(format!("{variant}-{viewpoints}-viewpoint-{material}.txt")),
                )
                .expect("golden plan file");
                let sections: Vec<&str> = golden.split("# n = ").skip(1).collect();
                assert_eq!(sections.len(), 4);
                for (n, section) in (1..=4).zip(sections) {
                    let plan: Vec<String> = trimmed(section).into_iter().skip(1).collect();
                    let layers = n.to_string();
                    let out = lensmap(&[
                        "passes",
                        "--layers",
                        &layers,
                        "--viewpoints",
                        viewpoints,
                        "--terms",
                        terms,
                        "--variant",
                        variant,
                        "--format",
                        "rgba8",
                    ]);
                    assert!(out.status.success());
                    let printed = trimmed(&String::from_utf8_lossy(&out.stdout));
                    assert_eq!(
                        printed[..plan.len()],
                        plan[..],
                        "{variant} {viewpoints} viewpoint(s) {material} n = {n}"
                    );
                }
            }
        }
    }
}

#[test]
fn out_of_range_options_exit_2_naming_the_flag() {
    for (flag, value) in [
        ("--t", "0"),
        ("--angle-degrees", "200"),
        ("--em-size", "0"),
        ("--fresnel", "table:1"),
        ("--fresnel", "table:4097"),
    ] {
        let option = format!("{flag}={value}");
        let out = lensmap(&[
            "render",
            "--scene",
            "glass-sphere",
            "--projected",
            &option,
            "--out",
            "/tmp/lensmap-cli-option.png",
        ]);
        assert_eq!(out.status.code(), Some(2), "{option}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains(&format!("{flag} {value}:")),
            "{option}: {stderr}"
        );
    }
}

/// `bench passes` measures the formats' error over the lens pixels found from the geometry: on
/// the synthetic sphere, for every blending scheme and the single pass, with one, two and three
/// viewpoints, RGBA8 and RGBA16F differ from the multipass front-to-back RGBA32F frame there
/// (non-zero, and RGBA8 more), and every RGBA32F row is within 1e-5 of it; a camera that sees no lens object is exit 2 naming
/// the fix, never a table of zeros.
#[test]
fn bench_passes_errors_are_over_the_geometric_lens_mask_and_an_empty_mask_is_refused() {
    // The GPU runs with the validation layer on (a message fails the run).
    let validated = common::lensmap;
    let out = validated(&[
        "bench",
        "passes",
        "--json",
        "--width",
        "48",
        "--height",
        "36",
        "--frames",
        "1",
        "--max-layers",
        "1",
        "--blend",
        "all",
        "--viewpoints",
        "all",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("validation"), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let rows = report["rows"].as_array().expect("rows");
    // n = 1 with one, two and three viewpoints, four schemes and the single pass, three formats.
    assert_eq!(rows.len(), 3 * 5 * 3);
    let rms = |viewpoints: u64, variant: &str, blend: &str, format: &str| {
        rows.iter()
            .find(|r| {
                r["viewpoints"] == viewpoints
                    && r["variant"] == variant
                    && r["blend"] == blend
                    && r["format"] == format
            })
            .and_then(|r| r["rms_vs_reference"].as_f64())
            .expect("a row per viewpoint count, scheme and format")
    };
    let compositings = [
        ("multipass", "front-to-back"),
        ("multipass", "back-to-front"),
        ("multipass", "group-targets"),
        ("multipass", "programmable"),
        ("single-pass", "-"),
    ];
    for viewpoints in [1, 2, 3] {
        for (variant, blend) in compositings {
            let (rgba8, rgba16f) = (
                rms(viewpoints, variant, blend, "rgba8"),
                rms(viewpoints, variant, blend, "rgba16f"),
            );
            assert!(
                rgba8 > rgba16f && rgba16f > 0.0,
                "{variant} {blend}: {rgba8} {rgba16f}"
            );
            // Every scheme is exact in RGBA32F: within 1e-5 of the reference (which is the
            // multipass front-to-back row itself: 0).
            assert!(rms(viewpoints, variant, blend, "rgba32f") <= 1e-5);
        }
        assert_eq!(
            rms(viewpoints, "multipass", "front-to-back", "rgba32f"),
            0.0
        );
    }
    let lens_pixels = rows[0]["lens_pixels"].as_u64().expect("the mask's size");
    assert!(
        (100..48 * 36).contains(&lens_pixels),
        "the sphere covers part of the frame: {lens_pixels}"
    );

    let away = validated(&[
        "bench",
        "passes",
        "--width",
        "32",
        "--height",
        "24",
        "--frames",
        "1",
        "--scene",
        "glass-sphere",
        "--em-size",
        "16",
        "--camera-position",
        "0,2.5,5",
        "--look-at",
        "0,2.5,10",
    ]);
    assert_eq!(away.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&away.stderr);
    assert!(
        stderr.contains("cover no pixel") && stderr.contains("--look-at"),
        "{stderr}"
    );
}

/// `bench error` on a tiny frame: the default, the moved knob asked for and the three baselines
/// each get a time, a lens PSNR and a lens SSIM; at least one point is on the Pareto frontier and no point on
/// it is beaten in both time and error by another; the CSV has a row per point and the plot is
/// written as SVG and PNG.
#[test]
fn bench_error_measures_time_and_error_with_baselines_and_a_frontier() {
    let dir = common::temp_dir("cli", "bench-error");
    let (csv, plot) = (dir.join("error.csv"), dir.join("plot"));
    let out = common::lensmap_command(&[
        "bench",
        "error",
        "--json",
        "--width",
        "24",
        "--height",
        "18",
        "--reference-supersampling",
        "2",
        "--frames",
        "1",
        "--only",
        "t=8 angle=3° em=128 layers=all single-pass rgba16f ss=1",
        "--csv",
    ])
    .arg(&csv)
    .arg("--plot")
    .arg(&plot)
    .output()
    .expect("the lensmap binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("validation"), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let points = report["points"].as_array().expect("points");
    let series: Vec<&str> = points.iter().filter_map(|p| p["series"].as_str()).collect();
    assert_eq!(
        series,
        [
            "default",
            "t",
            "baseline: EM at infinity",
            "baseline: box probe",
            "baseline: ray tracer, 1 spp"
        ]
    );
    let measured = |p: &serde_json::Value| {
        (
            p["frame_ms"].as_f64().expect("a time"),
            p["lens_psnr_db"].as_f64().expect("an error"),
        )
    };
    for point in points {
        let (ms, db) = measured(point);
        assert!(
            ms > 0.0 && db.is_finite() && db > 0.0 && db < 100.0,
            "{point}"
        );
        assert_eq!(point["per_camera"].as_array().map(Vec::len), Some(3));
    }
    let frontier: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p["on_frontier"] == true)
        .map(measured)
        .collect();
    assert!(!frontier.is_empty());
    for &(ms, db) in &frontier {
        assert!(
            !points.iter().map(measured).any(|(m, d)| m < ms && d > db),
            "a frontier point ({ms} ms, {db} dB) is beaten"
        );
    }
    let table = std::fs::read_to_string(&csv).expect("the CSV");
    assert_eq!(table.lines().count(), 1 + points.len());
    // Eight fields a row (the last two, f32 against f64, empty but for the CPU-precision
    // settings): commas only between fields (names with commas are quoted).
    for line in table.lines() {
        let mut fields = 1;
        let mut quoted = false;
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => fields += 1,
                _ => {}
            }
        }
        assert_eq!(fields, 8, "{line}");
    }
    for name in ["pareto.svg", "pareto.png"] {
        let bytes = std::fs::metadata(plot.join(name))
            .map(|m| m.len())
            .unwrap_or(0);
        assert!(
            bytes > 1000,
            "{name}: {bytes} bytes (fonts-dejavu-core installed?)"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench error --reference-tree full` judges every point against the full ray tree, reports
/// that reference's convergence per camera, and puts the class set on the sweep: on the glass
/// ball, 4 path classes come closer to the full tree than the papers' two greedy terms (the
/// default), which drop the light of the weaker child at every interface.
#[test]
fn bench_error_against_the_full_tree_sweeps_path_classes() {
    let report = json_report(&[
        "bench",
        "error",
        "--json",
        "--scene",
        "glass-sphere",
        "--sample",
        "0",
        "--width",
        "48",
        "--height",
        "36",
        "--reference-supersampling",
        "2",
        "--frames",
        "1",
        "--reference-tree",
        "full",
        "--only",
        "terms=4",
    ]);
    assert_eq!(report["reference_tree"], "full");
    let convergence = report["reference_convergence"]["lens_psnr_db_per_camera"]
        .as_array()
        .expect("the full tree's convergence");
    assert_eq!(convergence.len(), 3);
    assert!(
        convergence
            .iter()
            .all(|db| db.as_f64().is_some_and(f64::is_finite))
    );
    let points = report["points"].as_array().expect("points");
    let psnr = |series: &str, setting: &str| {
        points
            .iter()
            .find(|p| {
                p["series"] == series && p["setting"].as_str().is_some_and(|s| s.contains(setting))
            })
            .and_then(|p| p["lens_psnr_db"].as_f64())
            .unwrap_or_else(|| panic!("a {series} point with {setting}: {report}"))
    };
    let greedy = psnr("default", "t=3");
    let classes = psnr(
        "path classes",
        "t=3 angle=3° em=128 layers=all multipass rgba16f ss=1 terms=4",
    );
    assert!(
        classes > greedy + 0.5,
        "4 classes {classes:.2} dB against greedy {greedy:.2} dB, both against the full tree"
    );
}

/// `bench hybrid` times every stage for greedy and for 3, 4 and 6 path classes, by the multipass
/// variant and by the single pass: the multipass frame's layer passes grow by the same count per
/// class past the two greedy terms (each term draws its layers once per viewpoint sample), and 6
/// classes trace more ray segments than the two greedy paths; the single pass draws each of them
/// in one pass (glass-sphere's one layer per viewpoint sample: 6 classes take 6·2 = 12 of the 16
/// varyings), and names itself in its rows. The CPU tracer's rows, then the GPU tracer's alike.
#[test]
fn bench_hybrid_times_the_stages_of_path_classes() {
    let report = json_report(&[
        "bench",
        "hybrid",
        "--json",
        "--scene",
        "glass-sphere",
        "--width",
        "32",
        "--height",
        "24",
        "--frames",
        "1",
    ]);
    for (key, tracer) in [("path_classes", "cpu"), ("path_classes_gpu_tracer", "gpu")] {
        assert_eq!(report[key]["tracer"], tracer, "{key}");
        path_class_rows(&report[key]);
    }
    // The same lens passes on either tracer (the GPU's compute passes are not counted).
    let passes = |key: &str| -> Vec<u64> {
        let rows = report[key]["rows"].as_array().expect("rows");
        rows.iter()
            .filter_map(|r| r["layer_passes"].as_u64())
            .collect()
    };
    assert_eq!(passes("path_classes"), passes("path_classes_gpu_tracer"));
}

/// The checks of [`bench_hybrid_times_the_stages_of_path_classes`] on one tracer's rows.
fn path_class_rows(part: &serde_json::Value) {
    let rows = part["rows"].as_array().expect("the path-class rows");
    let text = |key: &str| -> Vec<&str> { rows.iter().filter_map(|r| r[key].as_str()).collect() };
    assert_eq!(
        text("terms"),
        ["greedy", "3", "4", "6", "greedy", "3", "4", "6"]
    );
    assert_eq!(
        text("variant"),
        [
            "multipass",
            "multipass",
            "multipass",
            "multipass",
            "single pass",
            "single pass",
            "single pass",
            "single pass"
        ]
    );
    let count = |row: &serde_json::Value, key: &str| row[key].as_u64().expect("a count");
    let passes: Vec<u64> = rows.iter().map(|r| count(r, "layer_passes")).collect();
    assert!(passes[..4].windows(2).all(|w| w[0] < w[1]), "{passes:?}");
    let per_class = passes[1] - passes[0];
    assert_eq!(passes[2] - passes[0], 2 * per_class, "{passes:?}");
    assert_eq!(passes[3] - passes[0], 4 * per_class, "{passes:?}");
    assert!(
        passes[4..].iter().all(|&p| p == passes[4]) && passes[4] < passes[0],
        "{passes:?}"
    );
    let varyings: Vec<u64> = rows.iter().map(|r| count(r, "varyings")).collect();
    assert_eq!(varyings, [0, 6, 8, 12, 0, 6, 8, 12]);
    assert!(
        count(&rows[3], "rays") > count(&rows[0], "rays"),
        "{rows:?}"
    );
    for row in rows {
        let total = row["median_ms"]["total"].as_f64().expect("a time");
        assert!(total > 0.0, "{row}");
    }
}

/// `bench fresnel` reports, per table size, an error within the derived bound 2.5/(N − 1)² and
/// near it; per material of mirror-teapot and glass-sphere, the mirror's error against exact
/// Schlick at most (1 − R₀) of that, and for glass both sides against exact Fresnel. A `--fresnel`
/// that is neither `exact` nor `table:N` is a usage error naming the forms.
#[test]
fn bench_fresnel_reports_errors_within_the_bound_and_bad_forms_exit_2() {
    let out = lensmap(&[
        "bench",
        "fresnel",
        "--texels",
        "16,256",
        "--samples",
        "8192",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
    let tables = json["tables"].as_array().expect("tables");
    assert_eq!(tables.len(), 2);
    for table in tables {
        let n = table["texels"].as_f64().unwrap();
        let bound = 2.5 / (n - 1.0).powi(2);
        let measured = table["measured"].as_f64().unwrap();
        assert!((table["bound"].as_f64().unwrap() - bound).abs() < 1e-15);
        assert!(
            measured <= bound + 1e-7 && measured > 0.8 * bound,
            "N = {n}: {measured}"
        );
        let materials = table["materials"].as_array().unwrap();
        let mirror = materials
            .iter()
            .find(|m| {
                m["material"]
                    .as_str()
                    .unwrap()
                    .starts_with("mirror-teapot:mirror")
            })
            .expect("mirror-teapot's silver");
        let against_schlick = mirror["errors"]["against_schlick"].as_f64().unwrap();
        assert!(against_schlick <= 0.05 * measured * (1.0 + 1e-6) + 1e-9);
        let glass = materials
            .iter()
            .find(|m| {
                m["material"]
                    .as_str()
                    .unwrap()
                    .starts_with("glass-sphere:glass")
            })
            .expect("glass-sphere's glass");
        let sides = glass["errors"]["against_dielectric"].as_array().unwrap();
        assert_eq!(sides.len(), 2, "entering and leaving");
        assert!(sides.iter().all(|e| e.as_f64().unwrap() > 0.0));
    }
    let out = lensmap(&[
        "render",
        "--scene",
        "glass-sphere",
        "--projected",
        "--fresnel",
        "tabel:8",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("give exact or table:N"), "{stderr}");
}

/// `bench classes` on a small glass-sphere: four path classes keep more of the full tree's lens
/// light than the greedy terms (which miss the internal reflections), the full tree's
/// convergence and the ranked classes are reported, and the scene's top four are judged too.
#[test]
fn bench_classes_judges_models_against_the_full_tree() {
    let out = lensmap(&[
        "bench",
        "classes",
        "--scenes",
        "glass-sphere",
        "--tree",
        "greedy",
        "--tree",
        "4",
        "--width",
        "48",
        "--height",
        "36",
        "--supersampling",
        "1",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 3, "greedy, 4 and the top four: {report}");
    let ratio = |tree: &str| {
        rows.iter()
            .find(|r| r["tree"] == tree)
            .and_then(|r| r["radiance_ratio"].as_f64())
            .unwrap_or_else(|| panic!("a {tree} row: {report}"))
    };
    assert!(ratio("greedy") < 0.9 && ratio("4") > 0.98, "{report}");
    let reference = &report["references"][0];
    assert!(reference["convergence_psnr_srgb_db"].as_f64().unwrap() > 0.0);
    assert_eq!(reference["ranked_classes"][0][0], "TT", "{reference}");
}
