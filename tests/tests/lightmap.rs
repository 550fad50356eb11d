//! The light-mapped opaque environment against the reference ray tracer: on teapot-room (checker
//! floor, columns casting shadows, walls), the hybrid frame's non-lens pixels — those in which no
//! reference sub-sample sees a lens object — must match the reference's radiance to ≥ 45 dB in
//! display sRGB. GPU work runs with validation on.

use lensmap::render::Compositing;
use lensmap::{
    hybrid::HybridOptions,
    layers::projected::ProjectedOptions,
    metrics::{self, Channels, Encoding, Mask},
    render::TargetFormat,
    runner::{EmSource, FrameOptions, FrameRunner, load_hybrid_scene},
    scene::Scene,
    trace::{TraceOptions, render_reference},
};
use lensmap_tests::{assert_clean, gpu};

/// The least PSNR the non-lens pixels must reach, dB (display sRGB).
const NON_LENS_PSNR_DB: f64 = 45.0;

#[test]
fn non_lens_pixels_match_the_reference() {
    let mut scene = Scene::load_named("teapot-room").unwrap();
    let camera = scene.camera.with_resolution(160, 120, 2);
    scene.camera = camera;
    let ems = EmSource::Projected(ProjectedOptions {
        size: 16,
        supersampling: 1,
    });
    let (hybrid, _) = load_hybrid_scene(scene, &ems.into()).unwrap();
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let options = FrameOptions {
        hybrid: HybridOptions::with_t(6.0),
        compositing: Compositing::SinglePass,
        format: TargetFormat::Rgba32f,
    };
    let frame = runner.frame(&hybrid, &camera, &options).unwrap();
    let reference =
        render_reference(hybrid.trace(), &camera, &TraceOptions::default(), &|_| {}).unwrap();
    // An independent mask from the reference's own coverage (no sub-sample on a lens object).
    let non_lens = Mask::from_flags(reference.lens_mask.iter().map(|&c| c == 0.0).collect());
    let error = metrics::compare(
        &frame.image.pixels,
        &reference.radiance,
        &non_lens,
        Encoding::DisplaySrgb,
        Channels::Rgb,
    )
    .unwrap();
    println!(
        "non-lens PSNR {:.2} dB over {} pixels (largest difference {:.3})",
        error.psnr_db, error.pixels, error.max_abs
    );
    assert!(
        error.pixels > 160 * 120 / 2,
        "{} non-lens pixels",
        error.pixels
    );
    assert!(
        error.psnr_db >= NON_LENS_PSNR_DB,
        "non-lens PSNR {:.2} dB < {NON_LENS_PSNR_DB} dB",
        error.psnr_db
    );
    assert_clean(runner.gpu());
}
