//! What the C ABI costs: the same moving-camera frames of glass-sphere (320×240, t = 3, single
//! pass, RGBA16F) through `lensmap_render_to_memory` and through the Rust API
//! (`FrameRunner::frame`), in one run. The camera steps 0.5° a frame so that no frame is the
//! scene's still-camera reuse. `cargo bench -p lensmap-capi --bench overhead`.

use std::ptr::null_mut;

use criterion::{Criterion, criterion_group, criterion_main};
use lensmap::gpu::{Gpu, GpuOptions};
use lensmap::hybrid::HybridOptions;
use lensmap::layers::projected::ProjectedOptions;
use lensmap::render::{Compositing, TargetFormat};
use lensmap::runner::{EmSource, FrameOptions, FrameRunner, load_hybrid_scene};
use lensmap::scene::{Camera, Scene};
use lensmap_capi::*;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

/// A full turn of cameras around the scene camera's look-at point, 0.5° apart.
fn cameras() -> Vec<Camera> {
    let scene = Scene::load_named("glass-sphere").expect("built in");
    let base = scene.camera.with_resolution(WIDTH, HEIGHT, 1);
    (0..720)
        .map(|step| base.orbited(0.5 * step as f32))
        .collect()
}

fn overhead(c: &mut Criterion) {
    let cameras = cameras();
    let camera = |step: usize| cameras[step % cameras.len()];
    let mut group = c.benchmark_group("glass-sphere 320x240 frame");
    group.sample_size(30);

    // The ABI.
    let (mut context, mut scene) = (null_mut(), null_mut());
    let scene_options = LensmapSceneOptions {
        struct_size: size_of::<LensmapSceneOptions>() as u32,
        scene: c"glass-sphere".as_ptr(),
        bake_dir: std::ptr::null(),
        em_size: 0,
        accept_any_bake: 0,
        light_map_max_texels: 0,
        radiance_dir: std::ptr::null(),
    };
    // SAFETY: valid options and out-pointers.
    unsafe {
        assert_eq!(
            lensmap_context_new(std::ptr::null(), &mut context),
            LensmapResult::Ok
        );
        assert_eq!(
            lensmap_scene_load(&scene_options, &mut scene),
            LensmapResult::Ok
        );
    }
    let mut pixels = vec![0.0f32; (4 * WIDTH * HEIGHT) as usize];
    let mut step = 0;
    group.bench_function("through the C ABI", |b| {
        b.iter(|| {
            step += 1;
            let view = camera(step);
            let options = LensmapFrameOptions {
                struct_size: size_of::<LensmapFrameOptions>() as u32,
                position: view.position.to_array(),
                look_at: view.look_at.to_array(),
                up: view.up.to_array(),
                vfov_degrees: view.vfov_radians.to_degrees(),
                width: WIDTH,
                height: HEIGHT,
                supersampling: 1,
                t: 3.0,
                variant: LENSMAP_VARIANT_SINGLE_PASS,
                format: LENSMAP_FORMAT_RGBA16F,
                blend: LENSMAP_BLEND_FRONT_TO_BACK,
                viewpoint_blending: LENSMAP_VIEWPOINTS_VIEW_SPACE,
                fresnel_texels: 0,
                tracer: LENSMAP_TRACER_CPU,
            };
            // SAFETY: live handles, a buffer of the frame's size.
            let code = unsafe {
                lensmap_render_to_memory(
                    context,
                    scene,
                    &options,
                    pixels.as_mut_ptr(),
                    pixels.len(),
                    std::ptr::null_mut(),
                )
            };
            assert_eq!(code, LensmapResult::Ok);
        })
    });
    // SAFETY: live handles, freed once.
    unsafe {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }

    // The Rust API, the same work.
    let mut runner =
        FrameRunner::new(Gpu::new(&GpuOptions::default()).expect("a device")).expect("a runner");
    let (hybrid, _) = load_hybrid_scene(
        Scene::load_named("glass-sphere").expect("built in"),
        &EmSource::Projected(ProjectedOptions::default()).into(),
    )
    .expect("projected EMs");
    let options = FrameOptions {
        hybrid: HybridOptions::with_t(3.0),
        compositing: Compositing::SinglePass,
        format: TargetFormat::Rgba16f,
    };
    let mut step = 0;
    group.bench_function("through the Rust API", |b| {
        b.iter(|| {
            step += 1;
            let frame = runner
                .frame(&hybrid, &camera(step), &options)
                .expect("a frame");
            pixels.copy_from_slice(frame.image.pixels.as_flattened());
        })
    });
    group.finish();
}

// The macro's generated function has no doc comment to carry.
#[allow(missing_docs)]
mod group {
    super::criterion_group!(benches, super::overhead);
}
use group::benches;
criterion_main!(benches);
