//! Shared helpers for the end-to-end tests: a GPU with the Khronos validation layer on, and the
//! check that it reported nothing.

use lensmap::gpu::{Gpu, GpuOptions};

/// A GPU for tests, with validation on. The validation layer is required (CI installs
/// `vulkan-validationlayers`); set `LENSMAP_TEST_NO_VALIDATION=1` to run without it locally.
pub fn gpu() -> Gpu {
    let mut options = GpuOptions::from_env();
    options.validation = std::env::var("LENSMAP_TEST_NO_VALIDATION").map_or(true, |v| v != "1");
    match Gpu::new(&options) {
        Ok(gpu) => gpu,
        Err(e) => panic!("no GPU for tests: {e}"),
    }
}

/// Fails the test if the validation layer reported anything.
pub fn assert_clean(gpu: &Gpu) {
    let report = gpu.validation_report();
    let asked = std::env::var("LENSMAP_TEST_NO_VALIDATION").map_or(true, |v| v != "1");
    assert!(!asked || report.enabled, "the validation layer is not on");
    assert!(
        report.messages.is_empty(),
        "{} validation message(s):\n{}",
        report.messages.len(),
        report.messages.join("\n")
    );
}

/// teapot-room (two lens objects, one open) at `width × height`, 1×1, with 16² projected EMs:
/// small enough for a test, with every kind of lens object.
pub fn small_teapot_room(width: u32, height: u32) -> lensmap::hybrid::HybridScene {
    use lensmap::layers::projected::ProjectedOptions;
    use lensmap::runner::{EmSource, load_hybrid_scene};
    let mut scene = lensmap::scene::Scene::load_named("teapot-room").expect("built in");
    scene.camera.width = width;
    scene.camera.height = height;
    scene.camera.supersampling = 1;
    let options = ProjectedOptions {
        size: 16,
        supersampling: 1,
    };
    load_hybrid_scene(scene, &EmSource::Projected(options))
        .expect("teapot-room loads")
        .0
}

/// A square sheet 1.6 units a side centred on the origin, as a `grid × grid` mesh of quads split
/// into two triangles each, its vertices lifted by `z(u, v)` (u, v in [−½, ½]): the lens of the
/// compositor's tests.
pub fn grid_sheet(grid: u32, z: impl Fn(f32, f32) -> f32) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    for j in 0..=grid {
        for i in 0..=grid {
            let u = i as f32 / grid as f32 - 0.5;
            let v = j as f32 / grid as f32 - 0.5;
            positions.push(glam::Vec3::new(1.6 * u, 1.6 * v, z(u, v)));
        }
    }
    let row = grid + 1;
    let mut triangles = Vec::new();
    for j in 0..grid {
        for i in 0..grid {
            let (a, b, c, d) = (
                j * row + i,
                j * row + i + 1,
                (j + 1) * row + i + 1,
                (j + 1) * row + i,
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    (positions, triangles)
}
