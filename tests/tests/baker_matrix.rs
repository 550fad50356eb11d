//! The baker's rendering matrices against the hardware and the CPU f64 model (the matrix is what
//! the hardware renders), and the solver against known EMs (the solver inverts the matrix).

use lensmap::hybrid::FrameBuilder;
use std::sync::Arc;

use lensmap::{
    cubemap::CubeMap,
    hybrid::{HybridOptions, HybridScene, LayeredEms},
    index::{LayerIndex, LensIndex},
    layers::projected::ProjectedOptions,
    render::{
        BlendScheme, Compositing, FrameInput, TargetFormat,
        model::{ModelOptions, render_model},
    },
    runner::FrameRunner,
    scene::{Camera, Scene},
};
use lensmap_baker::{
    infer::DeviceRenderer,
    matrix::{
        LayerFrames, MatrixError, MeasureOptions, RenderingMatrix, TestRenderer, TexelLayout,
    },
    solve::{Equations, Smoothness, SolveError, SolveMethod, SolveOptions, solve},
};
use lensmap_tests::{assert_clean, gpu};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// EM face size of the tests: small, so a full decode is quick, with 5 MIP levels.
const EM_SIZE: u32 = 16;

fn frame_of(name: &str, width: u32, height: u32, k: u32) -> (HybridScene, FrameInput, Camera) {
    let scene = Scene::load_named(name).unwrap();
    let camera = scene.camera.with_resolution(width, height, k);
    let (hybrid, _) = HybridScene::new(
        scene,
        LayeredEms::Projected(ProjectedOptions::with_size(EM_SIZE)).into(),
    )
    .unwrap();
    let (frame, _) = FrameBuilder::new()
        .frame(&hybrid, &camera, &HybridOptions::default())
        .unwrap();
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

/// The CPU f64 compositor model as a test renderer.
#[derive(Default)]
struct ModelRenderer(Option<FrameInput>);

impl TestRenderer for ModelRenderer {
    fn begin(&mut self, frame: &FrameInput) -> Result<(), MatrixError> {
        self.0 = Some(frame.clone());
        Ok(())
    }

    fn render(&mut self, em: Arc<CubeMap>) -> Result<Vec<[f32; 4]>, MatrixError> {
        let frame = self.0.as_mut().expect("begun");
        frame.lenses[0].layers = vec![vec![em]];
        Ok(render_model(frame, &ModelOptions::lavapipe())
            .rgba
            .iter()
            .map(|p| p.map(|v| v as f32))
            .collect())
    }
}

#[test]
fn the_matrix_is_the_hardware() {
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let mut rng = Pcg64::seed_from_u64(0x0a11_ce55);
    for name in ["glass-sphere", "teapot-room"] {
        let (_, frame, _) = frame_of(name, 64, 48, 2);
        let frames = LayerFrames::new(&frame, LensIndex::new(0), 2).unwrap();
        let n = frames.layer_count();
        for variant in [
            Compositing::Multipass(BlendScheme::FrontToBack),
            Compositing::SinglePass,
        ] {
            for term in frames.terms() {
                for layer in if n > 1 { vec![0, n - 1] } else { vec![0] } {
                    let mut layer_frame = frames.layer(term, LayerIndex::new(layer)).unwrap();
                    let mut device = DeviceRenderer::new(&mut runner, variant);
                    let matrix = RenderingMatrix::measure(
                        &mut device,
                        &mut layer_frame,
                        &MeasureOptions::new(EM_SIZE, 2),
                    )
                    .unwrap();
                    let case = format!("{name} {variant:?} {term:?} layer {layer}");
                    let lens_pixels = matrix.coverage().iter().filter(|c| **c > 0.0).count();
                    assert!(lens_pixels > 100, "{case}: {lens_pixels} lens pixels");
                    // Fresh random EMs: the frame equals base + A x everywhere.
                    for _ in 0..2 {
                        let x = random_em(&mut rng, &matrix.layout);
                        let rendered = runner
                            .render(
                                layer_frame.with_em(Arc::new(matrix.layout.to_cube(&x))),
                                variant,
                                TargetFormat::Rgba32f,
                            )
                            .unwrap();
                        let image = layer_frame.to_display(&rendered.pixels, 2);
                        let ax = matrix.apply(&x);
                        let mut worst = 0.0f64;
                        for (i, (p, (a, b))) in
                            image.iter().zip(ax.iter().zip(&matrix.base)).enumerate()
                        {
                            for c in 0..4 {
                                let d = (p[c] - (a[c] + b[c])).abs();
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
    let (_, frame, _) = frame_of("teapot-room", 96, 72, 1);
    let frames = LayerFrames::new(&frame, LensIndex::new(0), 1).unwrap();
    let mut layer_frame = frames.layer(frames.terms()[0], LayerIndex::new(0)).unwrap();
    let mut device = DeviceRenderer::new(
        &mut runner,
        Compositing::Multipass(BlendScheme::FrontToBack),
    );
    let hardware = RenderingMatrix::measure(
        &mut device,
        &mut layer_frame,
        &MeasureOptions::new(EM_SIZE, 1),
    )
    .unwrap();
    let model = RenderingMatrix::measure(
        &mut ModelRenderer::default(),
        &mut layer_frame,
        &MeasureOptions::new(EM_SIZE, 1),
    )
    .unwrap();
    let exclusion = render_model(
        layer_frame.with_em(Arc::new(CubeMap::uniform(EM_SIZE, [0.5; 4]))),
        &ModelOptions::lavapipe(),
    )
    .exclusion;
    // Rows are display pixels of the whole frame; the model rendered the lens's crop.
    let crop = layer_frame.crop();
    let mut excluded = vec![false; hardware.a.rows()];
    for (i, reason) in exclusion.iter().enumerate() {
        excluded[crop.display_pixel(i, 1)] = reason.is_some();
    }
    let (mut compared, mut close) = (0usize, 0usize);
    for (row, (h, m)) in hardware
        .a
        .outer_iterator()
        .zip(model.a.outer_iterator())
        .enumerate()
    {
        if excluded[row] {
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

/// Standard normal samples (Box–Muller).
fn gaussian(rng: &mut Pcg64) -> f64 {
    let (u, v): (f64, f64) = (rng.gen_range(f64::EPSILON..1.0), rng.gen_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn psnr_over(a: &[[f64; 4]], b: &[[f64; 4]], mask: &[bool]) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for ((a, b), m) in a.iter().zip(b).zip(mask) {
        if *m {
            for c in 0..4 {
                sum += (a[c] - b[c]).powi(2);
                count += 1;
            }
        }
    }
    assert!(count > 0, "empty mask");
    let peak = b
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .flat_map(|(v, _)| *v)
        .fold(0.0f64, f64::max);
    10.0 * (peak * peak / (sum / count as f64)).log10()
}

#[test]
fn the_solver_inverts_the_matrix() {
    let mut runner = FrameRunner::new(gpu()).unwrap();
    // An EM small enough (8², 510 texels) for 128×96 pixels of two terms to determine the texels
    // they see; the re-render holds whatever the size.
    let size = 8;
    let (_, frame, _) = frame_of("teapot-room", 128, 96, 2);
    let frames = LayerFrames::new(&frame, LensIndex::new(0), 2).unwrap();
    let terms = frames.terms();
    let mut device = DeviceRenderer::new(&mut runner, Compositing::SinglePass);
    let matrices: Vec<RenderingMatrix> = terms
        .iter()
        .map(|&t| {
            RenderingMatrix::measure(
                &mut device,
                &mut frames.layer(t, LayerIndex::new(1)).unwrap(),
                &MeasureOptions::new(size, 2),
            )
            .unwrap()
        })
        .collect();
    let layout = matrices[0].layout.clone();
    let smoothness = Smoothness::new(&layout);
    let mut rng = Pcg64::seed_from_u64(0x5017e);
    let truth = random_em(&mut rng, &layout);
    let clean: Vec<Vec<[f64; 4]>> = matrices.iter().map(|m| m.apply(&truth)).collect();
    let masks: Vec<Vec<bool>> = matrices
        .iter()
        .map(|m| m.coverage().iter().map(|c| *c > 0.0).collect())
        .collect();
    let ones = vec![1.0; clean[0].len()];
    let solve_for = |targets: &[Vec<[f64; 4]>]| {
        let equations: Vec<Equations<'_>> = matrices
            .iter()
            .zip(targets)
            .map(|(m, b)| Equations {
                a: &m.a,
                b,
                confidence: &ones,
            })
            .collect();
        solve(
            &equations,
            &layout,
            &smoothness,
            &vec![[0.0; 4]; layout.len()],
            &SolveOptions {
                method: SolveMethod::ConjugateGradient,
                smoothness: 1e-6,
                tolerance: 1e-9,
                max_iterations: 20_000,
            },
        )
        .unwrap()
    };
    let (x, report) = solve_for(&clean);
    println!("clean: {report:?}");
    // The re-render matches b.
    for ((m, b), mask) in matrices.iter().zip(&clean).zip(&masks) {
        let psnr = psnr_over(&m.apply(&x), b, mask);
        println!("re-render PSNR {psnr:.1} dB");
        assert!(psnr >= 60.0, "re-render PSNR {psnr:.1} dB");
    }
    // Observed texels (those whose data weight is a sizeable share of the strongest) match x*;
    // texels nobody sees are finite, in range and smooth.
    let mut weight = vec![0.0f64; layout.len()];
    for m in &matrices {
        for (&v, (_, column)) in m.a.iter() {
            weight[column] += v * v;
        }
    }
    let strongest = weight.iter().copied().fold(0.0, f64::max);
    let mut observed = 0;
    for (i, w) in weight.iter().enumerate() {
        if *w >= 0.05 * strongest {
            observed += 1;
            for c in 0..4 {
                assert!(
                    (x[i][c] - truth[i][c]).abs() <= 1e-3,
                    "observed texel {:?} channel {c}: {} vs x* {}",
                    layout.texel(i),
                    x[i][c],
                    truth[i][c]
                );
            }
        }
    }
    let unseen: Vec<usize> = (0..layout.len()).filter(|&i| weight[i] == 0.0).collect();
    println!("{observed} observed texels, {} unseen", unseen.len());
    assert!(observed > 20 && !unseen.is_empty());
    for &i in &unseen {
        assert!(x[i].iter().all(|v| v.is_finite()) && (0.0..=1.0).contains(&x[i][3]));
        assert!(x[i][..3].iter().all(|v| *v >= 0.0));
    }
    // Smooth: the fill stays within the range of the observed values (a harmonic field obeys the
    // maximum principle), so no unseen texel overshoots.
    let (lo, hi) = truth
        .iter()
        .flatten()
        .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    for &i in &unseen {
        for c in 0..4 {
            assert!(
                x[i][c] >= lo - 1e-6 && x[i][c] <= hi + 1e-6,
                "unseen {:?}: {:?}",
                layout.texel(i),
                x[i]
            );
        }
    }
    // …and harmonic: their Laplacian (over neighbours within faces, across seams and to parent
    // and child levels) vanishes up to the solver's tolerance.
    let laplacian = smoothness.laplacian(&x);
    for &i in &unseen {
        for c in 0..4 {
            assert!(
                laplacian[i][c].abs() <= 1e-4,
                "unseen {:?}: Laplacian {:?}",
                layout.texel(i),
                laplacian[i]
            );
        }
    }
    // 5% Gaussian noise in b: the re-render is no further from the clean image than the noise.
    let noisy: Vec<Vec<[f64; 4]>> = clean
        .iter()
        .map(|b| {
            let rms =
                (b.iter().flatten().map(|v| v * v).sum::<f64>() / (4 * b.len()) as f64).sqrt();
            b.iter()
                .map(|p| {
                    p.map(|v| {
                        if v != 0.0 {
                            v + 0.05 * rms * gaussian(&mut rng)
                        } else {
                            v
                        }
                    })
                })
                .collect()
        })
        .collect();
    let (xn, report) = solve_for(&noisy);
    println!("noisy: {report:?}");
    for (((m, b), bn), mask) in matrices.iter().zip(&clean).zip(&noisy).zip(&masks) {
        let rerender = psnr_over(&m.apply(&xn), b, mask);
        let noise = psnr_over(bn, b, mask);
        println!("noisy: re-render vs clean {rerender:.1} dB, noise {noise:.1} dB");
        assert!(
            rerender >= noise,
            "re-render {rerender:.1} dB worse than the noise {noise:.1} dB"
        );
    }
    assert_clean(runner.gpu());
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let layout = TexelLayout::new(4);
    let smoothness = Smoothness::new(&layout);
    let mut tri = sprs::TriMat::new((2, layout.len()));
    tri.add_triplet(0, 3, 0.5);
    let a = tri.to_csr();
    let start = vec![[0.0; 4]; layout.len()];
    // Zero confidence everywhere: nothing to fit.
    let zero = solve(
        &[Equations {
            a: &a,
            b: &[[0.5; 4], [0.0; 4]],
            confidence: &[0.0, 0.0],
        }],
        &layout,
        &smoothness,
        &start,
        &SolveOptions::default(),
    );
    assert!(matches!(zero, Err(SolveError::NoData)), "{zero:?}");
    // Mismatched sizes.
    let mismatched = solve(
        &[Equations {
            a: &a,
            b: &[[0.5; 4]],
            confidence: &[1.0, 1.0],
        }],
        &layout,
        &smoothness,
        &start,
        &SolveOptions::default(),
    );
    assert!(
        matches!(mismatched, Err(SolveError::BadInput(_))),
        "{mismatched:?}"
    );
    // NaN in a target.
    let nan = solve(
        &[Equations {
            a: &a,
            b: &[[f64::NAN; 4], [0.0; 4]],
            confidence: &[1.0, 1.0],
        }],
        &layout,
        &smoothness,
        &start,
        &SolveOptions::default(),
    );
    assert!(matches!(nan, Err(SolveError::BadInput(_))), "{nan:?}");
    // A layer no outgoing ray reaches (b = 0 where the lens is): the documented result is a
    // transparent, black layer, finite everywhere.
    let (x, _) = solve(
        &[Equations {
            a: &a,
            b: &[[0.0; 4], [0.0; 4]],
            confidence: &[1.0, 1.0],
        }],
        &layout,
        &smoothness,
        &start,
        &SolveOptions::default(),
    )
    .unwrap();
    assert!(x.iter().flatten().all(|v| *v == 0.0));
}
