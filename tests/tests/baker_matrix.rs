//! The baker's rendering matrices against the hardware and the CPU f64 model, and the solver
//! against known EMs (the baker issue's "the matrix is the hardware" and "the solver inverts it").

use std::sync::Arc;

use lensmap::{
    cubemap::CubeMap,
    hybrid::{HybridOptions, HybridScene},
    layers::projected::ProjectedOptions,
    render::{
        FrameInput, TargetFormat, Variant,
        model::{ModelOptions, render_model_with},
    },
    runner::FrameRunner,
    scene::{Camera, Scene},
};
use lensmap_baker::{
    infer::DeviceRenderer,
    matrix::{LayerFrames, MatrixError, RenderingMatrix, TestRenderer, TexelLayout},
};
use lensmap_tests::{assert_clean, gpu};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// EM face size of the tests: small, so a full decode is quick, with 5 MIP levels.
const EM_SIZE: u32 = 16;

fn small_camera(scene: &Scene, width: u32, height: u32, k: u32) -> Camera {
    let mut camera = scene.camera;
    camera.width = width;
    camera.height = height;
    camera.supersampling = k;
    camera
}

fn frame_of(name: &str, camera_size: (u32, u32, u32)) -> (HybridScene, FrameInput, Camera) {
    let scene = Scene::load_named(name).unwrap();
    let camera = small_camera(&scene, camera_size.0, camera_size.1, camera_size.2);
    let (hybrid, _) = HybridScene::projected(scene, &ProjectedOptions::with_size(EM_SIZE)).unwrap();
    let (frame, _) = hybrid.frame(&camera, &HybridOptions::default()).unwrap();
    (hybrid, frame, camera)
}

/// A random premultiplied EM with every texel of every level non-zero.
fn random_em(rng: &mut Pcg64, layout: &TexelLayout) -> Vec<[f64; 4]> {
    (0..layout.len())
        .map(|_| {
            let alpha: f64 = rng.gen_range(0.2..1.0);
            [
                alpha * rng.gen_range(0.05..2.0),
                alpha * rng.gen_range(0.05..2.0),
                alpha * rng.gen_range(0.05..2.0),
                alpha,
            ]
        })
        .map(|t: [f64; 4]| t.map(|v| f64::from(v as f32)))
        .collect()
}

struct ModelRenderer;

impl TestRenderer for ModelRenderer {
    fn render(&mut self, frame: &FrameInput) -> Result<Vec<[f64; 4]>, MatrixError> {
        Ok(render_model_with(frame, &ModelOptions::lavapipe()).rgba)
    }
}

#[test]
fn the_matrix_is_the_hardware() {
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let mut rng = Pcg64::seed_from_u64(0x0a11_ce55);
    for name in ["glass-sphere", "teapot-room"] {
        let (_, frame, _) = frame_of(name, (64, 48, 2));
        let frames = LayerFrames::new(&frame, 0).unwrap();
        let n = frames.layer_count();
        for variant in [Variant::Multipass, Variant::SinglePass] {
            for term in frames.terms() {
                for layer in if n > 1 { vec![0, n - 1] } else { vec![0] } {
                    let layer_frame = frames.layer(term, layer).unwrap();
                    let mut device = DeviceRenderer {
                        runner: &mut runner,
                        variant,
                    };
                    let matrix =
                        RenderingMatrix::measure(&mut device, &layer_frame, EM_SIZE, 2).unwrap();
                    let case = format!("{name} {variant:?} {term:?} layer {layer}");
                    let lens_pixels = matrix.coverage().iter().filter(|c| **c > 0.0).count();
                    assert!(lens_pixels > 100, "{case}: {lens_pixels} lens pixels");
                    // Fresh random EMs: the frame equals base + A x everywhere.
                    for _ in 0..2 {
                        let x = random_em(&mut rng, &matrix.layout);
                        let image = runner
                            .render(
                                &layer_frame.with_em(Arc::new(matrix.layout.to_cube(&x))),
                                variant,
                                TargetFormat::Rgba32f,
                            )
                            .unwrap()
                            .box_downsample(2);
                        let ax = matrix.apply(&x);
                        let mut worst = 0.0f64;
                        for (i, (p, (a, b))) in image
                            .pixels
                            .iter()
                            .zip(ax.iter().zip(&matrix.base))
                            .enumerate()
                        {
                            for c in 0..4 {
                                let d = (f64::from(p[c]) - (a[c] + b[c])).abs();
                                worst = worst.max(d);
                                assert!(
                                    d <= 1e-5,
                                    "{case}: pixel {i} channel {c}: GPU {} vs A·x + base {}",
                                    p[c],
                                    a[c] + b[c]
                                );
                            }
                        }
                        println!(
                            "{case}: {} renders, {} non-zeros, {lens_pixels} lens pixels, max |frame − A·x| {worst:.2e}",
                            matrix.renders,
                            matrix.nnz()
                        );
                    }
                }
            }
        }
    }
    assert_clean(runner.gpu());
}

#[test]
fn the_matrix_agrees_with_the_f64_model() {
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let (_, frame, _) = frame_of("teapot-room", (96, 72, 1));
    let frames = LayerFrames::new(&frame, 0).unwrap();
    let layer_frame = frames.layer(frames.terms()[0], 0).unwrap();
    let mut device = DeviceRenderer {
        runner: &mut runner,
        variant: Variant::Multipass,
    };
    let hardware = RenderingMatrix::measure(&mut device, &layer_frame, EM_SIZE, 1).unwrap();
    let model = RenderingMatrix::measure(&mut ModelRenderer, &layer_frame, EM_SIZE, 1).unwrap();
    let excluded = render_model_with(
        &layer_frame.with_em(Arc::new(CubeMap::uniform(EM_SIZE, [0.5; 4]))),
        &ModelOptions::lavapipe(),
    )
    .exclusion;
    let (mut compared, mut close) = (0usize, 0usize);
    for (row, (h, m)) in hardware
        .a
        .outer_iterator()
        .zip(model.a.outer_iterator())
        .enumerate()
    {
        if excluded[row].is_some() {
            continue;
        }
        let mut columns: Vec<usize> = h.indices().iter().chain(m.indices()).copied().collect();
        columns.sort_unstable();
        columns.dedup();
        for column in columns {
            let d = (h.get(column).copied().unwrap_or(0.0) - m.get(column).copied().unwrap_or(0.0))
                .abs();
            compared += 1;
            close += usize::from(d <= 1e-5);
        }
    }
    println!("{close} of {compared} entries within 1e-5 of the f64 model");
    assert!(compared > 1000, "only {compared} entries compared");
    assert!(
        close * 100 >= compared * 95,
        "{close} of {compared} within 1e-5"
    );
    assert_clean(runner.gpu());
}
