//! The compositor against independent answers: the multipass frame in RGBA32F equals the CPU f64
//! model (which evaluates the blend sequence and samples cube maps the way the Vulkan spec
//! describes), with every blending scheme, and the single-pass frame equals the multipass frame,
//! on random inputs with one, two and three viewpoint samples. Every GPU path runs with the
//! validation layer on.
//!
//! On any driver the GPU frames must lie in the model's bounds ([`ModelImage::bounds`]), derived
//! from the spec's minimum `subTexelPrecisionBits` and `mipmapPrecisionBits` (4 and 4, what
//! conformance holds every driver to: [`FilterPrecision::SPEC_MINIMUM`]) and the LOD
//! approximation the spec allows, plus [`F32_SLACK`]. On lavapipe they must also equal the
//! model's nominal value (lavapipe's measured LOD choices, [`ModelOptions::lavapipe`]) to 1e-5.

use lensmap::render::Compositing;
use std::sync::Arc;

use glam::Vec3;
use lensmap::cubemap::CubeMap;
use lensmap::gpu::Gpu;
use lensmap::index::LensIndex;
use lensmap::metrics::Mask;
use lensmap::render::{
    BlendScheme, FrameInput, PassCategory, RenderOptions, RenderedImage, Renderer,
    SinglePassLimits, TargetFormat, UploadedFrame, Variant, frame_lens_pixels,
    model::{FilterPrecision, ModelImage, ModelOptions, render_model},
};
use lensmap::trace::{LensSelection, Term};
use lensmap_tests::fixtures::compositor;
use lensmap_tests::render_rgba32f;
use lensmap_tests::{assert_clean, gpu, random_compositor_frame};
use rand::SeedableRng;
use rand_pcg::Pcg64;

const SIZE: u32 = 96;

/// The per-scheme test's exact tolerance on lavapipe. Its frames reach 1.03e-5 at one pixel's α
/// (the same pixel and value for all four schemes, so the difference is the GPU's f32 sampling,
/// not the blending); 2e-5 keeps the check exact to f32 sampling noise. The first test's frames
/// stay within 1e-5 (largest 9.2e-6).
const EXACT: f64 = 2e-5;

/// Absolute slack on top of [`ModelImage::bounds`] for the GPU's f32 arithmetic (interpolated
/// directions and F·G, face projection, blending); the bounds themselves are exact. The same
/// 1e-5 the exact comparison uses on lavapipe, where the largest GPU − model difference measured
/// is < 9e-6 on values ≤ 1.
const F32_SLACK: f64 = 1e-5;

/// What a comparison on this device checks.
struct Tolerance {
    /// The filtering precision the bounds assume: [`FilterPrecision::SPEC_MINIMUM`], the
    /// precision every conformant driver is held to (see there: a driver's reported
    /// `subTexelPrecisionBits` and `mipmapPrecisionBits` are not checked by conformance, and
    /// Mesa 25.0's lavapipe exceeds its reported 6 mipmap bits).
    precision: FilterPrecision,
    /// The precision the device reports, from `gpu.properties().limits`: pixels outside the
    /// bounds it would give are counted and printed, not failed.
    reported: FilterPrecision,
    /// The device is lavapipe, whose LOD arithmetic the model's nominal value reproduces: the
    /// exact 1e-5 comparison applies as well (measured on Mesa 22.3 and 25.0).
    exact: bool,
}

impl Tolerance {
    fn of(gpu: &Gpu) -> Tolerance {
        Tolerance {
            precision: FilterPrecision::SPEC_MINIMUM,
            reported: gpu.filter_precision(),
            exact: gpu.device_name().starts_with("llvmpipe"),
        }
    }
}

/// The model of lavapipe's nominal values with the bounds of `precision`.
fn model_options(precision: FilterPrecision) -> ModelOptions {
    ModelOptions {
        precision: Some(precision),
        ..ModelOptions::lavapipe()
    }
}

/// The largest channel width of pixel `i`'s bounds.
fn bound_width(model: &ModelImage, i: usize) -> f64 {
    model.bounds[i]
        .iter()
        .map(|[lo, hi]| hi - lo)
        .fold(0.0, f64::max)
}

/// `image`'s pixel `i` as f64.
fn pixel(image: &RenderedImage, i: usize) -> [f64; 4] {
    image.pixels[i].map(f64::from)
}

/// A random frame of `SIZE²` pixels (`lensmap_tests::random_compositor_frame`).
fn random_frame(rng: &mut Pcg64, layers: usize, viewpoints: usize, terms: &[Term]) -> FrameInput {
    random_compositor_frame(rng, SIZE, layers, viewpoints, terms)
}

#[test]
fn multipass_rgba32f_matches_the_f64_model_and_single_pass_matches_multipass() {
    let gpu = gpu();
    let tolerance = Tolerance::of(&gpu);
    let (precision, reported) = (tolerance.precision, tolerance.reported);
    println!(
        "{}: bounds from the spec's minimum precision, subTexelPrecisionBits = {}, \
         mipmapPrecisionBits = {} (LOD within the spec's scale-factor approximation, coarse or \
         fine derivatives, ± 2·2^-{}) plus {F32_SLACK:e} for f32; the device reports {} and {}; \
         exact 1e-5 check against lavapipe's LOD choices: {}",
        gpu.device_name(),
        precision.sub_texel_bits,
        precision.mipmap_bits,
        precision.mipmap_bits,
        reported.sub_texel_bits,
        reported.mipmap_bits,
        if tolerance.exact {
            "yes"
        } else {
            "no (not lavapipe)"
        }
    );
    let mut outside_reported = 0;
    let mut compared_total = 0;
    let mut renderer = Renderer::new(&gpu).unwrap();
    let mut rng = Pcg64::seed_from_u64(0x01e4_53a9);
    let both = [Term::Refraction, Term::Reflection];
    let mut worst_model: f64 = 0.0;
    let mut worst_outside: f64 = 0.0;
    let mut worst_single: f64 = 0.0;
    // Per viewpoint count, the largest |GPU − model| of the multipass and the single pass.
    let mut worst_by_viewpoints = [[0f64; 2]; 3];
    let mut widths = Vec::new();
    for layers in 1..=4 {
        for viewpoints in 1..=3 {
            for terms in [&both[..], &[Term::Reflection][..]] {
                let frame = random_frame(&mut rng, layers, viewpoints, terms);
                let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
                let multipass = render_rgba32f(
                    &mut renderer,
                    &gpu,
                    &mut uploaded,
                    Compositing::Multipass(BlendScheme::FrontToBack),
                );
                let single =
                    render_rgba32f(&mut renderer, &gpu, &mut uploaded, Compositing::SinglePass);

                let model = render_model(&frame, &model_options(tolerance.precision));
                let reported_model = render_model(&frame, &model_options(tolerance.reported));
                let lens_pixels = model.lens_mask.iter().filter(|m| **m).count();
                let compared = model.comparable_lens_pixels();
                let case = format!("n = {layers}, {viewpoints} viewpoint(s), terms {terms:?}");
                // Pixels the model marks ill-defined (coverage ties on triangle edges, cube
                // corners the spec leaves to the implementation, LOD face ties) are left out and
                // counted; the test requires most lens pixels to be compared.
                assert!(
                    lens_pixels > 1500,
                    "{case}: the lens covers only {lens_pixels} pixels"
                );
                assert!(
                    compared * 10 >= lens_pixels * 8,
                    "{case}: only {compared} of {lens_pixels} lens pixels comparable; excluded: {:?}",
                    model.exclusion_counts()
                );
                for i in 0..multipass.pixels.len() {
                    if model.exclusion[i].is_some() {
                        continue;
                    }
                    if model.lens_mask[i] {
                        widths.push(bound_width(&model, i));
                    }
                    let (x, y) = (i as u32 % SIZE, i as u32 / SIZE);
                    // Single pass and multipass evaluate the same spec formula from the same
                    // inputs, so both lie in the bounds on any driver. Whether they agree beyond
                    // that depends on the driver sampling identically in two pipelines, which
                    // the spec does not promise: 1e-5 is checked where measured (lavapipe).
                    for (variant, image) in [("multipass", &multipass), ("single pass", &single)] {
                        let outside = model.distance_outside_bounds(i, pixel(image, i));
                        worst_outside = worst_outside.max(outside);
                        assert!(
                            outside <= F32_SLACK,
                            "{case}: {variant} pixel ({x}, {y}) {:?} lies {outside:.3e} outside the \
                             model's bounds {:?} (lens: {})",
                            image.pixels[i],
                            model.bounds[i],
                            model.lens_mask[i]
                        );
                    }
                    compared_total += 1;
                    if reported_model.exclusion[i].is_none()
                        && reported_model.distance_outside_bounds(i, pixel(&multipass, i))
                            > F32_SLACK
                    {
                        outside_reported += 1;
                    }
                    let (gpu_pixel, model_pixel) = (pixel(&multipass, i), model.rgba[i]);
                    for c in 0..4 {
                        let worst = &mut worst_by_viewpoints[viewpoints - 1];
                        worst[1] = worst[1].max((pixel(&single, i)[c] - model_pixel[c]).abs());
                        let d = (gpu_pixel[c] - model_pixel[c]).abs();
                        worst[0] = worst[0].max(d);
                        worst_model = worst_model.max(d);
                        assert!(
                            !tolerance.exact || d <= 1e-5,
                            "{case}: pixel ({x}, {y}) channel {c}: GPU {} vs model {} (lens: {})",
                            gpu_pixel[c],
                            model_pixel[c],
                            model.lens_mask[i]
                        );
                    }
                }
                for (i, (a, b)) in single.pixels.iter().zip(&multipass.pixels).enumerate() {
                    for c in 0..4 {
                        let d = f64::from((a[c] - b[c]).abs());
                        worst_single = worst_single.max(d);
                        assert!(
                            !tolerance.exact || d <= 1e-5,
                            "{case}: single pass {a:?} vs multipass {b:?} at pixel {i}"
                        );
                    }
                }
                println!(
                    "{case}: {compared}/{lens_pixels} lens pixels compared, excluded {:?}",
                    model.exclusion_counts()
                );
            }
        }
    }
    println!(
        "with the device's reported precision ({} and {} bits) instead: {outside_reported} of \
         {compared_total} compared pixels outside the bounds (not a failure: conformance holds a \
         driver to the spec's minimum)",
        reported.sub_texel_bits, reported.mipmap_bits
    );
    widths.sort_by(f64::total_cmp);
    println!(
        "over {} compared lens pixels: bound width (largest channel) median {:.3e}, 90th percentile {:.3e}, largest {:.3e}; \
         largest |GPU − model| {worst_model:.3e}; largest distance outside the bounds \
         {worst_outside:.3e}; largest |single pass − multipass| {worst_single:.3e}",
        widths.len(),
        widths[widths.len() / 2],
        widths[widths.len() * 9 / 10],
        widths.last().unwrap()
    );
    for (v, [multipass, single]) in worst_by_viewpoints.iter().enumerate() {
        println!(
            "{} viewpoint(s): largest |GPU − model| multipass {multipass:.3e}, single pass {single:.3e}",
            v + 1
        );
    }
    assert_clean(&gpu);
}

/// Renders `frame` composited by `compositing` and checks it against the f64 model of its
/// arithmetic order (the single pass's is front-to-back's); the largest |GPU − model|.
fn against_model(
    case: &str,
    gpu: &Gpu,
    renderer: &mut Renderer,
    uploaded: &mut UploadedFrame,
    frame: &FrameInput,
    compositing: Compositing,
    tolerance: &Tolerance,
) -> f64 {
    let (image, _) = renderer
        .render(
            gpu,
            uploaded,
            &RenderOptions {
                compositing,
                format: TargetFormat::Rgba32f,
                host: None,
            },
        )
        .unwrap();
    let options = ModelOptions {
        blend: compositing.blend(),
        ..model_options(tolerance.precision)
    };
    let model = render_model(frame, &options);
    assert_matches_model(case, &image, &model, tolerance)
}

/// Every blending scheme's RGBA32F frame against the f64 model of that scheme's passes (its own
/// arithmetic order): within 1e-5 on lavapipe and inside the device-derived bounds on any driver;
/// glass and mirror, one, two and three viewpoints, n = 1 and 3.
#[test]
fn every_blending_scheme_matches_its_f64_model() {
    let (gpu, mut renderer, mut rng) = compositor(0x05c4_e3e5);
    let tolerance = Tolerance::of(&gpu);
    let both = [Term::Refraction, Term::Reflection];
    // Per viewpoint count and scheme, the largest |GPU − model|.
    let mut worst = [[0f64; 4]; 3];
    for layers in [1, 3] {
        for viewpoints in 1..=3 {
            for terms in [&both[..], &[Term::Reflection][..]] {
                let frame = random_frame(&mut rng, layers, viewpoints, terms);
                let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
                for (k, blend) in BlendScheme::ALL.into_iter().enumerate() {
                    let case = format!(
                        "{}: n = {layers}, {viewpoints} viewpoint(s), terms {terms:?}",
                        blend.name()
                    );
                    let d = against_model(
                        &case,
                        &gpu,
                        &mut renderer,
                        &mut uploaded,
                        &frame,
                        Compositing::Multipass(blend),
                        &tolerance,
                    );
                    worst[viewpoints - 1][k] = worst[viewpoints - 1][k].max(d);
                }
            }
        }
    }
    for (v, worst) in worst.iter().enumerate() {
        for (k, blend) in BlendScheme::ALL.into_iter().enumerate() {
            println!(
                "{}, {} viewpoint(s): largest |GPU − model| {:.3e}",
                blend.name(),
                v + 1,
                worst[k]
            );
        }
    }
    assert_clean(&gpu);
}

/// Path-class terms (R, TT, TRT and TRRT; 3 and 4 of them) make (viewpoint sample, class)
/// groups: every blending scheme's RGBA32F frame against the f64 model of that scheme's
/// passes, within the same bounds as the greedy terms', n = 1 and 3, one to three viewpoints;
/// the single pass, whose K·(n + 1) varyings they fit, against the model of its front-to-back
/// order. Six classes at n = 3 (24 varyings) the single pass refuses with an error naming the
/// multipass variant.
#[test]
fn path_class_terms_match_the_f64_model_in_every_scheme() {
    use lensmap::trace::PathClass;
    use lensmap::trace::classes::ClassTerm;
    let (gpu, mut renderer, mut rng) = compositor(0x0c1a_55e5);
    let tolerance = Tolerance::of(&gpu);
    let classes = |count: usize| -> Vec<Term> {
        (0..count)
            .map(|i| {
                Term::Class(ClassTerm {
                    class: PathClass::glass(i).unwrap(),
                    greedy_tail: false,
                })
            })
            .collect()
    };
    let compositings: Vec<Compositing> = BlendScheme::ALL
        .into_iter()
        .map(Compositing::Multipass)
        .chain([Compositing::SinglePass])
        .collect();
    let name = |c: Compositing| match c {
        Compositing::SinglePass => "single pass",
        Compositing::Multipass(blend) => blend.name(),
    };
    let mut worst = vec![0f64; compositings.len()];
    for count in [3, 4] {
        for layers in [1, 3] {
            for viewpoints in 1..=3 {
                let frame = random_frame(&mut rng, layers, viewpoints, &classes(count));
                let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
                for (k, &compositing) in compositings.iter().enumerate() {
                    let case = format!(
                        "{}: n = {layers}, {viewpoints} viewpoint(s), {count} classes",
                        name(compositing)
                    );
                    let d = against_model(
                        &case,
                        &gpu,
                        &mut renderer,
                        &mut uploaded,
                        &frame,
                        compositing,
                        &tolerance,
                    );
                    worst[k] = worst[k].max(d);
                }
            }
        }
    }
    let frame = random_frame(&mut rng, 3, 2, &classes(6));
    let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
    let error = renderer
        .render(
            &gpu,
            &mut uploaded,
            &RenderOptions {
                compositing: Compositing::SinglePass,
                format: TargetFormat::Rgba32f,
                host: None,
            },
        )
        .unwrap_err();
    assert!(
        error.to_string().contains(
            "= 24 varyings for them, at most 16 as its shader is compiled: use the multipass variant"
        ),
        "{error}"
    );
    for (k, &compositing) in compositings.iter().enumerate() {
        println!(
            "{}, path classes: largest |GPU − model| {:.3e}",
            name(compositing),
            worst[k]
        );
    }
    assert_clean(&gpu);
}

/// `image` (one scheme's RGBA32F frame) against `model` (that scheme's): most lens pixels
/// comparable, every comparable pixel inside the bounds plus [`F32_SLACK`] and, on lavapipe,
/// within [`EXACT`]; returns the largest |GPU − model|.
fn assert_matches_model(
    case: &str,
    image: &RenderedImage,
    model: &ModelImage,
    tolerance: &Tolerance,
) -> f64 {
    let lens_pixels = model.lens_mask.iter().filter(|m| **m).count();
    assert!(
        model.comparable_lens_pixels() * 10 >= lens_pixels * 8,
        "{case}: too few comparable pixels"
    );
    let mut worst: f64 = 0.0;
    for i in 0..image.pixels.len() {
        if model.exclusion[i].is_some() {
            continue;
        }
        let outside = model.distance_outside_bounds(i, pixel(image, i));
        assert!(
            outside <= F32_SLACK,
            "{case}: pixel {i} {outside:e} outside"
        );
        for c in 0..4 {
            let d = (pixel(image, i)[c] - model.rgba[i][c]).abs();
            worst = worst.max(d);
            assert!(
                !tolerance.exact || d <= EXACT,
                "{case}: pixel {i} channel {c}: GPU {} vs model {}",
                image.pixels[i][c],
                model.rgba[i][c]
            );
        }
    }
    worst
}

/// The bound check can fail: GPU frames of deliberately wrong inputs (the two viewpoints' weights
/// swapped, the two terms' F·G swapped, the layers in reverse order) are compared against the
/// model of the right input; each mistake must put a large share of the compared lens pixels
/// outside the bounds: ≥ 75 % with Mesa 22.3 lavapipe's reported precision (8 sub-texel, 4 mipmap bits; measured
/// 84–99 %), ≥ 25 % with the loosest the spec allows (4 and 4; measured 33–94 %), and the device's
/// own as much as the looser of the two it is at least as precise as (the bounds shrink as the
/// bits grow, so the share only rises).
#[test]
fn the_bound_check_rejects_wrong_frames() {
    let (gpu, mut renderer, mut rng) = compositor(0x0b0_04d5);
    let tolerance = Tolerance::of(&gpu);
    let mut frame = random_frame(&mut rng, 3, 2, &[Term::Refraction, Term::Reflection]);
    frame.viewpoint_weights = vec![0.15, 0.85];
    let mut swapped_weights = frame.clone();
    swapped_weights.viewpoint_weights.reverse();
    let mut swapped_fg = frame.clone();
    let fg = swapped_fg.lenses[0].terms[0].fg.clone();
    swapped_fg.lenses[0].terms[0].fg = swapped_fg.lenses[0].terms[1].fg.clone();
    swapped_fg.lenses[0].terms[1].fg = fg;
    let mut reversed_layers = frame.clone();
    for layers in &mut reversed_layers.lenses[0].layers {
        layers.reverse();
    }
    let mistakes = [
        ("viewpoint weights swapped", swapped_weights),
        ("F·G of the two terms swapped", swapped_fg),
        ("layers in reverse order", reversed_layers),
    ];
    let lavapipe_precision = FilterPrecision {
        sub_texel_bits: 8,
        mipmap_bits: 4,
    };
    let device = tolerance.reported;
    let device_share = if device.sub_texel_bits >= 8 && device.mipmap_bits >= 4 {
        0.75
    } else {
        0.25
    };
    for (precision, least_share) in [
        (FilterPrecision::SPEC_MINIMUM, 0.25),
        (lavapipe_precision, 0.75),
        (device, device_share),
    ] {
        let options = model_options(precision);
        let model = render_model(&frame, &options);
        let compared: Vec<usize> = (0..model.rgba.len())
            .filter(|&i| model.lens_mask[i] && model.exclusion[i].is_none())
            .collect();
        assert!(compared.len() > 1500, "{} pixels compared", compared.len());
        for (mistake, wrong) in &mistakes {
            let mut uploaded = renderer.upload(&gpu, wrong).unwrap();
            let image = render_rgba32f(
                &mut renderer,
                &gpu,
                &mut uploaded,
                Compositing::Multipass(BlendScheme::FrontToBack),
            );
            let rejected = compared
                .iter()
                .filter(|&&i| model.distance_outside_bounds(i, pixel(&image, i)) > F32_SLACK)
                .count();
            let share = rejected as f64 / compared.len() as f64;
            println!(
                "{mistake}, bounds from {precision:?}: {rejected}/{} compared lens pixels \
                 rejected ({:.1} %)",
                compared.len(),
                100.0 * share
            );
            assert!(
                share >= least_share,
                "{mistake}: only {:.1} % of lens pixels outside the bounds",
                100.0 * share
            );
        }
    }
    assert_clean(&gpu);
}

#[test]
fn zero_weight_viewpoint_renders_like_one_viewpoint() {
    let (gpu, mut renderer, mut rng) = compositor(7);
    let both = random_frame(&mut rng, 2, 2, &[Term::Refraction, Term::Reflection]);
    // Either viewpoint may be the one with weight 0.
    for zero in [1, 0] {
        let mut frame = both.clone();
        frame.viewpoint_weights = if zero == 1 {
            vec![1.0, 0.0]
        } else {
            vec![0.0, 1.0]
        };
        let mut single = frame.clone();
        single.viewpoint_weights = vec![1.0];
        single.lenses[0].layers.remove(zero);
        renders_like(
            &gpu,
            &mut renderer,
            &frame,
            &single,
            PlanCounts {
                layer_passes: 4,
                alpha_clears: 1,
            },
            zero,
        );
    }
    assert_clean(&gpu);
}

/// A multipass plan's layer passes and alpha clears.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PlanCounts {
    layer_passes: usize,
    alpha_clears: usize,
}

/// `frame`, whose viewpoint `zero` has weight 0, renders bit for bit like `without` (the same
/// frame without that viewpoint) in both variants, and its multipass plan has `counts`: the zero-weight viewpoint's groups are left out.
fn renders_like(
    gpu: &Gpu,
    renderer: &mut Renderer,
    frame: &FrameInput,
    without: &FrameInput,
    counts: PlanCounts,
    zero: usize,
) {
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let mut a = renderer.upload(gpu, frame).unwrap();
        let mut b = renderer.upload(gpu, without).unwrap();
        let plan = Renderer::plan(
            &a,
            &RenderOptions {
                compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
                format: TargetFormat::Rgba32f,
                ..Default::default()
            },
        )
        .unwrap();
        if variant == Variant::Multipass {
            let found = PlanCounts {
                layer_passes: plan.count(PassCategory::Layer),
                alpha_clears: plan.count(PassCategory::AlphaClear),
            };
            assert_eq!(found, counts, "{plan}");
        }
        let x = render_rgba32f(
            renderer,
            gpu,
            &mut a,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        let y = render_rgba32f(
            renderer,
            gpu,
            &mut b,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        assert_eq!(x, y, "{variant:?}, weight 0 on viewpoint {zero}");
    }
}

/// Three viewpoint samples with one at weight 0 (a camera on an edge of a spherical triangle)
/// render exactly like the frame of the other two: the plan leaves the zero-weight viewpoint's
/// groups out, and the single pass binds the remaining two in order, whichever position the
/// zero takes.
#[test]
fn a_zero_weight_among_three_viewpoints_renders_like_two() {
    let (gpu, mut renderer, mut rng) = compositor(0x3_0e4d);
    let three = random_frame(&mut rng, 2, 3, &[Term::Refraction, Term::Reflection]);
    for zero in 0..3 {
        let mut frame = three.clone();
        frame.viewpoint_weights = vec![0.3; 3];
        frame.viewpoint_weights[zero] = 0.0;
        frame.viewpoint_weights[(zero + 1) % 3] = 0.7;
        let mut two = frame.clone();
        two.viewpoint_weights.remove(zero);
        two.lenses[0].layers.remove(zero);
        renders_like(
            &gpu,
            &mut renderer,
            &frame,
            &two,
            PlanCounts {
                layer_passes: 8,
                alpha_clears: 3,
            },
            zero,
        );
    }
    assert_clean(&gpu);
}

#[test]
fn frames_the_renderer_cannot_draw_are_errors_not_panics() {
    let (gpu, mut renderer, mut rng) = compositor(5);
    // The spec's minimum limits fit what the single pass is compiled for (see
    // SinglePassLimits), so on a conformant device its limits are the shader's.
    let limits = SinglePassLimits::of_device(&gpu.properties().limits);
    println!(
        "{}: the single pass composites at most {} layers ({}) and {} viewpoints ({})",
        gpu.device_id().driver_description(),
        limits.max_layers,
        limits.layers_bound,
        limits.max_viewpoints,
        limits.viewpoints_bound
    );
    assert_eq!(limits, SinglePassLimits::COMPILED);
    // Two lens objects with one name would give two passes one name.
    let mut frame = random_frame(&mut rng, 1, 1, &[Term::Reflection]);
    frame.lenses.push(frame.lenses[0].clone());
    let message = renderer
        .upload(&gpu, &frame)
        .err()
        .expect("duplicate names are rejected")
        .to_string();
    assert!(message.contains("name"), "{message}");
    // A lens with no layers.
    let mut frame = random_frame(&mut rng, 1, 1, &[Term::Reflection]);
    frame.lenses[0].layers[0].clear();
    frame.lenses[0].terms[0].directions.clear();
    let message = renderer
        .upload(&gpu, &frame)
        .err()
        .expect("no layers is rejected")
        .to_string();
    assert!(message.contains("no layers"), "{message}");
    // More layers than the single pass carries: an error naming the way out; multipass draws it.
    let frame = random_frame(&mut rng, 7, 1, &[Term::Reflection]);
    let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
    let message = renderer
        .render(
            &gpu,
            &mut uploaded,
            &RenderOptions {
                compositing: Compositing::SinglePass,
                format: TargetFormat::Rgba8,
                ..Default::default()
            },
        )
        .expect_err("7 layers in the single pass is rejected")
        .to_string();
    assert!(message.contains("multipass"), "{message}");
    renderer
        .render(
            &gpu,
            &mut uploaded,
            &RenderOptions {
                compositing: Compositing::Multipass(BlendScheme::FrontToBack),
                format: TargetFormat::Rgba8,
                ..Default::default()
            },
        )
        .unwrap();
    assert_clean(&gpu);
}

/// Maps over the device's budget for maps (the heap made 1 MiB through the GPU's heap limit, so
/// the budget is 20 % of it): the upload is refused with one error naming the size, the budget
/// and the options that shrink them, before anything is uploaded; the frame uploaded before it
/// and a smaller frame uploaded after it render exactly as on a renderer that never saw the
/// refusal.
#[test]
fn maps_over_the_budget_are_refused_before_upload_and_lose_nothing() {
    let heap = 1u64 << 20;
    let gpu = lensmap_tests::gpu_with_heap_limit(Some(heap));
    assert_eq!(gpu.device_local_heap_bytes(), heap);
    let mut renderer = Renderer::new(&gpu).unwrap();
    let mut rng = Pcg64::seed_from_u64(0xb0d6e7);
    let both = [Term::Refraction, Term::Reflection];
    // One viewpoint of two 16² cube maps: 64 KiB, within the 205 KiB budget.
    let small = random_compositor_frame(&mut rng, 32, 2, 1, &both);
    // Three viewpoints of three: nine cube maps, 288 KiB.
    let large = random_compositor_frame(&mut rng, 32, 3, 3, &both);
    let before = lensmap::render::MapBytes::of_frame(&small);
    assert_eq!(before.total(), 2 * 32736);
    let mut uploaded = renderer.upload(&gpu, &small).unwrap();
    let first = render_rgba32f(&mut renderer, &gpu, &mut uploaded, Compositing::SinglePass);

    let error = renderer
        .upload(&gpu, &large)
        .err()
        .expect("nine cube maps are over the budget");
    let lensmap::render::RenderError::Maps(refusal) = &error else {
        panic!("not a map-budget refusal: {error}");
    };
    assert_eq!(refusal.maps.cube_maps, 9);
    assert_eq!(refusal.maps.total(), 9 * 32736);
    assert_eq!(
        refusal.budget,
        (heap as f64 * lensmap::render::MAP_HEAP_SHARE) as u64
    );
    let message = error.to_string();
    assert_eq!(message.lines().count(), 1, "{message}");
    for words in [
        "287.7 KiB",
        "204.8 KiB",
        "`ProjectedOptions.size`",
        "`LightMapOptions.max_texels`",
    ] {
        assert!(message.contains(words), "{words}: {message}");
    }

    // The frame uploaded before renders as before, and a smaller frame after the refusal
    // renders as it does on a fresh renderer.
    let again = render_rgba32f(&mut renderer, &gpu, &mut uploaded, Compositing::SinglePass);
    assert_eq!(again, first);
    let smaller = random_compositor_frame(&mut rng, 32, 1, 3, &both);
    let mut after = renderer.upload(&gpu, &smaller).unwrap();
    let mut fresh_renderer = Renderer::new(&gpu).unwrap();
    let mut fresh = fresh_renderer.upload(&gpu, &smaller).unwrap();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let image = render_rgba32f(
            &mut renderer,
            &gpu,
            &mut after,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        let expected = render_rgba32f(
            &mut fresh_renderer,
            &gpu,
            &mut fresh,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        assert_eq!(image, expected, "{variant:?}");
    }
    assert_clean(&gpu);
}

#[test]
fn bad_frame_input_is_an_error_not_a_panic() {
    let (gpu, mut renderer, mut rng) = compositor(3);
    let mut frame = random_frame(&mut rng, 1, 1, &[Term::Reflection]);
    frame.lenses[0].terms[0].fg[0] = Vec3::NAN;
    let message = renderer
        .upload(&gpu, &frame)
        .err()
        .expect("NaN F·G is rejected")
        .to_string();
    assert!(
        message.contains("fg") && message.contains("finite"),
        "{message}"
    );
    let mut frame = random_frame(&mut rng, 1, 1, &[Term::Reflection]);
    std::sync::Arc::make_mut(&mut frame.lenses[0].layers[0][0])
        .levels
        .pop();
    let message = renderer
        .upload(&gpu, &frame)
        .err()
        .expect("a short mip chain is rejected")
        .to_string();
    assert!(message.contains("mip levels"), "{message}");
    // Four viewpoint samples: the most a frame blends is three (a spherical triangle's).
    let mut frame = random_frame(&mut rng, 1, 3, &[Term::Reflection]);
    frame.viewpoint_weights.push(0.0);
    let fourth = frame.lenses[0].layers[0].clone();
    frame.lenses[0].layers.push(fourth);
    let message = renderer
        .upload(&gpu, &frame)
        .err()
        .expect("four viewpoints are rejected")
        .to_string();
    assert!(
        message.contains("viewpoint_weights has 4 entries; give 1 to 3"),
        "{message}"
    );
    assert_clean(&gpu);
}

#[test]
fn replacing_the_layered_ems_of_an_uploaded_frame_renders_like_a_fresh_upload() {
    let (gpu, mut renderer, mut rng) = compositor(0x7e91ace);
    let first = random_frame(&mut rng, 2, 2, &[Term::Refraction, Term::Reflection]);
    let second = random_frame(&mut rng, 2, 2, &[Term::Refraction, Term::Reflection]);
    let mut replaced = first.clone();
    replaced.lenses[0].layers = second.lenses[0].layers.clone();
    let mut uploaded = renderer.upload(&gpu, &first).unwrap();
    renderer
        .replace_layers(
            &gpu,
            &mut uploaded,
            LensIndex::new(0),
            &replaced.lenses[0].layers,
        )
        .unwrap();
    let mut fresh = renderer.upload(&gpu, &replaced).unwrap();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let a = render_rgba32f(
            &mut renderer,
            &gpu,
            &mut uploaded,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        let b = render_rgba32f(
            &mut renderer,
            &gpu,
            &mut fresh,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        assert_eq!(a.pixels, b.pixels, "{variant:?}");
    }
    // A replacement that does not fit the uploaded frame is an error naming the lens.
    let wrong = vec![vec![Arc::new(CubeMap::uniform(4, [0.0; 4]))]];
    let error = renderer
        .replace_layers(&gpu, &mut uploaded, LensIndex::new(0), &wrong)
        .unwrap_err();
    assert!(error.to_string().contains("lenses[0]"), "{error}");
    assert_clean(&gpu);
}

/// The lens pixels of a frame by the engine's rule on the frame's geometry
/// (`render::frame_lens_pixels`: each pixel centre's ray through the view-projection, its first
/// drawn surface) against the f64 model's own rasterization of the same frame (its front-most
/// surface is a lens object): two algorithms agree on every pixel the model does not mark
/// ill-defined (coverage ties on triangle edges), which must be most of them.
#[test]
fn the_frames_lens_pixels_are_the_models_lens_coverage() {
    let mut rng = Pcg64::seed_from_u64(0x6e0_3a5c);
    let both = [Term::Refraction, Term::Reflection];
    let frame = random_frame(&mut rng, 2, 2, &both);
    let mask = Mask::lens(&frame_lens_pixels(&frame), LensSelection::All);
    let model = render_model(&frame, &ModelOptions::lavapipe());
    let lens_pixels = model.lens_mask.iter().filter(|m| **m).count();
    assert!(lens_pixels > 1500, "the lens covers {lens_pixels} pixels");
    let mut compared = 0;
    for (i, model_lens) in model.lens_mask.iter().enumerate() {
        if model.exclusion[i].is_some() {
            continue;
        }
        compared += 1;
        assert_eq!(
            mask.contains(i),
            *model_lens,
            "pixel ({}, {}): the frame's lens pixels vs the model's coverage",
            i as u32 % SIZE,
            i as u32 / SIZE
        );
    }
    assert!(
        compared * 10 >= (SIZE * SIZE) as usize * 9,
        "{compared} pixels compared"
    );
}

/// RGBA32F render options of every multipass blending scheme, then the single pass.
fn every_rgba32f_scheme() -> impl Iterator<Item = RenderOptions<'static>> {
    BlendScheme::ALL
        .map(|blend| (Variant::Multipass, blend))
        .into_iter()
        .chain([(Variant::SinglePass, BlendScheme::FrontToBack)])
        .map(|(variant, blend)| RenderOptions {
            compositing: Compositing::new(variant, blend).unwrap(),
            format: TargetFormat::Rgba32f,
            host: None,
        })
}

/// The convex-hull split's draws: a frame whose every lens triangle is a hull triangle renders
/// bit for bit like the same frame with layer 0 made transparent (all zeros) at every viewpoint,
/// in every blending scheme and the single pass (a second construction of "drawn without layer
/// 0"), and unlike the frame without the split.
#[test]
fn hull_triangles_render_like_a_transparent_layer_zero() {
    let (gpu, mut renderer, mut rng) = compositor(0x4a11);
    for viewpoints in [1, 3] {
        let frame = random_frame(
            &mut rng,
            3,
            viewpoints,
            &[Term::Refraction, Term::Reflection],
        );
        let mut split = frame.clone();
        split.lenses[0].hull_triangles = split.lenses[0].triangles.len();
        let mut transparent = frame.clone();
        for maps in &mut transparent.lenses[0].layers {
            maps[0] = Arc::new(CubeMap::uniform(16, [0.0; 4]));
        }
        let mut uploads = [&frame, &split, &transparent].map(|f| renderer.upload(&gpu, f).unwrap());
        for options in every_rgba32f_scheme() {
            let (variant, blend) = (options.compositing.variant(), options.compositing.blend());
            let [plain, split, transparent] = uploads
                .each_mut()
                .map(|uploaded| renderer.render(&gpu, uploaded, &options).unwrap().0.pixels);
            let case = format!("{variant:?} {}, {viewpoints} viewpoint(s)", blend.name());
            assert!(split == transparent, "{case}: hull triangles drew layer 0");
            let changed = plain.iter().zip(&split).filter(|(a, b)| a != b).count();
            assert!(
                changed > 1000,
                "{case}: the split changed only {changed} pixels"
            );
        }
    }
    assert_clean(&gpu);
}

/// Half the lens triangles on the hull (the last half, as the hybrid frame sorts them): every
/// blending scheme and the single pass against the f64 model, which leaves layer 0 off those
/// triangles' fragments; within 1e-5 on lavapipe, inside the bounds on any driver.
#[test]
fn a_partial_hull_split_matches_the_f64_model_in_every_scheme() {
    let (gpu, mut renderer, mut rng) = compositor(0x4a12);
    let tolerance = Tolerance::of(&gpu);
    for viewpoints in 1..=3 {
        for terms in [
            &[Term::Refraction, Term::Reflection][..],
            &[Term::Reflection][..],
        ] {
            let mut frame = random_frame(&mut rng, 2, viewpoints, terms);
            frame.lenses[0].hull_triangles = frame.lenses[0].triangles.len() / 2;
            let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
            for options in every_rgba32f_scheme() {
                let (variant, blend) = (options.compositing.variant(), options.compositing.blend());
                let (image, _) = renderer.render(&gpu, &mut uploaded, &options).unwrap();
                let model = render_model(
                    &frame,
                    &ModelOptions {
                        blend,
                        ..model_options(tolerance.precision)
                    },
                );
                let case = format!(
                    "{variant:?} {}: {viewpoints} viewpoint(s), {terms:?}",
                    blend.name()
                );
                assert_matches_model(&case, &image, &model, &tolerance);
            }
        }
    }
    assert_clean(&gpu);
}
