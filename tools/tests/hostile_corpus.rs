//! The hostile-input corpus, through the `lensmap` binary: scene files, OBJ and image assets,
//! damaged bake directories, command-line options, a full disk, closed output streams
//! and sizes past every budget. Each refusal asserts the exit code (2 for bad input or usage, 1
//! for a failure of the work such as a full disk), exactly one line on stderr naming the file,
//! field or option concerned, no panic, that the earlier output at the same path is intact, and
//! (for sizes past a budget) that it came in under 5 s. Inputs that must be accepted are rendered
//! and their EXR checked for NaN and infinity. Every case says its name when it fails.
//!
//! (`tools/tests/hostile.rs`, `cli.rs`, `bake.rs` and `tests/tests/scene_errors.rs`,
//! `layers_bake.rs` hold more of it.)

mod common;
use common::{
    TINY_FRAME, TINY_RENDER, assert_success, lensmap, lensmap_command, on_full_disk, read,
};
use lensmap_tests::fixtures::{SMALL_SCENE, edit_scene};

use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

use lensmap::cubemap::CubeMap;
use lensmap::layers::bake::{read_cube_map_exr, write_cube_map_exr};

/// The longest a refusal of an over-budget size may take.
const OVER_BUDGET_LIMIT: Duration = Duration::from_secs(5);

/// `SMALL_SCENE` with `from` replaced by `to` (which must occur).
fn edit(from: &str, to: &str) -> String {
    edit_scene(SMALL_SCENE, from, to)
}

/// The floor of `SMALL_SCENE` made of the OBJ file `name`.
fn with_obj(name: &str) -> String {
    edit(
        "plane = { size = [4, 4] }",
        &format!("obj = {{ path = \"{name}\" }}"),
    )
}

/// The floor material of `SMALL_SCENE` textured with the image `name`.
fn with_texture(name: &str) -> String {
    edit(
        "diffuse = { colour = [0.5, 0.5, 0.5] }",
        &format!("diffuse = {{ image = \"{name}\" }}"),
    )
}

/// The environment of `SMALL_SCENE` a lat-long image `name` times `scale`.
fn with_sky(name: &str, scale: &str) -> String {
    edit(
        "constant = [0.1, 0.1, 0.1]",
        &format!("latlong = {{ path = \"{name}\", scale = {scale} }}"),
    )
}

/// A fresh folder under the system's temporary folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(common::temp_dir("hostile-corpus", name))
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to `name` in the folder (creating subfolders) and returns its path.
    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.path(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn text(path: &Path) -> &str {
    path.to_str().expect("UTF-8 temporary path")
}

/// A refusal: exit `code`, exactly one line on stderr holding every one of `names`, no panic
/// (`elapsed` is said when the exit code is wrong).
fn assert_refused(case: &str, output: &Output, elapsed: Duration, code: i32, names: &[&str]) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        !stderr.contains("panicked") && !stdout.contains("panicked"),
        "{case}: panicked: {stderr}"
    );
    assert_eq!(
        output.status.code(),
        Some(code),
        "{case}: exit code (after {elapsed:?}); stderr: {stderr}"
    );
    assert!(
        stderr.lines().count() == 1 && stderr.ends_with('\n'),
        "{case}: not exactly one line on stderr: {stderr:?}"
    );
    for name in names {
        assert!(
            stderr.contains(name),
            "{case}: does not name {name:?}: {stderr}"
        );
    }
}

/// Runs `lensmap args` and asserts a refusal (see [`assert_refused`]); `over_budget` also
/// demands it came in under [`OVER_BUDGET_LIMIT`].
fn refused(case: &str, args: &[&str], code: i32, names: &[&str], over_budget: bool) {
    let start = Instant::now();
    let output = lensmap(args);
    let elapsed = start.elapsed();
    assert_refused(case, &output, elapsed, code, names);
    if over_budget {
        assert!(
            elapsed < OVER_BUDGET_LIMIT,
            "{case}: an over-budget size took {elapsed:?} to refuse"
        );
    }
}

/// Runs `lensmap args`, expecting success ([`assert_success`]).
fn succeeds(case: &str, args: &[&str]) {
    assert_success(case, &lensmap(args));
}

/// Every value of the EXR at `path` is finite.
fn assert_finite_exr(case: &str, path: &Path) {
    let image = image::open(path)
        .unwrap_or_else(|e| panic!("{case}: {}: {e}", path.display()))
        .into_rgb32f();
    let bad = image.pixels().flat_map(|p| p.0).filter(|v| !v.is_finite());
    assert_eq!(
        bad.count(),
        0,
        "{case}: NaN or infinity in {}",
        path.display()
    );
}

/// The PNG and EXR at `out` (a `.png` path) and their bytes, to check they survive a refusal.
struct Earlier {
    files: Vec<(PathBuf, Vec<u8>)>,
}

impl Earlier {
    fn of(out: &Path) -> Earlier {
        let files = [out.with_extension("png"), out.with_extension("exr")]
            .into_iter()
            .map(|path| {
                let bytes = read(&path);
                (path, bytes)
            })
            .collect();
        Earlier { files }
    }

    /// Runs `lensmap args`: refused with exit 2 and one line naming `names` ([`refused`]),
    /// these files intact.
    fn refused_intact(&self, case: &str, args: &[&str], names: &[&str], over_budget: bool) {
        refused(case, args, 2, names, over_budget);
        self.assert_intact(case);
    }

    fn assert_intact(&self, case: &str) {
        for (path, bytes) in &self.files {
            assert!(
                std::fs::read(path).ok().as_ref() == Some(bytes),
                "{case}: the earlier {} was changed",
                path.display()
            );
        }
        // Nothing else (no temporary) left beside them.
        let folder = self.files[0].0.parent().unwrap();
        let stray: Vec<_> = std::fs::read_dir(folder)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|name| name.ends_with(".tmp"))
            .collect();
        assert!(stray.is_empty(), "{case}: left {stray:?}");
    }
}

/// `render --scene SCENE --projected --em-size 8 --out OUT` (the scene's own 16×12 camera).
fn render_scene(scene: &Path, out: &Path) -> Vec<String> {
    [
        "render",
        "--scene",
        text(scene),
        "--projected",
        "--em-size",
        "8",
    ]
    .into_iter()
    .chain(["--out", text(out)])
    .map(String::from)
    .collect()
}

/// `render --scene glass-sphere --bake BAKE` at the tiny frame, to `out`.
fn render_bake(bake: &Path, out: &Path) -> Vec<String> {
    ["render", "--scene", "glass-sphere", "--bake", text(bake)]
        .into_iter()
        .chain(TINY_FRAME)
        .chain(["--out", text(out)])
        .map(String::from)
        .collect()
}

fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

/// A valid render to `out` from `scene`, its EXR finite: the earlier output every refusal of a
/// table must leave intact, and the proof that the table's base input is good.
fn control_render(case: &str, scene: &Path, out: &Path) -> Earlier {
    succeeds(case, &strs(&render_scene(scene, out)));
    assert_finite_exr(case, &out.with_extension("exr"));
    Earlier::of(out)
}

/// One scene-file case: the scene's text (or bytes), the names the message must hold, and
/// whether it is a size past a budget.
struct SceneCase {
    /// What it is, for failure messages.
    case: &'static str,
    /// The scene file's content.
    scene: Vec<u8>,
    /// The field (and whatever else) the one line must name; the file is always checked.
    names: &'static [&'static str],
    /// A size past a budget: refused in under 5 s.
    over_budget: bool,
}

fn scene_case(
    case: &'static str,
    scene: impl Into<Vec<u8>>,
    names: &'static [&'static str],
) -> SceneCase {
    SceneCase {
        case,
        scene: scene.into(),
        names,
        over_budget: false,
    }
}

fn over_budget(case: SceneCase) -> SceneCase {
    SceneCase {
        over_budget: true,
        ..case
    }
}

/// Writes each case's scene as `<case>.toml` and runs `render` on it: exit 2, one line naming
/// the scene file and the field, the earlier frame at `--out` intact.
fn assert_scene_cases(scratch: &Scratch, earlier: &Earlier, out: &Path, cases: Vec<SceneCase>) {
    for SceneCase {
        case,
        scene,
        names,
        over_budget,
    } in cases
    {
        let file_name = format!("{case}.toml");
        let path = scratch.write(&file_name, &scene);
        let mut all = vec![file_name.as_str()];
        all.extend_from_slice(names);
        earlier.refused_intact(case, &strs(&render_scene(&path, out)), &all, over_budget);
    }
}

/// Scene files: values that are NaN, infinite, of the wrong type, unknown or enormous, an empty
/// file, binary garbage and a folder where the file should be.
#[test]
fn hostile_scene_files_are_refused_naming_the_field() {
    let scratch = Scratch::new("scene");
    let base = scratch.write("base.toml", SMALL_SCENE);
    let out = scratch.path("frames/frame.png");
    let earlier = control_render("the base scene", &base, &out);

    let many_views: Vec<String> = (0..10_001)
        .map(|i| format!("[{}, 1, 5]", f64::from(i) * 1e-3))
        .collect();
    let cases = vec![
        // An empty file: no [camera].
        scene_case("empty-file", "", &["missing field `camera`"]),
        // Binary garbage, not UTF-8.
        scene_case(
            "binary-garbage",
            b"\x7fELF\x02\x01\x01\x00\xff\xfe\x00\x00[camera]\x00\x9c".to_vec(),
            &["cannot read the scene file", "UTF-8"],
        ),
        // TOML that is text but not TOML.
        scene_case(
            "not-toml",
            "<scene><camera/></scene>\n",
            &[":1:", "correct the TOML"],
        ),
        // `nan` is a TOML float: an index of refraction that is NaN.
        scene_case(
            "nan-ior",
            edit("ior = 1.5", "ior = nan"),
            &["materials[0].glass.ior", "NaN"],
        ),
        // An infinite field of view.
        scene_case(
            "inf-vfov",
            edit("vfov_degrees = 45", "vfov_degrees = inf"),
            &["camera.vfov_degrees", "inf"],
        ),
        // A light at minus infinity.
        scene_case(
            "inf-light-position",
            edit("position = [0, 5, 0]", "position = [0, -inf, 0]"),
            &["lights[0].position", "non-finite"],
        ),
        // A light whose intensity is NaN.
        scene_case(
            "nan-light-intensity",
            edit("intensity = [10, 10, 10]", "intensity = [nan, 10, 10]"),
            &["lights[0].intensity", "NaN"],
        ),
        // A negative width: not a u32.
        scene_case(
            "negative-width",
            edit("width = 16", "width = -3"),
            &["camera.width", "-3"],
        ),
        // A string where a number belongs.
        scene_case(
            "string-height",
            edit("height = 12", "height = \"tall\""),
            &["camera.height", "invalid type"],
        ),
        // A string where a list of object names belongs.
        scene_case(
            "string-lens-objects",
            format!("{SMALL_SCENE}\n[[lenses]]\nname = \"lens\"\nobjects = \"ball\"\n"),
            &["lenses[0].objects", "invalid type"],
        ),
        // A misspelt field of a light.
        scene_case(
            "unknown-light-field",
            edit(
                "intensity = [10, 10, 10]",
                "intensity = [10, 10, 10]\ncolour = [1, 1, 1]",
            ),
            &["lights[0].colour", "unknown field"],
        ),
        // An unknown top-level table.
        scene_case(
            "unknown-table",
            format!("{SMALL_SCENE}\n[renderer]\nsamples = 4\n"),
            &["renderer", "unknown field"],
        ),
        // Two materials of one name.
        scene_case(
            "duplicate-material",
            edit("name = \"grey\"", "name = \"glass\""),
            &["materials[1].name", "used twice"],
        ),
        // Both a constant environment and a lat-long one.
        scene_case(
            "two-environments",
            edit(
                "constant = [0.1, 0.1, 0.1]",
                "constant = [0.1, 0.1, 0.1]\nlatlong = { path = \"sky.exr\" }",
            ),
            &["environment", "exactly one"],
        ),
        // A camera 1e30 m away (refused for its distance, not as "camera.up … parallel to the
        // view direction").
        scene_case(
            "far-camera",
            edit("position = [0, 1, 5]", "position = [0, 1, 1e30]"),
            &["camera.position", "1e6 m"],
        ),
        // A viewpoint sample 1e30 m away.
        scene_case(
            "far-viewpoint",
            format!("{SMALL_SCENE}\n[view_space]\nlist = [[0, 1, 1e30]]\n"),
            &["view_space sample 0", "1e6 m"],
        ),
        // A sphere of radius 1e30 m (refused for its size, not as "181 degenerate (zero-area)
        // triangles").
        scene_case(
            "huge-sphere",
            edit("radius = 1,", "radius = 1e30,"),
            &["objects[0].sphere.radius", "1e6 m"],
        ),
        // An object moved 1e30 m away (refused before the BVH builder, which would panic on it).
        scene_case(
            "far-translate",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "sphere = { radius = 1, segments = 16, rings = 8 }\ntransform = { translate = [1e30, 0, 0] }",
            ),
            &["objects[0].transform", "1e6 m"],
        ),
        // An object moved 1e20 m away (refused at load, not as "frame input: view_proj has NaN or
        // infinite entries").
        scene_case(
            "farther-translate",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "sphere = { radius = 1, segments = 16, rings = 8 }\ntransform = { translate = [0, 1e20, 0] }",
            ),
            &["objects[0].transform", "1e6 m"],
        ),
        // A floor 1e9 m wide (refused before the light-map atlas, whose size arithmetic would
        // overflow).
        scene_case(
            "huge-plane",
            edit("size = [4, 4]", "size = [1e9, 1e9]"),
            &["objects[1].plane.size", "1e6 m"],
        ),
        // A scale of 1e30 turning the sphere into overflowing triangles.
        scene_case(
            "huge-scale",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "sphere = { radius = 1, segments = 16, rings = 8 }\ntransform = { scale = 1e30 }",
            ),
            &["objects[0].transform", "1e6 m"],
        ),
        // An environment of 1e38 (refused at load, not as "frame input: lenses[0] (ball).layers[0][0]
        // … is inf").
        scene_case(
            "huge-environment",
            edit(
                "constant = [0.1, 0.1, 0.1]",
                "constant = [1e38, 1e38, 1e38]",
            ),
            &["environment.constant", "1e30"],
        ),
        // A light of 3e38 W/sr.
        scene_case(
            "huge-light",
            edit("intensity = [10, 10, 10]", "intensity = [3e38, 3e38, 3e38]"),
            &["lights[0].intensity", "1e30"],
        ),
        // A width that does not fit a u32.
        over_budget(scene_case(
            "width-beyond-u32",
            edit("width = 16", "width = 99999999999"),
            &["camera.width", "99999999999"],
        )),
        // A width of 4e9 pixels: past the subpixel budget.
        over_budget(scene_case(
            "width-past-the-budget",
            edit("width = 16", "width = 4000000000"),
            &["camera", "4000000000×12 subpixels", "the limit is 16384"],
        )),
        // 100000×100000 supersampling.
        over_budget(scene_case(
            "supersampling-past-the-budget",
            edit("supersampling = 1", "supersampling = 100000"),
            &["camera", "1600000×1200000 subpixels"],
        )),
        // A torus of 4096×4096 segments: 33 million triangles.
        over_budget(scene_case(
            "torus-past-the-budget",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "torus = { major_radius = 1, minor_radius = 0.3, major_segments = 4096, minor_segments = 4096 }",
            ),
            &["objects[0].torus.major_segments", "33554432 triangles"],
        )),
        // A teapot tessellated 100000 times.
        over_budget(scene_case(
            "teapot-past-the-budget",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "teapot = { tessellation = 100000 }",
            ),
            &["objects[0].teapot.tessellation", "100000"],
        )),
        // A cylinder of 4 billion segments.
        over_budget(scene_case(
            "cylinder-past-the-budget",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "cylinder = { radius = 1, height = 1, segments = 4000000000 }",
            ),
            &["objects[0].cylinder.segments", "4000000000"],
        )),
        // 10001 viewpoint samples in a list.
        over_budget(scene_case(
            "view-list-past-the-budget",
            format!(
                "{SMALL_SCENE}\n[view_space]\nlist = [{}]\n",
                many_views.join(", ")
            ),
            &["view_space.list", "10001 viewpoint samples"],
        )),
    ];
    assert_scene_cases(&scratch, &earlier, &out, cases);

    // A folder given as the scene, with and without a .toml name.
    for (case, name) in [
        ("folder-as-scene", "scenes"),
        ("folder-named-toml", "dir.toml"),
    ] {
        let folder = scratch.path(name);
        std::fs::create_dir_all(&folder).unwrap();
        earlier.refused_intact(
            case,
            &strs(&render_scene(&folder, &out)),
            &[text(&folder), "cannot read the scene file"],
            false,
        );
    }
}

/// A PNG's IHDR and the rest: `width`×`height` RGB8 whose one IDAT holds `raw` (zlib-stored).
fn png_with_header(width: u32, height: u32, raw: &[u8]) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend((data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend(&body);
        out.extend(crc32(&body).to_be_bytes());
    }
    // zlib with one stored block (no compression): header, block, Adler-32.
    let mut zlib = vec![0x78, 0x01, 0x01];
    zlib.extend((raw.len() as u16).to_le_bytes());
    zlib.extend((!(raw.len() as u16)).to_le_bytes());
    zlib.extend_from_slice(raw);
    let (mut a, mut b) = (1u32, 0u32);
    for &byte in raw {
        a = (a + u32::from(byte)) % 65521;
        b = (b + a) % 65521;
    }
    zlib.extend(((b << 16) | a).to_be_bytes());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut header = width.to_be_bytes().to_vec();
    header.extend(height.to_be_bytes());
    header.extend([8, 2, 0, 0, 0]); // 8-bit RGB, no interlace
    chunk(&mut png, b"IHDR", &header);
    chunk(&mut png, b"IDAT", &zlib);
    chunk(&mut png, b"IEND", &[]);
    png
}

/// A `width`×`height` float RGB EXR whose texel (1, 0) is `bad` (0.5 elsewhere).
fn exr_with(width: u32, height: u32, bad: f32) -> Vec<u8> {
    let mut pixels = vec![0.5f32; (width * height * 3) as usize];
    pixels[3] = bad;
    let image = image::Rgb32FImage::from_raw(width, height, pixels).unwrap();
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, image::ImageFormat::OpenExr)
        .unwrap();
    bytes.into_inner()
}

/// OBJ assets: empty, without faces, indices out of range or overflowing, non-UTF-8, NaN
/// normals and uvs, unparsable numbers, enormous coordinates, a polyline, a folder.
#[test]
fn hostile_obj_assets_are_refused_naming_the_object() {
    let scratch = Scratch::new("obj");
    let good_obj = "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 3 2\nf 1 4 3\n";
    scratch.write("good.obj", good_obj);
    let base = scratch.write("base.toml", with_obj("good.obj"));
    let out = scratch.path("frames/frame.png");
    let earlier = control_render("a good OBJ", &base, &out);

    let triangle = "v 0 0 0\nv 1 0 0\nv 0 0 1\n";
    let cases: Vec<(&str, Vec<u8>, &[&str])> = vec![
        // A zero-byte file.
        ("empty", Vec::new(), &["no triangles"]),
        // Vertices and no face.
        ("no-faces", triangle.into(), &["no triangles"]),
        // A face naming vertex 7 of 3.
        (
            "index-out-of-range",
            format!("{triangle}f 1 2 7\n").into(),
            &[
                "line 4 (`f 1 2 7`)",
                "position (v) index 7 is not one of the 3",
            ],
        ),
        // A face naming vertex 4294967295.
        (
            "index-u32-max",
            format!("{triangle}f 1 2 4294967295\n").into(),
            &["line 4", "index 4294967295 is not one of the 3"],
        ),
        // A face index past every integer type.
        (
            "index-overflow",
            format!("{triangle}f 1 2 99999999999999999999\n").into(),
            &["line 4", "index 99999999999999999999 is not one of the 3"],
        ),
        // Index 0 (OBJ indices start at 1).
        (
            "index-zero",
            format!("{triangle}f 1 2 0\n").into(),
            &["line 4", "index 0 is not one of the 3"],
        ),
        // A relative index reaching before the first vertex.
        (
            "negative-index",
            format!("{triangle}f 1 2 -9\n").into(),
            &["line 4", "index -9 is not one of the 3"],
        ),
        // Bytes that are not UTF-8 inside a vertex record.
        (
            "not-utf8",
            b"v 0 0 0\nv 1 0 \xff\xfe 0\nv 0 0 1\nf 1 2 3\n".to_vec(),
            &["line 2", "is not a number"],
        ),
        // A coordinate that is not a number.
        (
            "word-coordinate",
            b"v 0 0 0\nv abc 0 0\nv 0 0 1\nf 1 2 3\n".to_vec(),
            &["line 2 (`v abc 0 0`)", "`abc` is not a number"],
        ),
        // A NaN normal.
        (
            "nan-normal",
            format!("{triangle}vn nan 1 0\nf 1//1 2//1 3//1\n").into(),
            &["line 4 (`vn nan 1 0`)", "`nan` is not a finite number"],
        ),
        // A NaN texture coordinate.
        (
            "nan-uv",
            format!("{triangle}vt nan 0\nf 1/1 2/1 3/1\n").into(),
            &["line 4 (`vt nan 0`)", "`nan` is not a finite number"],
        ),
        // A coordinate that overflows f32 to infinity.
        (
            "overflowing-vertex",
            b"v 0 0 0\nv 1e39 0 0\nv 0 0 1\nf 1 2 3\n".to_vec(),
            &["line 2 (`v 1e39 0 0`)", "beyond f32"],
        ),
        // Finite but enormous coordinates (refused for their distance, not as "1 degenerate
        // (zero-area) triangle").
        (
            "enormous-vertex",
            b"v 0 0 0\nv 1e30 0 0\nv 0 0 1e30\nf 1 2 3\n".to_vec(),
            &["vertex 1", "1e6 m"],
        ),
        // A polyline, which is no surface.
        (
            "polyline",
            format!("{triangle}l 1 2 3\n").into(),
            &["line 4", "polyline"],
        ),
    ];
    for (case, bytes, names) in cases {
        let obj = format!("{case}.obj");
        scratch.write(&obj, &bytes);
        let scene = scratch.write(&format!("{case}.toml"), with_obj(&obj));
        let mut all = vec!["objects[1].obj.path", obj.as_str()];
        all.extend_from_slice(names);
        earlier.refused_intact(case, &strs(&render_scene(&scene, &out)), &all, false);
    }

    // The OBJ path names a folder; a missing OBJ.
    std::fs::create_dir_all(scratch.path("mesh.obj")).unwrap();
    for (case, obj, what) in [
        ("obj-is-a-folder", "mesh.obj", "Is a directory"),
        ("obj-missing", "nowhere/mesh.obj", "cannot read"),
    ] {
        let scene = scratch.write(&format!("{case}.toml"), with_obj(obj));
        earlier.refused_intact(
            case,
            &strs(&render_scene(&scene, &out)),
            &["objects[1].obj.path", obj, what],
            false,
        );
    }
}

/// Image assets a scene references: truncated, empty, with NaN, infinite or negative texels,
/// brighter than any radiance, or declaring 10¹⁰ pixels.
#[test]
fn hostile_image_assets_are_refused_naming_the_field() {
    let scratch = Scratch::new("image");
    let good_png = png_with_header(
        2,
        2,
        &[0, 128, 128, 128, 64, 64, 64, 0, 9, 9, 9, 200, 200, 200],
    );
    scratch.write("good.png", &good_png);
    scratch.write("good.exr", exr_with(4, 2, 0.25));
    let base = scratch.write("base.toml", with_texture("good.png"));
    let out = scratch.path("frames/frame.png");
    let earlier = control_render("a good PNG texture", &base, &out);
    // A good EXR sky renders too, and so does one at the radiance limit.
    scratch.write("bright.exr", exr_with(4, 2, 1e30));
    for (case, scene) in [
        ("a good EXR sky", with_sky("good.exr", "2")),
        ("a sky at the radiance limit", with_sky("bright.exr", "1")),
    ] {
        let scene = scratch.write("sky-control.toml", scene);
        let frame = scratch.path("sky/frame.png");
        succeeds(case, &strs(&render_scene(&scene, &frame)));
        assert_finite_exr(case, &frame.with_extension("exr"));
    }

    let good_exr = exr_with(4, 2, 0.25);
    const TEXTURE: &str = "materials[1].diffuse.image";
    const SKY: &str = "environment.latlong.path";
    /// The scene around an asset file name.
    type Scene = fn(&str) -> String;
    /// Case, asset file name, its bytes, the scene, the names the line must hold, over budget.
    type AssetCase = (
        &'static str,
        &'static str,
        Vec<u8>,
        Scene,
        &'static [&'static str],
        bool,
    );
    let textured: Scene = with_texture;
    let skied: Scene = |name| with_sky(name, "1");
    let cases: Vec<AssetCase> = vec![
        // A PNG cut in half.
        (
            "truncated-png",
            "wood.png",
            good_png[..good_png.len() / 2].to_vec(),
            textured,
            &[TEXTURE, "cannot read the image"],
            false,
        ),
        // A zero-byte PNG.
        (
            "empty-png",
            "wood.png",
            Vec::new(),
            textured,
            &[TEXTURE, "cannot read the image"],
            false,
        ),
        // A PNG whose header declares 100000×100000 pixels.
        (
            "png-past-the-budget",
            "wood.png",
            png_with_header(100_000, 100_000, &[0; 16]),
            textured,
            &[TEXTURE, "cannot read the image"],
            true,
        ),
        // An EXR texture with an infinite texel.
        (
            "inf-exr-texture",
            "wood.exr",
            exr_with(4, 2, f32::INFINITY),
            textured,
            &[TEXTURE, "NaN, infinite or negative", "pixel (1, 0)"],
            false,
        ),
        // An EXR sky cut in half.
        (
            "truncated-exr-sky",
            "sky.exr",
            good_exr[..good_exr.len() / 2].to_vec(),
            skied,
            &[SKY, "cannot read the image"],
            false,
        ),
        // A zero-byte EXR sky.
        (
            "empty-exr-sky",
            "sky.exr",
            Vec::new(),
            skied,
            &[SKY, "cannot read the image"],
            false,
        ),
        // An EXR sky with a NaN texel.
        (
            "nan-exr-sky",
            "sky.exr",
            exr_with(4, 2, f32::NAN),
            skied,
            &[SKY, "NaN, infinite or negative", "pixel (1, 0)"],
            false,
        ),
        // An EXR sky with a negative texel.
        (
            "negative-exr-sky",
            "sky.exr",
            exr_with(4, 2, -1.0),
            skied,
            &[SKY, "NaN, infinite or negative"],
            false,
        ),
        // An EXR sky brighter than any radiance (refused at load, not as "frame input: … is inf").
        (
            "blinding-exr-sky",
            "sky.exr",
            exr_with(4, 2, 3e38),
            skied,
            &[SKY, "1e30"],
            false,
        ),
        // A PNG header declaring 100000×100000 as the sky.
        (
            "png-sky-past-the-budget",
            "sky.png",
            png_with_header(100_000, 100_000, &[0; 16]),
            skied,
            &[SKY, "cannot read the image"],
            true,
        ),
    ];
    for (case, name, bytes, scene, names, over_budget) in cases {
        let asset = scratch.write(&format!("{case}/{name}"), &bytes);
        let scene = scratch.write(&format!("{case}/scene.toml"), scene(name));
        let mut all = vec![text(&asset)];
        all.extend_from_slice(names);
        earlier.refused_intact(case, &strs(&render_scene(&scene, &out)), &all, over_budget);
    }

    // A good sky scaled past the radiance limit names the scale.
    let scene = scratch.write("scaled.toml", with_sky("good.exr", "1e38"));
    earlier.refused_intact(
        "sky-scaled-past-the-limit",
        &strs(&render_scene(&scene, &out)),
        &["environment.latlong.scale", "1e30"],
        false,
    );
    // A sky that does not exist.
    let scene = scratch.write("missing.toml", with_sky("nowhere/sky.exr", "1"));
    earlier.refused_intact(
        "missing-sky",
        &strs(&render_scene(&scene, &out)),
        &[SKY, "nowhere/sky.exr", "No such file"],
        false,
    );
}

/// Copies every file of `from` into a fresh `to`.
fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
    }
}

/// The cube-map file of the bake `render --write-bake` writes for glass-sphere.
const MAP: &str = "lens0-sphere.v000.layer0.exr";

/// Rewrites the bake's manifest with `edit` applied to its text.
fn edit_manifest(dir: &Path, edit: impl FnOnce(String) -> String) {
    let path = dir.join("manifest.json");
    let text = String::from_utf8(read(&path)).unwrap();
    std::fs::write(&path, edit(text)).unwrap();
}

/// Reads the bake's cube map (8²), applies `edit`, writes it back.
fn edit_map(dir: &Path, edit: impl FnOnce(&mut CubeMap)) {
    let path = dir.join(MAP);
    let mut cube = read_cube_map_exr(&path, 8).unwrap();
    edit(&mut cube);
    write_cube_map_exr(&cube, &path).unwrap();
}

/// Bake directories given to `render --bake`: no manifest, a manifest that is not JSON or of
/// another version or size, missing, truncated, empty, wrongly sized or foreign EXRs, NaN and
/// out-of-range texels, escaping paths, a lens of another name, and a file for the folder.
#[test]
fn damaged_bakes_are_refused_naming_the_file_and_field() {
    let scratch = Scratch::new("bake");
    let good = scratch.path("good-bake");
    let out = scratch.path("frames/frame.png");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    args.extend(["--write-bake", text(&good), "--out", text(&out)]);
    succeeds("writing the bake", &args);
    let render_bake = |bake: &Path| render_bake(bake, &out);
    // The bake as written renders, finite.
    succeeds("the good bake", &strs(&render_bake(&good)));
    assert_finite_exr("the good bake", &out.with_extension("exr"));
    let earlier = Earlier::of(&out);

    type Damage = fn(&Path);
    let cases: Vec<(&str, Damage, &str, &[&str], bool)> = vec![
        // No manifest.json.
        (
            "no-manifest",
            |d| std::fs::remove_file(d.join("manifest.json")).unwrap(),
            "manifest.json",
            &["not a bake directory"],
            false,
        ),
        // A manifest that is not JSON.
        (
            "manifest-not-json",
            |d| std::fs::write(d.join("manifest.json"), "format_version = 1\n").unwrap(),
            "manifest.json:1:",
            &["fix the manifest"],
            false,
        ),
        // An empty manifest.
        (
            "empty-manifest",
            |d| std::fs::write(d.join("manifest.json"), "").unwrap(),
            "manifest.json:1:",
            &["EOF"],
            false,
        ),
        // A manifest of format version 99.
        (
            "manifest-version-99",
            |d| {
                edit_manifest(d, |t| {
                    t.replace("\"format_version\": 1", "\"format_version\": 99")
                })
            },
            "manifest.json",
            &["format_version is 99"],
            false,
        ),
        // A version that is a string.
        (
            "manifest-version-string",
            |d| {
                edit_manifest(d, |t| {
                    t.replace("\"format_version\": 1", "\"format_version\": \"1\"")
                })
            },
            "manifest.json",
            &["format_version is \"1\""],
            false,
        ),
        // A viewpoint of 1e999 (infinite).
        (
            "manifest-infinite-viewpoint",
            |d| edit_manifest(d, |t| t.replacen("2.5,", "1e999,", 1)),
            "manifest.json:",
            &["number out of range"],
            false,
        ),
        // A map path that climbs out of the bake.
        (
            "manifest-escaping-path",
            |d| {
                edit_manifest(d, |t| {
                    t.replace(&format!("\"{MAP}\""), &format!("\"../{MAP}\""))
                })
            },
            "manifest.json",
            &["lenses[0].layers[0].maps[0]", "not a plain relative path"],
            false,
        ),
        // A lens object the scene does not have.
        (
            "manifest-other-lens",
            |d| {
                edit_manifest(d, |t| {
                    t.replace("\"name\": \"sphere\"", "\"name\": \"ball\"")
                })
            },
            "manifest.json",
            &["lenses", "\"sphere\""],
            false,
        ),
        // cube_map_size 2³¹ with an 8² map.
        (
            "cube-map-size-2^31",
            |d| {
                edit_manifest(d, |t| {
                    t.replace("\"cube_map_size\": 8", "\"cube_map_size\": 2147483648")
                })
            },
            MAP,
            &["level0/+X", "expected 2147483648×2147483648"],
            true,
        ),
        // cube_map_size 2³², past a u32.
        (
            "cube-map-size-2^32",
            |d| {
                edit_manifest(d, |t| {
                    t.replace("\"cube_map_size\": 8", "\"cube_map_size\": 4294967296")
                })
            },
            "manifest.json:",
            &["4294967296"],
            true,
        ),
        // The map file removed.
        (
            "missing-map",
            |d| std::fs::remove_file(d.join(MAP)).unwrap(),
            MAP,
            &["lenses[0].layers[0].maps[0]", "not found"],
            false,
        ),
        // A folder where the map file should be.
        (
            "map-is-a-folder",
            |d| {
                std::fs::remove_file(d.join(MAP)).unwrap();
                std::fs::create_dir(d.join(MAP)).unwrap();
            },
            MAP,
            &["lenses[0].layers[0].maps[0]"],
            false,
        ),
        // The map cut in half.
        (
            "truncated-map",
            |d| {
                let bytes = read(&d.join(MAP));
                std::fs::write(d.join(MAP), &bytes[..bytes.len() / 2]).unwrap();
            },
            MAP,
            &["not a readable OpenEXR file"],
            false,
        ),
        // A zero-byte map.
        (
            "empty-map",
            |d| std::fs::write(d.join(MAP), b"").unwrap(),
            MAP,
            &["not a readable OpenEXR file"],
            false,
        ),
        // A map of 4² where the manifest says 8².
        (
            "map-of-the-wrong-size",
            |d| {
                write_cube_map_exr(&CubeMap::uniform(4, [0.1, 0.1, 0.1, 1.0]), &d.join(MAP))
                    .unwrap()
            },
            MAP,
            &["level0/+X", "4×4", "expected 8×8"],
            false,
        ),
        // An ordinary RGB EXR, not a cube map.
        (
            "map-is-a-plain-exr",
            |d| std::fs::write(d.join(MAP), exr_with(8, 8, 0.5)).unwrap(),
            MAP,
            &["part", "is not one of level0/+X"],
            false,
        ),
        // A NaN texel.
        (
            "nan-texel",
            |d| edit_map(d, |cube| cube.levels[0][2][5][1] = f32::NAN),
            MAP,
            &["level0/+Y", "texel (5, 0) channel G is NaN"],
            false,
        ),
        // An infinite texel in a mip level.
        (
            "inf-texel",
            |d| edit_map(d, |cube| cube.levels[1][5][3][0] = f32::INFINITY),
            MAP,
            &["level1/-Z", "channel R is inf"],
            false,
        ),
        // An α of 7.
        (
            "alpha-7",
            |d| edit_map(d, |cube| cube.levels[0][0][0][3] = 7.0),
            MAP,
            &["level0/+X", "alpha 7"],
            false,
        ),
    ];
    for (case, damage, file, names, over_budget) in cases {
        let bake = scratch.path(case);
        copy_dir(&good, &bake);
        damage(&bake);
        let named = bake.join(file);
        let mut all = vec![text(&named)];
        all.extend_from_slice(names);
        earlier.refused_intact(case, &strs(&render_bake(&bake)), &all, over_budget);
    }
    // A regular file given as the bake.
    let file = scratch.write("not-a-bake.json", "{}");
    earlier.refused_intact(
        "bake-is-a-file",
        &strs(&render_bake(&file)),
        &[text(&file), "bake"],
        false,
    );
}

/// The compressed map of the bake `render --write-bake` writes for glass-sphere, once
/// `bake --compress` has run.
const COMPRESSED_MAP: &str = "lens0-sphere.v000.layer0.lmz";

/// Compressed bakes given to `render --bake`: a map truncated, cut to its header, emptied, with
/// a bit flipped or bytes appended, replaced by another scene's compressed map, or by the EXR it
/// came from; and a manifest whose checksum or chain was edited. Each refused in one line
/// naming the file, the earlier frame intact; and `bake --compress` over a damaged bake leaves
/// it as it was.
#[test]
fn damaged_compressed_bakes_are_refused_naming_the_file() {
    let scratch = Scratch::new("compressed");
    let (plain, good, other) = (
        scratch.path("plain-bake"),
        scratch.path("good-bake"),
        scratch.path("other-bake"),
    );
    let out = scratch.path("frames/frame.png");
    let patch = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/glass-sphere-patch.toml"
    );
    for (scene, dir) in [("glass-sphere", &plain), (patch, &other)] {
        let mut args = vec!["render", "--scene", scene];
        args.extend(TINY_RENDER);
        args.extend(["--write-bake", text(dir), "--out", text(&out)]);
        succeeds("writing the bake", &args);
    }
    succeeds(
        "compressing",
        &["bake", "--compress", text(&plain), "--out", text(&good)],
    );
    succeeds(
        "compressing the other",
        &["bake", "--compress", text(&other)],
    );
    let render_bake = |bake: &Path| render_bake(bake, &out);
    succeeds("the compressed bake", &strs(&render_bake(&good)));
    assert_finite_exr("the compressed bake", &out.with_extension("exr"));
    let earlier = Earlier::of(&out);
    let original = read(&good.join(COMPRESSED_MAP));
    let exr = read(&plain.join(MAP));
    let foreign = read(&other.join(COMPRESSED_MAP));
    let flipped = {
        let mut bytes = original.clone();
        let at = bytes.len() - 10;
        bytes[at] ^= 0x10;
        bytes
    };
    let cases: Vec<(&str, Vec<u8>, &[&str])> = vec![
        (
            "truncated",
            original[..original.len() - 7].to_vec(),
            &["is truncated"],
        ),
        ("header-only", original[..50].to_vec(), &["88-byte header"]),
        ("empty", Vec::new(), &["is truncated: 0 bytes"]),
        ("bit-flipped", flipped, &["SHA-256", "changed or damaged"]),
        (
            "bytes-appended",
            [original.as_slice(), b"extra"].concat(),
            &["changed or damaged"],
        ),
        ("other-scene", foreign, &["another scene"]),
        ("an-exr", exr, &["no LMZC header"]),
    ];
    for (case, bytes, names) in cases {
        let bake = scratch.path(case);
        copy_dir(&good, &bake);
        std::fs::write(bake.join(COMPRESSED_MAP), bytes).unwrap();
        let named = bake.join(COMPRESSED_MAP);
        let mut all = vec![text(&named)];
        all.extend_from_slice(names);
        earlier.refused_intact(case, &strs(&render_bake(&bake)), &all, false);
    }
    // The manifest's record of the file changed.
    let bake = scratch.path("manifest-checksum");
    copy_dir(&good, &bake);
    edit_manifest(&bake, |t| {
        t.replacen("\"sha256\": \"", "\"sha256\": \"0", 1)
    });
    earlier.refused_intact(
        "manifest-checksum",
        &strs(&render_bake(&bake)),
        &["manifest.json", "compression.files", "sha256"],
        false,
    );
    // Compressing a damaged bake in place refuses and leaves it as it was.
    let damaged = scratch.path("damaged-plain");
    copy_dir(&plain, &damaged);
    let half = read(&plain.join(MAP));
    std::fs::write(damaged.join(MAP), &half[..half.len() / 2]).unwrap();
    let output = lensmap(&["bake", "--compress", text(&damaged)]);
    assert_refused(
        "compress-damaged",
        &output,
        Duration::ZERO,
        2,
        &[text(&damaged.join(MAP)), "not a readable OpenEXR file"],
    );
    assert_eq!(read(&damaged.join(MAP)), half[..half.len() / 2]);
    assert!(damaged.join("manifest.json").is_file());
}

/// Command-line options: bad enums, numbers out of range or of the wrong type, NaN and
/// infinity, conflicting options, and the paths `--write-bake` cannot use.
#[test]
fn hostile_options_are_refused_naming_the_option() {
    let scratch = Scratch::new("options");
    let out = scratch.path("frames/frame.png");
    let base: Vec<&str> = ["render", "--scene", "glass-sphere"]
        .into_iter()
        .chain(TINY_RENDER)
        .chain(["--out", text(&out)])
        .collect();
    succeeds("the base render", &base);
    assert_finite_exr("the base render", &out.with_extension("exr"));
    let earlier = Earlier::of(&out);

    // `render --scene glass-sphere --projected` at a size of the case's choosing.
    let sized: Vec<&str> = ["render", "--scene", "glass-sphere", "--projected"]
        .into_iter()
        .chain(["--out", text(&out)])
        .collect();
    let cases: Vec<(&str, &[&str], &[&str], bool)> = vec![
        // A variant that does not exist.
        (
            "bad-variant",
            &["--variant", "fast"],
            &["--variant", "fast", "multipass"],
            false,
        ),
        // A format that does not exist.
        (
            "bad-format",
            &["--format", "rgb9"],
            &["--format", "rgb9", "rgba16f"],
            false,
        ),
        // A view the view space does not have.
        (
            "view-past-the-end",
            &["--view", "99999"],
            &["--view", "99999", "between 0 and 44"],
            false,
        ),
        // A view index past a u64.
        (
            "view-beyond-u64",
            &["--view", "18446744073709551616"],
            &["--view", "too large"],
            false,
        ),
        // --view and --camera-position together.
        (
            "view-with-position",
            &["--view", "1", "--camera-position", "0,1,5"],
            &["--view", "--camera-position", "cannot be used with"],
            false,
        ),
        // --projected and --bake together.
        (
            "projected-with-bake",
            &["--bake", "/nonexistent"],
            &["--projected", "--bake", "cannot be used with"],
            false,
        ),
        // A NaN camera coordinate.
        (
            "nan-camera-position",
            &["--camera-position", "0,nan,1"],
            &["--camera-position", "not a finite number"],
            false,
        ),
        // Two coordinates for three.
        (
            "short-camera-position",
            &["--camera-position", "0,1"],
            &["--camera-position", "three comma-separated numbers"],
            false,
        ),
        // A look-at point on the camera.
        (
            "look-at-the-eye",
            &["--look-at", "0,2.5,5"],
            &["--look-at", "look-at point equals the camera position"],
            false,
        ),
        // A NaN angle.
        (
            "nan-angle",
            &["--angle-degrees", "nan"],
            &["--angle-degrees nan", "outside its range (0, 180)"],
            false,
        ),
        // An infinite t.
        ("inf-t", &["--t", "inf"], &["--t inf"], false),
        // A footprint that is a word, not a number.
        (
            "word-footprint",
            &["--footprint", "wide"],
            &["--footprint", "wide"],
            false,
        ),
        // A NaN light-map density.
        (
            "nan-light-map-density",
            &["--light-map-density", "nan"],
            &["--light-map-density nan", "outside its range [1, 4096]"],
            false,
        ),
        // Zero pixels per texel.
        (
            "zero-pixels-per-texel",
            &["--light-map-pixels-per-texel", "0"],
            &["--light-map-pixels-per-texel 0"],
            false,
        ),
        // A maximum density below the minimum.
        (
            "max-density-below-min",
            &[
                "--light-map-density",
                "100",
                "--light-map-max-density",
                "10",
            ],
            &["--light-map-max-density 10"],
            false,
        ),
        // A light-map budget of 2⁶⁴ − 1 texels.
        (
            "light-map-texels-past-the-budget",
            &["--light-map-max-texels", "18446744073709551615"],
            &["--light-map-max-texels 18446744073709551615"],
            true,
        ),
        // An EM size of 2³² (past a u32).
        (
            "em-size-beyond-u32",
            &["--em-size", "4294967296"],
            &["--em-size", "4294967296"],
            true,
        ),
        // An EM size of 65536 (a power of two past the budget).
        (
            "em-size-past-the-budget",
            &["--em-size", "65536"],
            &["--em-size 65536"],
            true,
        ),
        // A height of 2³² (past a u32).
        (
            "height-beyond-u32",
            &["--width", "16", "--height", "4294967296"],
            &["--height", "4294967296"],
            true,
        ),
        // A width that is negative.
        (
            "negative-width",
            &["--width=-5", "--height", "12"],
            &["--width", "-5"],
            false,
        ),
        // A zero width.
        (
            "zero-width",
            &["--width", "0", "--height", "12"],
            &["--width 0", "outside its range [1, 16384]"],
            false,
        ),
        // 10000×10000 pixels: each side within its range, the two past 2²⁶ subpixels.
        (
            "pixels-past-the-budget",
            &[
                "--width",
                "10000",
                "--height",
                "10000",
                "--supersampling",
                "1",
            ],
            &["camera", "10000×10000 subpixels", "67108864 in all"],
            true,
        ),
    ];
    for (case, extra, names, over_budget) in cases {
        let args: Vec<&str> = sized.iter().copied().chain(extra.iter().copied()).collect();
        earlier.refused_intact(case, &args, names, over_budget);
    }

    // --write-bake at a regular file, and at a folder that holds something else.
    let file = scratch.write("notes.txt", "not a bake");
    let folder = scratch.write("photos/holiday.jpg", "jpeg");
    let folder = folder.parent().unwrap();
    for (case, target) in [
        ("write-bake-over-a-file", file.as_path()),
        ("write-bake-over-a-folder", folder),
    ] {
        let mut args = base.clone();
        args.extend(["--write-bake", text(target)]);
        earlier.refused_intact(case, &args, &[text(target), "is not a bake"], false);
    }
    assert_eq!(read(&file), b"not a bake", "the file survives");
    assert_eq!(
        read(&folder.join("holiday.jpg")),
        b"jpeg",
        "the folder survives"
    );
}

/// Options that do not apply are refused, not ignored: `--accept-any-bake` without `--bake`.
#[test]
fn accept_any_bake_without_a_bake_is_refused() {
    let scratch = Scratch::new("accept");
    let out = scratch.path("frame.png");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    args.extend(["--accept-any-bake", "--out", text(&out)]);
    refused(
        "accept-any-bake-alone",
        &args,
        2,
        &["--accept-any-bake", "--bake"],
        false,
    );
    assert!(!out.exists(), "nothing written");
}

/// `--out` under a regular file cannot be honoured: usage (exit 2), said before any work.
#[test]
fn out_under_a_regular_file_is_refused_before_work() {
    let scratch = Scratch::new("out-file");
    let file = scratch.write("notes.txt", "keep me");
    let out = file.join("frame.png");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    args.extend(["--out", text(&out)]);
    let start = Instant::now();
    let output = lensmap(&args);
    let elapsed = start.elapsed();
    assert_refused(
        "out-under-a-file",
        &output,
        elapsed,
        2,
        &["--out", text(&out)],
    );
    assert!(
        elapsed < Duration::from_secs(1),
        "out-under-a-file: refused only after {elapsed:?} of work"
    );
    assert_eq!(read(&file), b"keep me");
}

/// Other commands read scenes too: `reference` and `bake` refuse a hostile scene alike.
#[test]
fn reference_and_bake_refuse_hostile_scenes() {
    let scratch = Scratch::new("commands");
    scratch.write(
        "nan.obj",
        "v 0 0 0\nv 1 0 0\nv 0 0 1\nvn nan 1 0\nf 1//1 2//1 3//1\n",
    );
    let far = scratch.write(
        "far.toml",
        edit(
            "sphere = { radius = 1, segments = 16, rings = 8 }",
            "sphere = { radius = 1, segments = 16, rings = 8 }\ntransform = { translate = [1e25, 0, 0] }",
        ),
    );
    let nan = scratch.write("nan.toml", with_obj("nan.obj"));
    let reference_out = scratch.path("reference");
    let bake_out = scratch.path("bake");
    for (case, args, names) in [
        // `reference` on an object 1e25 m away (refused before the BVH is built, which would panic).
        (
            "reference-far-object",
            vec![
                "reference",
                "--scene",
                text(&far),
                "--out",
                text(&reference_out),
            ],
            vec!["far.toml", "objects[0].transform", "1e6 m"],
        ),
        // `bake` on an OBJ with a NaN normal.
        (
            "bake-nan-normal",
            vec![
                "bake",
                "--scene",
                text(&nan),
                "--samples",
                "0",
                "--out",
                text(&bake_out),
            ],
            vec!["nan.toml", "objects[1].obj.path", "nan.obj"],
        ),
    ] {
        refused(case, &args, 2, &names, false);
    }
    assert!(
        !reference_out.exists() && !bake_out.exists(),
        "nothing written"
    );
}

/// A scene that is hostile but valid renders, finite: a light of 1e8 W/sr, whose light maps
/// overflow RGBA16F (clamped, not refused as "light map has NaN or infinite texels"); one at the
/// radiance limit; a sky of 1e5 (past RGBA16F's 65504).
#[test]
fn bright_but_valid_scenes_render_finite() {
    let scratch = Scratch::new("bright");
    for (case, scene) in [
        (
            "light-1e8",
            edit("intensity = [10, 10, 10]", "intensity = [1e8, 1e8, 1e8]"),
        ),
        (
            "light-1e30",
            edit("intensity = [10, 10, 10]", "intensity = [1e30, 1e30, 1e30]"),
        ),
        (
            "sky-1e5",
            edit("constant = [0.1, 0.1, 0.1]", "constant = [1e5, 1e5, 1e5]"),
        ),
        (
            "object-at-the-limit",
            edit(
                "sphere = { radius = 1, segments = 16, rings = 8 }",
                "sphere = { radius = 1, segments = 16, rings = 8 }\ntransform = { translate = [999000, 0, 0] }",
            ),
        ),
    ] {
        let scene = scratch.write(&format!("{case}.toml"), scene);
        let out = scratch.path(&format!("{case}.png"));
        succeeds(case, &strs(&render_scene(&scene, &out)));
        assert_finite_exr(case, &out.with_extension("exr"));
    }
}

/// A full disk mid-write: a failure of the work (exit 1), one line naming the file, and the
/// earlier PNG and EXR both as they were — not a new PNG beside an old EXR.
#[test]
fn a_full_disk_keeps_the_earlier_pair_and_bake() {
    let scratch = Scratch::new("full");
    let out = scratch.path("frame.png");
    // The earlier frame: 32×24. The new one, 64×48, has a PNG under the limit and an EXR over it.
    let frame = |width: &'static str, height: &'static str| -> Vec<&str> {
        vec![
            "render",
            "--scene",
            "glass-sphere",
            "--projected",
            "--width",
            width,
            "--height",
            height,
            "--supersampling",
            "1",
            "--em-size",
            "8",
            "--out",
            text(&out),
        ]
    };
    succeeds("the earlier frame", &frame("32", "24"));
    let earlier = Earlier::of(&out);
    // 16 KiB free: the new PNG (4 KB) fits, its EXR (37 KB) does not.
    let (output, elapsed) = on_full_disk(&scratch.0, 16, &frame("64", "48"));
    let exr = out.with_extension("exr");
    assert_refused(
        "full-disk-frame",
        &output,
        elapsed,
        1,
        &[text(&exr), "No space left on device"],
    );
    earlier.assert_intact("full-disk-frame");

    // `bake` on a full disk: exit 1, and the earlier bake at that path intact.
    let bake = scratch.path("bake");
    let bake_args: Vec<&str> = ["bake", "--scene", "glass-sphere", "--samples", "0"]
        .into_iter()
        .chain(TINY_FRAME)
        .chain(["--em-size", "8", "--layers", "1", "--multi-view", "1"])
        .chain(["--no-judge", "--out", text(&bake)])
        .collect();
    succeeds("the earlier bake", &bake_args);
    let before: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(&bake)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            let bytes = read(&path);
            (path, bytes)
        })
        .collect();
    let (output, elapsed) = on_full_disk(&scratch.0, 0, &bake_args);
    assert_refused(
        "full-disk-bake",
        &output,
        elapsed,
        1,
        &[text(&bake), "No space left on device"],
    );
    for (path, bytes) in &before {
        assert!(
            read(path) == *bytes,
            "full-disk-bake: {} changed",
            path.display()
        );
    }
}

/// `render --write-bake` on a full disk is a failure of the work (exit 1), as for `bake`: an
/// error writing a bake is not bad input.
#[test]
fn a_full_disk_under_write_bake_exits_1() {
    let scratch = Scratch::new("full-write-bake");
    let bake = scratch.path("bake");
    let out = scratch.path("frame.png");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    args.extend(["--write-bake", text(&bake), "--out", text(&out)]);
    // 4 KiB free: the 16×12 frame would fit, the bake does not.
    let (output, elapsed) = on_full_disk(&scratch.0, 4, &args);
    assert_refused(
        "full-disk-write-bake",
        &output,
        elapsed,
        1,
        &[text(&bake), "No space left on device"],
    );
    assert!(!bake.exists(), "no bake half written");
}

/// `lensmap render … | head -0`: stdout closed before the report is printed; the frame is still
/// written (finite), nothing is said on stderr, and the exit code is 141.
#[test]
fn a_closed_stdout_still_writes_the_frame() {
    let scratch = Scratch::new("closed-stdout");
    let out = scratch.path("frame.png");
    let mut args = vec!["render", "--scene", "glass-sphere"];
    args.extend(TINY_RENDER);
    args.extend(["--out", text(&out)]);
    let mut child = lensmap_command(&args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes at once; the report comes only after the frame, a second later.
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(141), "closed-stdout: {stderr}");
    assert!(stderr.is_empty(), "closed-stdout: {stderr}");
    assert!(out.is_file(), "closed-stdout: the PNG is written");
    assert_finite_exr("closed-stdout", &out.with_extension("exr"));
}

/// An error said to a closed stderr (`lensmap … 2>&1 | head -0`) ends with its exit code, not a
/// panic about failing to print it.
#[test]
fn a_closed_stderr_keeps_the_exit_code() {
    let mut child = lensmap_command(&["render", "--scene", "no-such-scene", "--projected"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take()); // the reader goes before the error is said
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(2), "closed-stderr");
}

/// Under a file-size limit (`ulimit -f`) every run says so in one warning before any work: past
/// it, a driver that backs GPU memory with files dies by SIGBUS, which lensmap cannot catch. A
/// run without a limit says nothing.
#[test]
fn a_file_size_limit_is_named_in_one_warning() {
    let run = |limit: &str| {
        let script = format!(
            "{limit} exec '{}' passes --layers 1",
            env!("CARGO_BIN_EXE_lensmap")
        );
        std::process::Command::new("sh")
            .args(["-c", &script])
            .output()
            .unwrap()
    };
    let limited = run("ulimit -f 2097152;");
    assert_success("under a limit", &limited);
    let stderr = String::from_utf8_lossy(&limited.stderr);
    assert!(
        stderr.lines().count() == 1
            && stderr.starts_with("warning: a file-size limit of ")
            && stderr.contains("SIGBUS"),
        "{stderr}"
    );
    let unlimited = run("ulimit -f unlimited;");
    assert_success("without a limit", &unlimited);
    assert!(
        unlimited.stderr.is_empty(),
        "{:?}",
        String::from_utf8_lossy(&unlimited.stderr)
    );
}
