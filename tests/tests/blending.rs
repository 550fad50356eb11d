//! The multipass variant's blending schemes (`--blend`) against each other: every scheme's
//! RGBA32F frame equals the paper's front-to-back scheme within 1e-5 on random inputs (random
//! cube maps with every level non-zero, random F·G and weights, glass and mirror, n = 1…4, one to
//! three viewpoints), including frames with all-zero layers and a zero-weight viewpoint, whose
//! passes the plans skip. Every GPU path runs with the validation layer on.

use std::sync::Arc;

use lensmap::cubemap::CubeMap;
use lensmap::metrics::Mask;
use lensmap::render::{
    BlendScheme, Compositing, RenderOptions, Renderer, TargetFormat, Variant, frame_lens_pixels,
};
use lensmap::trace::{LensSelection, Term};
use lensmap_tests::fixtures::compositor;
use lensmap_tests::{assert_clean, gpu, random_compositor_frame};
use rand::SeedableRng;
use rand_pcg::Pcg64;

const SIZE: u32 = 64;

fn largest_difference(a: &[[f32; 4]], b: &[[f32; 4]]) -> f32 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn every_scheme_equals_front_to_back_in_rgba32f() {
    let (gpu, mut renderer, mut rng) = compositor(0xb1e4d);
    let both = [Term::Refraction, Term::Reflection];
    let mut worst = [0f32; 4];
    for layers in 1..=4 {
        for viewpoints in 1..=3 {
            for terms in [&both[..], &[Term::Reflection][..]] {
                let frame = random_compositor_frame(&mut rng, SIZE, layers, viewpoints, terms);
                let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
                let render = |renderer: &mut Renderer, uploaded: &mut _, blend| {
                    renderer
                        .render(
                            &gpu,
                            uploaded,
                            &RenderOptions {
                                compositing: Compositing::Multipass(blend),
                                format: TargetFormat::Rgba32f,
                                host: None,
                            },
                        )
                        .unwrap()
                        .0
                };
                let reference = render(&mut renderer, &mut uploaded, BlendScheme::FrontToBack);
                for (k, blend) in BlendScheme::ALL.into_iter().enumerate() {
                    let image = render(&mut renderer, &mut uploaded, blend);
                    let d = largest_difference(&image.pixels, &reference.pixels);
                    worst[k] = worst[k].max(d);
                    assert!(
                        d <= 1e-5,
                        "{}: n = {layers}, {viewpoints} viewpoint(s), {terms:?}: differs from front-to-back by {d}",
                        blend.name()
                    );
                }
            }
        }
    }
    for (k, blend) in BlendScheme::ALL.into_iter().enumerate() {
        println!(
            "{}: largest |scheme − front-to-back| {:.2e}",
            blend.name(),
            worst[k]
        );
    }
    assert_clean(&gpu);
}

/// All-zero layers (their passes culled or not declared) anywhere in a group, a whole group
/// empty (first, middle or last), and a zero-weight viewpoint: every scheme still equals the
/// front-to-back frame.
#[test]
fn schemes_agree_when_layers_groups_and_viewpoints_are_skipped() {
    let (gpu, mut renderer, mut rng) = compositor(0x5c1f);
    let both = [Term::Refraction, Term::Reflection];
    let base = random_compositor_frame(&mut rng, SIZE, 3, 2, &both);
    let zero = Arc::new(CubeMap::uniform(16, [0.0; 4]));
    let mut cases = Vec::new();
    for (viewpoint, layer) in [(0, 0), (0, 1), (1, 2), (1, 0)] {
        let mut frame = base.clone();
        frame.lenses[0].layers[viewpoint][layer] = zero.clone();
        cases.push((
            format!("layer {layer} of viewpoint {viewpoint} empty"),
            frame,
        ));
    }
    for viewpoint in 0..2 {
        let mut frame = base.clone();
        frame.lenses[0].layers[viewpoint] = vec![zero.clone(); 3];
        cases.push((format!("viewpoint {viewpoint}'s layers all empty"), frame));
    }
    let mut frame = base.clone();
    frame.viewpoint_weights = vec![0.0, 1.0];
    cases.push(("viewpoint 0 weight 0".into(), frame));
    let mut frame = base.clone();
    frame.lenses[0].layers = vec![vec![zero.clone(); 3]; 2];
    cases.push(("every layer empty".into(), frame));
    // Three viewpoints: the middle one's layers all empty, then its weight 0, then the last
    // one's first layer empty.
    let three = random_compositor_frame(&mut rng, SIZE, 3, 3, &both);
    let mut frame = three.clone();
    frame.lenses[0].layers[1] = vec![zero.clone(); 3];
    cases.push(("of three, viewpoint 1's layers all empty".into(), frame));
    let mut frame = three.clone();
    frame.viewpoint_weights = vec![0.4, 0.0, 0.6];
    cases.push(("of three, viewpoint 1 weight 0".into(), frame));
    let mut frame = three;
    frame.lenses[0].layers[2][0] = zero.clone();
    cases.push(("of three, layer 0 of viewpoint 2 empty".into(), frame));
    for (case, frame) in cases {
        let mut uploaded = renderer.upload(&gpu, &frame).unwrap();
        let mut images = Vec::new();
        for blend in BlendScheme::ALL {
            let (image, _) = renderer
                .render(
                    &gpu,
                    &mut uploaded,
                    &RenderOptions {
                        compositing: Compositing::Multipass(blend),
                        format: TargetFormat::Rgba32f,
                        host: None,
                    },
                )
                .unwrap();
            images.push(image);
        }
        for (blend, image) in BlendScheme::ALL.into_iter().zip(&images).skip(1) {
            let d = largest_difference(&image.pixels, &images[0].pixels);
            assert!(d <= 1e-5, "{case}: {} differs by {d}", blend.name());
        }
    }
    assert_clean(&gpu);
}

/// Two lens objects in one frame, partly overlapping (the second, a two-sided mirror with three
/// layers, in front of a two-layer glass sheet): the second object's passes reuse the scratch
/// images with another group count, and where it covers the first its prime starts over. Every
/// scheme equals front-to-back within 1e-5.
#[test]
fn schemes_agree_with_two_overlapping_lens_objects() {
    use lensmap::render::LensFaces;
    let mut runner = lensmap::runner::FrameRunner::new(gpu()).unwrap();
    let mut rng = Pcg64::seed_from_u64(0x2_1e45);
    let both = [Term::Refraction, Term::Reflection];
    let mut frame = random_compositor_frame(&mut rng, SIZE, 2, 2, &both);
    let mirror_frame = random_compositor_frame(&mut rng, SIZE, 3, 2, &[Term::Reflection]);
    let mut mirror = mirror_frame.lenses[0].clone();
    mirror.name = "mirror".into();
    mirror.faces = LensFaces::Both;
    for p in &mut mirror.positions {
        *p += glam::Vec3::new(0.7, 0.3, 0.4);
    }
    frame.lenses.push(mirror);
    // Both objects are in the frame and overlap: each one's coverage from its own frame alone.
    let mut glass_only = frame.clone();
    glass_only.lenses.truncate(1);
    let mut mirror_only = frame.clone();
    mirror_only.lenses.remove(0);
    let coverage = |f| Mask::lens(&frame_lens_pixels(f), LensSelection::All).selected();
    let (all, glass, mirror) = (
        coverage(&frame),
        coverage(&glass_only),
        coverage(&mirror_only),
    );
    assert!(
        glass > 500 && mirror > 500 && all < glass + mirror,
        "the two objects overlap: {glass} + {mirror} pixels, {all} together"
    );
    let mut uploaded = runner.upload(&frame).unwrap();
    let images: Vec<_> = BlendScheme::ALL
        .into_iter()
        .map(|blend| {
            runner
                .timed_renders(
                    &mut uploaded,
                    &RenderOptions {
                        compositing: Compositing::Multipass(blend),
                        format: TargetFormat::Rgba32f,
                        host: None,
                    },
                    1,
                )
                .unwrap()
                .image
        })
        .collect();
    for (blend, image) in BlendScheme::ALL.into_iter().zip(&images).skip(1) {
        let d = largest_difference(&image.pixels, &images[0].pixels);
        assert!(d <= 1e-5, "{}: differs by {d}", blend.name());
    }
    assert_clean(runner.gpu());
}

/// The single pass does not blend: the one check of the pair refuses every other scheme, naming
/// the fix, so no frame, render or plan can be asked for it.
#[test]
fn the_single_pass_refuses_other_schemes() {
    for blend in BlendScheme::ALL.into_iter().skip(1) {
        let error = Compositing::new(Variant::SinglePass, blend)
            .unwrap_err()
            .to_string();
        assert!(
            error.contains(blend.name()) && error.contains("multipass"),
            "{error}"
        );
    }
}

/// The f64 model of each scheme (its own passes and arithmetic order: back-to-front "over" into
/// a cleared scratch image and an add per group, the groups' images summed, the shader's blend)
/// gives the same frame as the paper's scheme to f64 rounding, on glass and mirror with one, two
/// and three viewpoints: the schemes are one closed form.
#[test]
fn the_models_of_every_scheme_agree_to_f64_rounding() {
    use lensmap::render::model::{ModelOptions, render_model};
    let mut rng = Pcg64::seed_from_u64(0x40de1);
    let both = [Term::Refraction, Term::Reflection];
    for (layers, viewpoints, terms) in [
        (3, 2, &both[..]),
        (2, 1, &[Term::Reflection][..]),
        (2, 3, &both[..]),
    ] {
        let frame = random_compositor_frame(&mut rng, 48, layers, viewpoints, terms);
        let model = |blend| {
            render_model(
                &frame,
                &ModelOptions {
                    blend,
                    ..ModelOptions::lavapipe()
                },
            )
        };
        let reference = model(BlendScheme::FrontToBack);
        let lens = reference.lens_mask.iter().filter(|m| **m).count();
        assert!(lens > 200, "the lens covers {lens} pixels");
        for blend in BlendScheme::ALL.into_iter().skip(1) {
            let image = model(blend);
            let largest = image
                .rgba
                .iter()
                .zip(&reference.rgba)
                .flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs()))
                .fold(0.0, f64::max);
            assert!(largest <= 1e-12, "{}: {largest:e}", blend.name());
        }
    }
}
