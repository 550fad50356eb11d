//! Shared helpers for the end-to-end tests: a GPU with the Khronos validation layer on, and the
//! check that it reported nothing; the inputs several tests share ([`fixtures`]) and builds of C
//! and C++ hosts against the C ABI ([`c_abi`]).

pub mod c_abi;
pub mod fixtures;
pub mod mesh_checks;
pub mod source;

use std::sync::OnceLock;

use lensmap::gpu::{DeviceId, Gpu, GpuOptions};
use lensmap::render::{
    Compositing, RenderOptions, RenderedImage, Renderer, TargetFormat, UploadedFrame,
};

/// A GPU for tests, with validation on. The validation layer is required (CI installs
/// `vulkan-validationlayers`); set `LENSMAP_TEST_NO_VALIDATION=1` to run without it locally.
/// From then on every failure in this test process names the device and its driver
/// ([`name_the_driver_on_failure`]).
pub fn gpu() -> Gpu {
    gpu_with_heap_limit(None)
}

/// [`gpu`] whose largest device-local heap counts as at most `heap_limit_bytes`
/// ([`GpuOptions::heap_limit_bytes`]): the memory budgets refuse early without allocating.
pub fn gpu_with_heap_limit(heap_limit_bytes: Option<u64>) -> Gpu {
    let mut options = GpuOptions::from_env();
    options.validation = std::env::var("LENSMAP_TEST_NO_VALIDATION").map_or(true, |v| v != "1");
    options.heap_limit_bytes = heap_limit_bytes;
    if options.validation {
        one_validated_test_at_a_time();
    }
    match Gpu::new(&options) {
        Ok(gpu) => {
            name_the_driver_on_failure(gpu.device_id());
            gpu
        }
        Err(e) => panic!("no GPU for tests: {e}"),
    }
}

/// Held by the test thread whose validated devices are alive ([`one_validated_test_at_a_time`]).
static VALIDATED: std::sync::Mutex<()> = std::sync::Mutex::new(());

thread_local! {
    /// This thread's hold on [`VALIDATED`], released when the thread (a test) ends.
    static HOLDS: std::cell::RefCell<Option<std::sync::MutexGuard<'static, ()>>> =
        const { std::cell::RefCell::new(None) };
}

/// Waits until no other test thread of this process has a device with the validation layer,
/// and keeps other threads from making one until this thread (its test) ends; a thread already
/// holding it goes on (a test may make several devices). Debian 12's validation layer (1.3.239)
/// is not safe with validated devices used on several threads at once: four threads making,
/// using and dropping contexts crashed inside it (SIGSEGV in vkCreatePipelineLayout, in
/// vkCreateInstance against a vkDestroyDevice: 2 runs in 25 of 4 × 150 contexts), the same
/// without validation never (40 runs), and CI's blending tests once. Tests that make validated
/// devices call this first; [`gpu`] does.
pub fn one_validated_test_at_a_time() {
    HOLDS.with(|holds| {
        let mut holds = holds.borrow_mut();
        if holds.is_none() {
            // A test that failed holding it leaves nothing the lock guards half done.
            *holds = Some(
                VALIDATED
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner),
            );
        }
    });
}

/// The device a failure is reported against, once known.
static FAILING_ON: OnceLock<String> = OnceLock::new();

/// Makes every later panic of this test process (a failed assertion, in any test thread) end
/// with a line naming `device` and its driver with its version: two drivers can share a device
/// name (Mesa 22.3's and 25.0's lavapipe), and a failure on one says nothing of the other.
pub fn name_the_driver_on_failure(device: &DeviceId) {
    if FAILING_ON.set(device.to_string()).is_ok() {
        let report = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            report(info);
            if let Some(device) = FAILING_ON.get() {
                eprintln!("on device: {device}");
            }
        }));
    }
}

/// For tests that drive the `lensmap` binary: the device and driver the binary will pick (the
/// same `GpuOptions::from_env` choice, without validation), named on failure as
/// [`name_the_driver_on_failure`] does. Without a device it does nothing: the test's own run
/// then says what is missing.
pub fn name_the_binarys_driver_on_failure() {
    // Once per process, whatever the outcome: test threads calling at once wait for the one probe.
    static PROBED: OnceLock<()> = OnceLock::new();
    PROBED.get_or_init(|| {
        if FAILING_ON.get().is_none()
            && let Ok(gpu) = Gpu::new(&GpuOptions {
                validation: false,
                ..GpuOptions::from_env()
            })
        {
            name_the_driver_on_failure(gpu.device_id());
        }
    });
}

/// `frame` rendered by `renderer` composited as `compositing` says into RGBA32F, the format the
/// exact comparisons use (read back).
pub fn render_rgba32f(
    renderer: &mut Renderer,
    gpu: &Gpu,
    frame: &mut UploadedFrame,
    compositing: Compositing,
) -> RenderedImage {
    let options = RenderOptions {
        compositing,
        format: TargetFormat::Rgba32f,
        ..Default::default()
    };
    renderer
        .render(gpu, frame, &options)
        .expect("the frame renders")
        .0
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
    load_hybrid_scene(scene, &EmSource::Projected(options).into())
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

/// A cube map with independent random premultiplied texels in every level (α ∈ [0, 1],
/// rgb ∈ [0, α]), so a level mix-up or an upload bug shows.
pub fn random_cube(rng: &mut rand_pcg::Pcg64, size: u32) -> lensmap::cubemap::CubeMap {
    use rand::Rng;
    let levels = (0..lensmap::cubemap::CubeMap::full_chain_levels(size))
        .map(|l| {
            let n = ((size >> l).max(1) as usize).pow(2);
            std::array::from_fn(|_| {
                (0..n)
                    .map(|_| {
                        let a: f32 = rng.gen_range(0.0..=1.0);
                        [
                            rng.gen_range(0.0..=a),
                            rng.gen_range(0.0..=a),
                            rng.gen_range(0.0..=a),
                            a,
                        ]
                    })
                    .collect()
            })
        })
        .collect();
    lensmap::cubemap::CubeMap { size, levels }
}

/// A random compositor frame of `size × size` pixels: a grid lens (a tilted, slightly bent sheet
/// seen in perspective) whose vertices carry random F·G and smoothly varying random directions
/// for each (term, layer), over a background triangle; `viewpoints` (1 to 3) samples with random
/// weights summing to 1, each with `layers` random 16² cube maps.
pub fn random_compositor_frame(
    rng: &mut rand_pcg::Pcg64,
    size: u32,
    layers: usize,
    viewpoints: usize,
    terms: &[lensmap::trace::Term],
) -> lensmap::render::FrameInput {
    use glam::{Mat4, Vec3};
    use lensmap::render::{EnvironmentMesh, FrameInput, LensFaces, LensObject, TermVertices};
    use rand::Rng;
    use std::sync::Arc;
    let (positions, triangles) = grid_sheet(6, |u, v| 0.15 * (3.0 * u).sin() + 0.25 * v);
    let random_vector = |rng: &mut rand_pcg::Pcg64, r: f32| {
        Vec3::new(
            rng.gen_range(-r..r),
            rng.gen_range(-r..r),
            rng.gen_range(-r..r),
        )
    };
    let terms = terms
        .iter()
        .map(|&term| TermVertices {
            term,
            fg: positions
                .iter()
                .map(|_| Vec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()))
                .collect(),
            // Per layer, a random linear field of directions plus a little per-vertex noise:
            // smooth enough that the implicit LOD spans several mip levels across the lens.
            directions: (0..layers)
                .map(|_| {
                    let base = random_vector(rng, 1.0);
                    let gx = random_vector(rng, 2.0);
                    let gy = random_vector(rng, 2.0);
                    positions
                        .iter()
                        .map(|p| base + gx * p.x + gy * p.y + random_vector(rng, 0.05))
                        .collect()
                })
                .collect(),
        })
        .collect();
    let weights: Vec<f32> = match viewpoints {
        1 => vec![1.0],
        2 => {
            let w: f32 = rng.gen_range(0.05..0.95);
            vec![w, 1.0 - w]
        }
        _ => {
            // A point inside a spherical triangle: three positive weights summing to 1.
            let raw: Vec<f32> = (0..viewpoints).map(|_| rng.gen_range(0.05..1.0)).collect();
            let total: f32 = raw.iter().sum();
            raw.iter().map(|w| w / total).collect()
        }
    };
    let layer_maps = (0..viewpoints)
        .map(|_| {
            (0..layers)
                .map(|_| Arc::new(random_cube(rng, 16)))
                .collect()
        })
        .collect();
    let eye = Vec3::new(0.3, 0.2, 2.6);
    let view = glam::camera::rh::view::look_at_mat4(eye, Vec3::ZERO, Vec3::Y);
    let projection =
        glam::camera::rh::proj::vulkan::perspective(45f32.to_radians(), 1.0, 0.1, 20.0);
    let view_proj: Mat4 = projection * view;
    FrameInput {
        width: size,
        height: size,
        view_proj,
        environment: vec![Arc::new(EnvironmentMesh {
            positions: vec![
                Vec3::new(-6.0, -6.0, -3.0),
                Vec3::new(6.0, -6.0, -3.0),
                Vec3::new(0.0, 6.0, -3.0),
            ],
            colours: vec![
                Vec3::new(0.9, 0.1, 0.1),
                Vec3::new(0.1, 0.9, 0.1),
                Vec3::new(0.1, 0.1, 0.9),
            ],
            triangles: vec![[0, 1, 2]],
            light_map: None,
        })],
        glossy: Vec::new(),
        lenses: vec![LensObject {
            name: "sheet".into(),
            positions,
            triangles,
            faces: LensFaces::Front,
            hull_triangles: 0,
            terms,
            layers: layer_maps,
            resident: None,
        }],
        viewpoint_weights: weights,
    }
}
