//! The OBJ reader on every OBJ file of Debian's `assimp-testmodels` (installed by `.ci/run`):
//! each file loads as a scene's object, or is refused in one line naming its line and record, as
//! the table below pins; and a concave polygon keeps its shape: its triangles' area equals its
//! shoelace area, and its lens pixels seen face-on its projected area.

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use lensmap::metrics::Mask;
use lensmap::scene::Scene;
use lensmap::trace::{LensPixels, LensSelection, TraceScene};

/// Where Debian's `assimp-testmodels` puts its OBJ files.
const ASSIMP_OBJ: &str = "/usr/share/assimp/models/OBJ";

/// What lensmap does with each file: `Ok(triangles)` or `Err(words of the refusal)`.
const EXPECTED: &[(&str, Result<usize, &str>)] = &[
    ("WusonOBJ.obj", Ok(3_732)),
    ("box.obj", Ok(12)),
    ("box_UTF16BE.obj", Ok(12)),
    // One face of 480 corners walks a quad 120 times.
    ("box_longline.obj", Err("line 24 (`f 1 2 3 4 1 2 3 4")),
    ("box_mat_with_spaces.obj", Ok(12)),
    ("box_without_lineending.obj", Ok(12)),
    // A 66-gon with a hole, bridged: 64 triangles.
    ("concave_polygon.obj", Ok(64)),
    ("cube_mtllib_after_g.obj", Ok(12)),
    ("cube_usemtl.obj", Ok(12)),
    ("cube_with_vertexcolors.obj", Ok(12)),
    ("cube_with_vertexcolors_uni.obj", Ok(12)),
    // An empty `usemtl` on line 233: one warning.
    ("empty_mat.obj", Ok(256)),
    ("multiple_spaces.obj", Ok(1)),
    (
        "number_formats.obj",
        Err("line 11 (`v 1e+2 2.e+1 3.1+e2`): `3.1+e2` is not a number"),
    ),
    // Vertices alone.
    ("point_cloud.obj", Err("the mesh has no triangles")),
    (
        "regr01.obj",
        Err(
            "8 degenerate (zero-area) triangle(s), the first is triangle 1287 (0-based) (a face on line 2356)",
        ),
    ),
    ("regr_3429812.obj", Ok(4)),
    ("space_in_material_name.obj", Ok(64)),
    (
        "spider.obj",
        Err(
            "56 degenerate (zero-area) triangle(s), the first is triangle 924 (0-based) (a face on line 2902)",
        ),
    ),
    (
        "testline.obj",
        Err("line 15 (`l 4 3 2 1`): `l` (a polyline) is not a surface"),
    ),
    (
        "testmixed.obj",
        Err("line 15 (`l 4 3 2 1`): `l` (a polyline) is not a surface"),
    ),
    (
        "testpoints.obj",
        Err("line 15 (`p 4 3 2 1`): `p` (points) is not a surface"),
    ),
];

/// A scene in `dir` whose one object is the OBJ at `obj`, of material `material`, seen by
/// `camera` (TOML).
fn scene_text(obj: &Path, material: &str, camera: &str) -> String {
    format!(
        r#"name = "obj-file"
{camera}
[[materials]]
name = "m"
{material}

[[objects]]
name = "mesh"
material = "m"
obj = {{ path = "{}" }}
"#,
        obj.display()
    )
}

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensmap-obj-files-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn load(dir: &Path, text: &str) -> Result<Scene, String> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path).map_err(|e| e.to_string())
}

const CAMERA: &str = "[camera]\nposition = [0, 0, 50]\nlook_at = [0, 0, 0]\nvfov_degrees = 45\nwidth = 8\nheight = 8\n";

#[test]
fn every_assimp_obj_file_loads_or_is_refused_naming_its_line() {
    let folder = Path::new(ASSIMP_OBJ);
    assert!(
        folder.is_dir(),
        "{ASSIMP_OBJ} is missing: install Debian's assimp-testmodels (.ci/run does)"
    );
    let mut files: Vec<String> = std::fs::read_dir(folder)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".obj"))
        .collect();
    files.sort();
    let listed: Vec<&str> = EXPECTED.iter().map(|(name, _)| *name).collect();
    assert_eq!(files, listed, "the folder's OBJ files and the table differ");
    let dir = temp_dir("assimp");
    let diffuse = "diffuse = { colour = [0.5, 0.5, 0.5] }";
    let mut report = String::from("| file | lensmap |\n|---|---|\n");
    let mut wrong = Vec::new();
    for (name, expected) in EXPECTED {
        let loaded = load(&dir, &scene_text(&folder.join(name), diffuse, CAMERA));
        let said = match &loaded {
            Ok(scene) => {
                let triangles = scene.objects[0].mesh.triangles.len();
                let warnings = match scene.warnings.len() {
                    0 => String::new(),
                    n => format!(", {n} warning(s): {}", scene.warnings[0]),
                };
                format!("loads, {triangles} triangles{warnings}")
            }
            Err(e) => format!("refused: {e}"),
        };
        report.push_str(&format!("| {name} | {said} |\n"));
        let holds = match (expected, &loaded) {
            (Ok(triangles), Ok(scene)) => scene.objects[0].mesh.triangles.len() == *triangles,
            (Err(words), Err(e)) => e.contains(words) && e.lines().count() == 1,
            _ => false,
        };
        if !holds {
            wrong.push(format!("{name}: expected {expected:?}, got {said}"));
        }
    }
    println!("{report}");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// assimp's 66-gon, concave on both sides, in the plane x = −1.146: ear clipping covers its
/// area (a fan from its first corner covered about 7× as much), and seen face-on at 10,000
/// pixels or more its lens pixels are its projected area within 1 %.
#[test]
fn a_concave_polygon_keeps_its_area_triangulated_and_rendered() {
    let obj = Path::new(ASSIMP_OBJ).join("concave_polygon.obj");
    let text = std::fs::read_to_string(&obj).expect("assimp-testmodels is installed");
    // The polygon as the file gives it, in f64: its shoelace area in its plane (y, z).
    let corners: Vec<DVec3> = text
        .lines()
        .filter_map(|line| line.strip_prefix("v "))
        .map(|v| {
            let p: Vec<f64> = v.split_whitespace().map(|x| x.parse().unwrap()).collect();
            DVec3::new(p[0], p[1], p[2])
        })
        .collect();
    let face: Vec<usize> = text
        .lines()
        .find_map(|line| line.strip_prefix("f "))
        .unwrap()
        .split_whitespace()
        .map(|c| c.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
        .collect();
    assert_eq!(face.len(), 66);
    assert!(corners.iter().all(|c| c.x == -1.146));
    let shoelace = 0.5
        * (0..face.len())
            .map(|i| {
                let (a, b) = (corners[face[i]], corners[face[(i + 1) % face.len()]]);
                a.y * b.z - b.y * a.z
            })
            .sum::<f64>()
            .abs();
    let (low, high) = face.iter().fold((DVec3::MAX, DVec3::MIN), |(lo, hi), &i| {
        (lo.min(corners[i]), hi.max(corners[i]))
    });
    let centre = (low + high) / 2.0;
    let extent = (high - low).max_element();

    // Seen face-on along −x from where the polygon spans most of the frame.
    let (size, vfov) = (512u32, 40.0f64);
    let distance = 0.75 * extent / (vfov.to_radians() / 2.0).tan();
    let camera = format!(
        "[camera]\nposition = [{}, {}, {}]\nlook_at = [{}, {}, {}]\nvfov_degrees = {vfov}\nwidth = {size}\nheight = {size}\n",
        centre.x + distance,
        centre.y,
        centre.z,
        centre.x,
        centre.y,
        centre.z
    );
    let dir = temp_dir("concave");
    let scene = load(
        &dir,
        &scene_text(&obj, "mirror = { reflectance = [0.9, 0.9, 0.9] }", &camera),
    )
    .unwrap();
    let mesh = &scene.objects[0].mesh;
    let triangulated: f64 = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
            // The file's corners, not their f32 copies: the area is the triangulation's alone.
            let nearest = |p: DVec3| {
                *face
                    .iter()
                    .map(|&i| &corners[i])
                    .min_by(|x, y| (**x - p).length().total_cmp(&(**y - p).length()))
                    .unwrap()
            };
            let [a, b, c] = [nearest(a), nearest(b), nearest(c)];
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    println!(
        "concave polygon: shoelace area {shoelace:.12} m², triangulated {triangulated:.12} m²"
    );
    assert!(
        (triangulated - shoelace).abs() <= 1e-9 * shoelace,
        "triangulated {triangulated} against shoelace {shoelace}"
    );
    // Every triangle faces +x, as the face is wound (toward the camera).
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        assert!(
            (b - a).cross(c - a).dot(Vec3::X) > 0.0,
            "triangle {t:?} faces away"
        );
    }

    let trace = TraceScene::new(&scene).unwrap();
    let pixels = LensPixels::trace(&trace, &scene.camera);
    let rendered = Mask::lens(&pixels, LensSelection::All).selected() as f64;
    // A plane facing the camera at `distance` is seen at one scale: a pixel covers this square.
    let pixel = 2.0 * distance * (vfov.to_radians() / 2.0).tan() / f64::from(size);
    let expected = shoelace / (pixel * pixel);
    println!("concave polygon: {rendered} lens pixels, {expected:.1} expected from its area");
    assert!(expected >= 10_000.0, "only {expected} pixels");
    assert!(
        (rendered - expected).abs() <= 0.01 * expected,
        "{rendered} lens pixels against {expected:.1}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
