//! `lensmap view --record`: a camera path rendered headless, byte-identical across runs and equal
//! to `lensmap render` at the same cameras.

mod common;
use common::{read, succeeds, temp_dir};

const FRAME: [&str; 8] = [
    "--width",
    "64",
    "--height",
    "48",
    "--supersampling",
    "1",
    "--em-size",
    "16",
];

fn record(dir: &std::path::Path) {
    let mut args = vec![
        "view",
        "--scene",
        "glass-sphere",
        "--projected",
        "--path",
        "orbit",
        "--frames",
        "3",
        "--record",
        dir.to_str().unwrap(),
        "--quiet",
    ];
    args.extend(FRAME);
    succeeds(&args);
}

#[test]
fn a_recorded_orbit_repeats_byte_for_byte_and_equals_render_at_its_cameras() {
    let root = temp_dir("view", "record");
    let (one, two) = (root.join("one"), root.join("two"));
    record(&one);
    record(&two);
    for i in 0..3 {
        for extension in ["png", "exr"] {
            let name = format!("frame-{i:04}.{extension}");
            assert!(
                read(&one.join(&name)) == read(&two.join(&name)),
                "{name} differs between two runs"
            );
        }
    }
    let csv = String::from_utf8(read(&one.join("stats.csv"))).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 4, "{csv}");
    assert!(rows[0].starts_with("frame,position_x"), "{csv}");
    for (i, row) in rows[1..].iter().enumerate() {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields[0], i.to_string(), "{row}");
        let (position, look_at) = (fields[1..4].join(","), fields[4..7].join(","));
        let out = root.join(format!("render-{i}.png"));
        let mut args = vec![
            "render",
            "--scene",
            "glass-sphere",
            "--projected",
            "--quiet",
        ];
        args.extend(FRAME);
        let position = format!("--camera-position={position}");
        let look_at = format!("--look-at={look_at}");
        args.extend([
            position.as_str(),
            look_at.as_str(),
            "--out",
            out.to_str().unwrap(),
        ]);
        succeeds(&args);
        for extension in ["png", "exr"] {
            assert!(
                read(&out.with_extension(extension))
                    == read(&one.join(format!("frame-{i:04}.{extension}"))),
                "frame {i} ({extension}) differs from lensmap render at its camera"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&root);
}
