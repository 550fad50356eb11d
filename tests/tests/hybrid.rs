//! The hybrid runtime end to end against the reference ray tracer: a flat mirror under one
//! distant sphere shell with a projected EM must reproduce the tracer's reflection term nearly
//! exactly; awkward cameras must render without errors or NaN. GPU work runs with validation on.

use lensmap::hybrid::FrameBuilder;
use lensmap::render::BlendScheme;
use lensmap::render::Compositing;
use std::path::PathBuf;

use glam::Vec3;
use lensmap::{
    hybrid::{HybridOptions, HybridScene, LayeredEms},
    layers::projected::ProjectedOptions,
    metrics::{self, Channels, Encoding, Mask},
    render::{Renderer, TargetFormat, Variant},
    runner::{EmSource, FrameOptions, FrameRunner, load_hybrid_scene},
    scene::Scene,
    trace::{LensSelection, TraceOptions, render_reference},
};
use lensmap_tests::render_rgba32f;
use lensmap_tests::{assert_clean, fixtures, gpu};

fn temp_dir(name: &str) -> PathBuf {
    fixtures::temp_dir("hybrid", name)
}

#[test]
fn flat_mirror_under_a_distant_shell_matches_the_reflection_term() {
    let dir = temp_dir("mirror");
    fixtures::write_smooth_sky(&dir.join("sky.exr"));
    let text = r#"
name = "mirror-plane"
[camera]
position = [0.0, 1.2, 2.2]
look_at = [0.0, 0.0, 0.0]
vfov_degrees = 50.0
width = 96
height = 72

[environment]
latlong = { path = "sky.exr" }

[[materials]]
name = "mirror"
mirror = { reflectance = [0.9, 0.85, 0.8] }

[[objects]]
name = "mirror"
material = "mirror"
plane = { size = [2.0, 2.0], subdivisions = 4 }

[[lenses]]
name = "mirror"
objects = ["mirror"]
layers = [{ sphere = 1000.0 }]
"#;
    let scene_path = dir.join("mirror.toml");
    std::fs::write(&scene_path, text).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let camera = scene.camera;
    let ems = EmSource::Projected(ProjectedOptions {
        size: 64,
        supersampling: 2,
    });
    let (hybrid, _) = load_hybrid_scene(scene, &ems.into()).unwrap();
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let reference =
        render_reference(hybrid.trace(), &camera, &TraceOptions::default(), &|_| {}).unwrap();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let options = FrameOptions {
            hybrid: HybridOptions::default(),
            compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
            format: TargetFormat::Rgba32f,
        };
        let frame = runner.frame(&hybrid, &camera, &options).unwrap();
        let stats = frame.stats;
        assert!(
            stats.triangles_out > stats.triangles_in,
            "the mirror is tessellated: {stats:?}"
        );
        // Linear HDR over the pixels the reference sees as all mirror.
        let error = metrics::compare(
            &frame.image.pixels,
            &reference.reflection,
            &Mask::lens(&reference.lens_pixels, LensSelection::All),
            Encoding::Linear,
            Channels::Rgb,
        )
        .unwrap();
        let (count, rms) = (error.pixels, error.rmse);
        assert!(count > 2000, "the mirror covers {count} pixels");
        println!(
            "{variant:?}: RMS {rms:.2e} over {count} mirror pixels (limit {:.2e})",
            1.0 / 255.0
        );
        assert!(rms <= 1.0 / 255.0, "{variant:?}: RMS {rms} > 1/255");
    }
    assert_clean(runner.gpu());
}

#[test]
fn awkward_cameras_render_without_error_or_nan() {
    let scene = fixtures::built_in_scene("glass-sphere", 48, 36, 1);
    let base = scene.camera;
    let hybrid = fixtures::with_projected_ems(scene, 16);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let sphere_centre = Vec3::new(0.0, 1.2, 0.0);
    let cameras = [
        (
            "inside the lens",
            base.with_position(sphere_centre + Vec3::new(0.1, 0.05, 0.2)),
        ),
        ("lens behind the camera", {
            let mut c = base.with_position(Vec3::new(0.0, 1.2, 3.0));
            c.look_at = Vec3::new(0.0, 1.2, 6.0);
            c
        }),
        ("lens covering no pixel", {
            let mut c = base;
            c.look_at = Vec3::new(8.0, 2.5, 5.0);
            c
        }),
    ];
    for (what, camera) in cameras {
        let mut stats = None;
        for variant in [Variant::Multipass, Variant::SinglePass] {
            let options = FrameOptions {
                hybrid: HybridOptions::default(),
                compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
                format: TargetFormat::Rgba16f,
            };
            let frame = runner.frame(&hybrid, &camera, &options).unwrap();
            assert!(
                frame.image.pixels.iter().flatten().all(|v| v.is_finite()),
                "{what}: NaN or Inf"
            );
            stats = Some(frame.stats);
        }
        let stats = stats.unwrap();
        println!(
            "{what}: {} lens triangles traced from {}",
            stats.triangles_out, stats.triangles_in
        );
        if what != "inside the lens" {
            // Nothing of the lens is on screen (or in front): nothing is worth subdividing.
            assert_eq!(
                stats.triangles_out, stats.triangles_in,
                "{what}: off-screen triangles were split"
            );
        }
    }
    assert_clean(runner.gpu());
}

#[test]
fn a_written_bake_reads_back_into_the_same_frame() {
    let scene = fixtures::built_in_scene("glass-sphere", 40, 30, 1);
    let camera = scene.camera;
    let (projected, _) = HybridScene::new(
        scene.clone(),
        LayeredEms::Projected(ProjectedOptions {
            size: 8,
            supersampling: 1,
        })
        .into(),
    )
    .unwrap();
    let dir = temp_dir("bake").join("bake");
    projected.to_bake().write(&dir).unwrap();
    let baked = HybridScene::new(
        scene,
        LayeredEms::Baked(lensmap::layers::Bake::read(&dir).unwrap()).into(),
    )
    .unwrap()
    .0;
    let (a, _) = FrameBuilder::new()
        .frame(&projected, &camera, &HybridOptions::default())
        .unwrap();
    let (b, _) = FrameBuilder::new()
        .frame(&baked, &camera, &HybridOptions::default())
        .unwrap();
    assert_eq!(a.lenses.len(), b.lenses.len());
    for (x, y) in a.lenses.iter().zip(&b.lenses) {
        assert_eq!(x.positions, y.positions);
        assert_eq!(x.terms, y.terms);
        // A projected bake has one viewpoint sample: the same maps, bit for bit.
        assert_eq!(*x.layers[0][0], *y.layers[0][0]);
    }
}

/// The frame runner does exactly what a hand-written frame does: the hybrid frame on the CPU, its
/// upload, the compositor and the box filter from the supersampled framebuffer to pixels, here
/// done step by step with the lower-level API on a second renderer; the images must be equal bit
/// for bit, the counters too.
#[test]
fn the_frame_runner_equals_the_frame_done_by_hand() {
    let scene = fixtures::built_in_scene("glass-sphere", 40, 30, 2);
    let camera = scene.camera;
    let hybrid = fixtures::with_projected_ems(scene, 16);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let by_hand_gpu = gpu();
    let mut renderer = Renderer::new(&by_hand_gpu).unwrap();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let frame_options = FrameOptions {
            hybrid: HybridOptions::with_t(4.0),
            compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
            format: TargetFormat::Rgba32f,
        };
        // Both frames built from scratch (a repeated camera would reuse the cached frame).
        runner.forget_frame();
        let run = runner.frame(&hybrid, &camera, &frame_options).unwrap();
        let (input, stats) = FrameBuilder::new()
            .frame(&hybrid, &camera, &frame_options.hybrid)
            .unwrap();
        let mut uploaded = renderer.upload(&by_hand_gpu, &input).unwrap();
        let full = render_rgba32f(
            &mut renderer,
            &by_hand_gpu,
            &mut uploaded,
            Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        );
        assert_eq!((full.width, full.height), (80, 60), "supersampled 2×2");
        let by_hand = full.box_downsample(2);
        assert_eq!((run.image.width, run.image.height), (40, 30));
        assert!(run.image == by_hand, "{variant:?}: the images differ");
        assert_eq!(run.stats.counters, stats.counters, "{variant:?}");
        assert_eq!(run.stats.triangles_out, stats.triangles_out, "{variant:?}");
    }
    assert_clean(runner.gpu());
    assert_clean(&by_hand_gpu);
}

/// The convex-hull split on mirror-teapot layered by bounce: the frame draws its hull triangles
/// last and counts them. Checked against the frame's own output triangles, plane by plane: each
/// hull triangle faces the eye and has every lens vertex behind its plane; each other triangle
/// that faces the eye and is not degenerate has some lens vertex in front. With the split off,
/// or layered by distance, none is split.
#[test]
fn the_hull_split_draws_triangles_that_cannot_reflect_the_object_last() {
    use lensmap::{hybrid::hull::IN_FRONT_FRACTION, layers::Layering};
    let scene = fixtures::built_in_scene("mirror-teapot", 160, 120, 1);
    let mut hybrid = fixtures::with_projected_ems(scene, 8);
    let camera = hybrid.scene().camera;
    let count = |hybrid: &HybridScene, hull_split: bool| {
        let options = HybridOptions {
            hull_split,
            ..HybridOptions::default()
        };
        let (frame, stats) = FrameBuilder::new()
            .frame(hybrid, &camera, &options)
            .unwrap();
        let total: usize = frame.lenses.iter().map(|l| l.hull_triangles).sum();
        assert_eq!(total, stats.hull_triangles);
        (frame, stats.hull_triangles)
    };
    assert_eq!(count(&hybrid, true).1, 0, "layered by distance");
    for lens in lensmap::index::LensIndex::all(hybrid.lenses().len()) {
        let mut layers = hybrid.lenses()[lens.index()].clone();
        layers.layering = Layering::Bounce;
        hybrid.set_lens_layers(lens, layers);
    }
    assert_eq!(count(&hybrid, false).1, 0, "split off");
    let (frame, split) = count(&hybrid, true);
    let points: Vec<glam::DVec3> = frame
        .lenses
        .iter()
        .flat_map(|l| l.positions.iter().map(|p| p.as_dvec3()))
        .collect();
    let (lo, hi) = points.iter().fold(
        (
            glam::DVec3::splat(f64::INFINITY),
            glam::DVec3::splat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    // The tessellated triangles lie in their input triangles' planes up to f32 rounding of the
    // midpoints: twice the split's tolerance either way.
    let tolerance = 2.0 * IN_FRONT_FRACTION * (hi - lo).length();
    let eye = camera.position.as_dvec3();
    let (mut hull, mut inner) = (0, 0);
    for lens in &frame.lenses {
        let first_hull = lens.triangles.len() - lens.hull_triangles;
        for (t, triangle) in lens.triangles.iter().enumerate() {
            let [a, b, c] = triangle.map(|i| lens.positions[i as usize].as_dvec3());
            let normal = (b - a).cross(c - a).normalize_or_zero();
            let facing = normal.dot(eye - a) > 0.0;
            let most_in_front = points
                .iter()
                .map(|&p| normal.dot(p - a))
                .fold(f64::NEG_INFINITY, f64::max);
            if t >= first_hull {
                hull += 1;
                assert!(facing, "{}: hull triangle {t} faces away", lens.name);
                assert!(
                    most_in_front <= tolerance,
                    "{}: hull triangle {t} has a lens vertex {most_in_front:e} m in front",
                    lens.name
                );
            } else if facing && normal != glam::DVec3::ZERO {
                inner += 1;
                assert!(
                    most_in_front > 0.25 * tolerance,
                    "{}: triangle {t} is on the hull ({most_in_front:e} m) but not split",
                    lens.name
                );
            }
        }
    }
    let lens_points: Vec<Vec3> = hybrid
        .trace()
        .lenses
        .iter()
        .flat_map(|lens| &lens.objects)
        .flat_map(|&o| hybrid.scene().objects[o].mesh.positions.iter().copied())
        .collect();
    let (on, of) = hybrid
        .trace()
        .lenses
        .iter()
        .flat_map(|lens| &lens.objects)
        .fold((0, 0), |(on, of), &o| {
            let mesh = &hybrid.scene().objects[o].mesh;
            let flags = lensmap::hybrid::hull::hull_triangles(mesh, &lens_points);
            (on + flags.iter().filter(|&&h| h).count(), of + flags.len())
        });
    println!(
        "input triangles on the hull: {on} of {of}; in the frame {split} hull triangles, {inner} others facing the eye"
    );
    assert!(hull > 100 && inner > 100, "{hull} split, {inner} not");
    assert!(
        frame
            .lenses
            .iter()
            .any(|l| l.faces == lensmap::render::LensFaces::Both),
        "the teapot is open: back faces drawn, and only facing hull triangles split"
    );
}

/// The first four glass classes as a list.
fn four_listed() -> lensmap::trace::classes::ClassSet {
    lensmap::trace::classes::ClassSet::parse("R,TT,TRT,TRRT").unwrap()
}

/// The mean of the channels' sum over `mask` of `pixels` (RGBA) or of `radiance` (RGB).
fn mean_over(mask: &Mask, values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, v) in values.enumerate() {
        if mask.contains(i) {
            sum += v;
            count += 1;
        }
    }
    assert!(count > 0, "an empty mask has no mean");
    sum / count as f64
}

/// Path classes in the hybrid frame, on a glass ball (absorbing, so every chord counts) under a
/// smooth sky on one distant shell, whose projected EM is nearly what the tracer sees: the frame
/// of 4 classes against the reference tracer's sum of the same 4 classes (a second algorithm:
/// per pixel, not per vertex) as close as the greedy frame is to the greedy reference, and its
/// mean lens radiance within 2 % of the full ray tree's (the issue's goal) where the greedy
/// frame's is more than 5 % short (measured: 0.998 and 0.911; RMS 3.22e-3 and 3.17e-3 against
/// their own references, on Mesa 22.3's lavapipe). The class frame has one term per class,
/// composited by the multipass variant in every blending scheme alike and by the single pass
/// while its varyings suffice, and the GPU tracer's frame of it is the CPU's.
#[test]
fn path_classes_bring_the_frame_to_the_full_ray_tree() {
    use lensmap::hybrid::ShadingTerms;
    use lensmap::trace::{PathModel, Term, classes::ClassSet};
    let dir = temp_dir("classes");
    fixtures::write_smooth_sky(&dir.join("sky.exr"));
    let text = r#"
name = "glass-ball-sky"
[camera]
position = [0.0, 0.6, 3.2]
look_at = [0.0, 0.0, 0.0]
vfov_degrees = 45.0
width = 80
height = 60
supersampling = 2

[environment]
latlong = { path = "sky.exr" }

[[materials]]
name = "glass"
glass = { ior = 1.5, absorption = [0.8, 0.9, 1.0] }

[[objects]]
name = "ball"
material = "glass"
sphere = { radius = 1.0, segments = 48, rings = 24 }

[[lenses]]
name = "ball"
objects = ["ball"]
layers = [{ sphere = 1000.0 }]
"#;
    let scene_path = dir.join("ball.toml");
    std::fs::write(&scene_path, text).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let camera = scene.camera;
    let ems = EmSource::Projected(ProjectedOptions {
        size: 64,
        supersampling: 2,
    });
    let (hybrid, _) = load_hybrid_scene(scene, &ems.clone().into()).unwrap();
    let reference = |model| {
        let options = TraceOptions {
            model,
            ..TraceOptions::default()
        };
        render_reference(hybrid.trace(), &camera, &options, &|_| {}).unwrap()
    };
    let four = ClassSet::First(4);
    let (greedy_ref, classes_ref, full_ref) = (
        reference(PathModel::Greedy),
        reference(PathModel::Classes(four)),
        reference(PathModel::Full),
    );
    let mask = Mask::lens(&full_ref.lens_pixels, LensSelection::All);
    let mean_ref = |r: &lensmap::trace::ReferenceImage| {
        mean_over(&mask, r.radiance.iter().map(|v| f64::from(v.element_sum())))
    };
    let full_mean = mean_ref(&full_ref);

    let mut runner = FrameRunner::new(gpu()).unwrap();
    let limits = runner.single_pass_limits();
    let mut frame_of = |terms, blend| {
        let options = FrameOptions {
            hybrid: HybridOptions {
                terms,
                ..HybridOptions::default()
            },
            compositing: Compositing::Multipass(blend),
            format: TargetFormat::Rgba32f,
        };
        runner.frame(&hybrid, &camera, &options).unwrap()
    };
    let rms = |frame: &lensmap::runner::HybridFrame, r: &lensmap::trace::ReferenceImage| {
        metrics::compare(
            &frame.image.pixels,
            &r.radiance,
            &mask,
            Encoding::Linear,
            Channels::Rgb,
        )
        .unwrap()
        .rmse
    };
    let mean = |frame: &lensmap::runner::HybridFrame| {
        mean_over(
            &mask,
            frame
                .image
                .pixels
                .iter()
                .map(|p| f64::from(p[0] + p[1] + p[2])),
        )
    };
    let greedy = frame_of(ShadingTerms::Greedy, BlendScheme::FrontToBack);
    let (greedy_rms, greedy_ratio) = (rms(&greedy, &greedy_ref), mean(&greedy) / full_mean);
    let mut class_rms = Vec::new();
    for blend in BlendScheme::ALL {
        let frame = frame_of(ShadingTerms::Classes(four), blend);
        let ratio = mean(&frame) / full_mean;
        let own = rms(&frame, &classes_ref);
        println!(
            "{}: 4 classes RMS {own:.2e} against their reference, mean lens radiance {ratio:.4} of the full tree's ({} vertices; greedy {} vertices, RMS {greedy_rms:.2e}, {greedy_ratio:.4})",
            blend.name(),
            if frame.stats.reused {
                "the same".to_string()
            } else {
                frame.stats.vertices_traced.to_string()
            },
            greedy.stats.vertices_traced,
        );
        assert!(
            (ratio - 1.0).abs() <= 0.02,
            "{}: 4 classes keep {ratio} of the full tree's light",
            blend.name()
        );
        assert!(
            own <= 1.25 * greedy_rms,
            "{}: 4 classes RMS {own} against their reference, greedy {greedy_rms}",
            blend.name()
        );
        class_rms.push(own);
    }
    assert!(
        greedy_ratio < 0.95,
        "the greedy frame keeps {greedy_ratio} of the light: the scene does not tell classes from greedy"
    );
    println!(
        "reference: 4 classes keep {:.4}, greedy {:.4} of the full tree's mean lens radiance",
        mean_ref(&classes_ref) / full_mean,
        mean_ref(&greedy_ref) / full_mean
    );

    // The frame's terms: one per class, in the set's order; the single pass asked for them
    // composites them by the multipass variant front-to-back, the same image.
    let mut builder = FrameBuilder::new();
    let options = HybridOptions {
        terms: ShadingTerms::Classes(four),
        ..HybridOptions::default()
    };
    let (input, stats) = builder.frame(&hybrid, &camera, &options).unwrap();
    let names: Vec<String> = input.lenses[0]
        .terms
        .iter()
        .map(|t| t.term.name())
        .collect();
    assert_eq!(names, ["R", "TT", "TRT", "TRRT"]);
    assert!(
        input.lenses[0]
            .terms
            .iter()
            .all(|t| matches!(t.term, Term::Class(_)))
    );
    assert_eq!(stats.class_terms, 4);
    // Four classes of one layer carry 4·(1 + 1) varyings: the single pass composites them, the
    // same light as the multipass frame (the compositor's tests hold both to the f64 model).
    assert_eq!(stats.class_slots, 8);
    let single = FrameOptions {
        hybrid: options,
        compositing: Compositing::SinglePass,
        format: TargetFormat::Rgba32f,
    };
    assert_eq!(
        single.compositing_for(&stats, &limits),
        Compositing::SinglePass
    );
    let by_multipass = frame_of(ShadingTerms::Classes(four), BlendScheme::FrontToBack);
    let by_single = runner.frame(&hybrid, &camera, &single).unwrap();
    let (single_mean, multipass_mean) = (mean(&by_single), mean(&by_multipass));
    assert!(
        (single_mean / multipass_mean - 1.0).abs() <= 1e-4,
        "4 classes: single pass mean lens radiance {single_mean}, multipass {multipass_mean}"
    );
    let own = rms(&by_single, &classes_ref);
    assert!(
        own <= 1.25 * greedy_rms,
        "single pass: 4 classes RMS {own} against their reference, greedy {greedy_rms}"
    );
    // Nine classes need 18 varyings, past the 16 every device has: the single pass asked for
    // them composites them by the multipass variant front-to-back, the same image.
    let nine = HybridOptions {
        terms: ShadingTerms::Classes(ClassSet::First(9)),
        ..options
    };
    let (_, stats) = builder.frame(&hybrid, &camera, &nine).unwrap();
    assert_eq!(stats.class_slots, 18);
    let single = FrameOptions {
        hybrid: nine,
        ..single
    };
    assert_eq!(
        single.compositing_for(&stats, &limits),
        Compositing::Multipass(BlendScheme::FrontToBack)
    );
    let by_single = runner.frame(&hybrid, &camera, &single).unwrap();
    let multipass = FrameOptions {
        compositing: Compositing::Multipass(BlendScheme::FrontToBack),
        ..single
    };
    let by_multipass = runner.frame(&hybrid, &camera, &multipass).unwrap();
    assert_eq!(by_single.image.pixels, by_multipass.image.pixels);

    // Set in the scene file, the classes shade the frame unless the options say greedy; a
    // class the file misspells is one line naming the field.
    let with_terms = text.replace(
        "objects = [\"ball\"]\n",
        "objects = [\"ball\"]\nterms = [\"R\", \"TT\", \"TRT\", \"TRRT\"]\n",
    );
    let scene = Scene::from_toml_str(&with_terms, &scene_path).unwrap();
    assert_eq!(scene.lenses[0].terms, Some(four_listed()));
    let (scene_hybrid, _) = load_hybrid_scene(scene, &ems.into()).unwrap();
    let term_names = |options: &HybridOptions| -> Vec<String> {
        let (input, _) = FrameBuilder::new()
            .frame(&scene_hybrid, &camera, options)
            .unwrap();
        input.lenses[0]
            .terms
            .iter()
            .map(|t| t.term.name())
            .collect()
    };
    assert_eq!(
        term_names(&HybridOptions::default()),
        ["R", "TT", "TRT", "TRRT"]
    );
    let greedy_options = HybridOptions {
        terms: ShadingTerms::Greedy,
        ..HybridOptions::default()
    };
    assert_eq!(term_names(&greedy_options), ["T", "R"]);
    let misspelt = text.replace(
        "objects = [\"ball\"]\n",
        "objects = [\"ball\"]\nterms = \"R,TX\"\n",
    );
    let error = Scene::from_toml_str(&misspelt, &scene_path)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("lenses[0].terms") && error.contains("TX"),
        "{error}"
    );
    // The GPU tracer traces the classes too: its frame, left on the device or read back, has
    // the CPU's terms, vertices within 10 % and mean lens radiance within 1 %. In f64 (devices
    // with shaderFloat64) it is as close to the classes' reference as the CPU frame, within
    // 1 %; in f32 (the default) within 1.3 times (measured 4.01e-3 against 3.22e-3, where the
    // greedy terms' f32 frame is 3.51e-3 against 3.17e-3: the classes' longer paths gather more
    // of f32's rounding, 64 % of glass-sphere's vertices within 1e-4 of f64 against the greedy
    // terms' 87 %).
    use lensmap::hybrid::{VertexTracer, paths::VertexPrecision};
    let on = |tracer, gpu_precision| FrameOptions {
        hybrid: HybridOptions {
            tracer,
            gpu_precision,
            ..options
        },
        compositing: Compositing::Multipass(BlendScheme::FrontToBack),
        format: TargetFormat::Rgba32f,
    };
    runner.forget_frame();
    let cpu = runner
        .frame(
            &hybrid,
            &camera,
            &on(VertexTracer::Cpu, VertexPrecision::F32),
        )
        .unwrap();
    let cpu_rms = rms(&cpu, &classes_ref);
    let mut runs = vec![
        (VertexPrecision::F32, false, 1.3),
        (VertexPrecision::F32, true, 1.3),
    ];
    if runner.gpu().shader_float64() {
        runs.push((VertexPrecision::F64, false, 1.01));
    }
    for (precision, read_back, bound) in runs {
        runner.forget_frame();
        runner.read_back_gpu_meshes(read_back);
        let frame = runner
            .frame(&hybrid, &camera, &on(VertexTracer::Gpu, precision))
            .unwrap();
        let (g, c) = (&frame.stats, &cpu.stats);
        let own = rms(&frame, &classes_ref);
        let ratio = mean(&frame) / mean(&cpu);
        println!(
            "GPU tracer in {precision:?} (read back {read_back}): 4 classes RMS {own:.3e} against their reference (CPU {cpu_rms:.3e}), mean lens radiance {ratio:.5} of the CPU frame's, vertices {} / {}",
            g.vertices_traced, c.vertices_traced
        );
        assert!(g.traced_on_gpu && !c.traced_on_gpu);
        assert_eq!((g.class_terms, g.class_slots), (4, 8));
        let vertices = g.vertices_traced as f64 / c.vertices_traced as f64;
        assert!((0.9..=1.1).contains(&vertices), "{g:?} {c:?}");
        assert!((ratio - 1.0).abs() <= 0.01, "mean lens radiance {ratio}");
        assert!(own <= bound * cpu_rms, "{own} against the CPU's {cpu_rms}");
        assert!(frame.image.pixels.iter().flatten().all(|v| v.is_finite()));
    }
    runner.read_back_gpu_meshes(false);
    // The CPU tracer traces classes in f64 only: f32 is one line naming the option.
    let in_f32 = HybridOptions {
        tracer: lensmap::hybrid::VertexTracer::Cpu,
        precision: lensmap::hybrid::paths::VertexPrecision::F32,
        ..options
    };
    let error = in_f32.validate().unwrap_err().to_string();
    assert!(error.contains("terms") && error.contains("f64"), "{error}");
    assert_clean(runner.gpu());
}
