//! The compositor's plans checked without a GPU: pass counts per scheme derived by hand, and every
//! plan `lensmap passes` prints against its golden text.

use super::*;
use crate::render::LensFaces;

/// Options of a plan ending in a readback (`variant` and `blend` a pair the plan takes).
fn readback(variant: Variant, blend: BlendScheme, format: TargetFormat) -> PlanOptions {
    PlanOptions {
        compositing: Compositing::new(variant, blend).expect("a compositing"),
        format,
        output: Output::Readback,
        single_pass: SinglePassLimits::COMPILED,
    }
}

/// The compiled plan of `shape` with `options`.
fn compiled(shape: &FrameShape, options: &PlanOptions) -> FramePlan {
    frame_graph(shape, options).unwrap().0.compile().unwrap()
}

fn plan(layers: usize, viewpoints: usize, terms: &[Term], variant: Variant) -> FramePlan {
    let shape = FrameShape::synthetic(64, 64, layers, viewpoints, terms);
    compiled(
        &shape,
        &readback(variant, BlendScheme::FrontToBack, TargetFormat::Rgba32f),
    )
}

const BOTH: [Term; 2] = [Term::Refraction, Term::Reflection];

/// The first `count` path classes of glass (R, TT, TRT, TRRT, …) as terms.
fn classes(count: usize) -> Vec<Term> {
    (0..count)
        .map(|i| {
            Term::Class(crate::trace::classes::ClassTerm {
                class: crate::trace::PathClass::glass(i).expect("a class"),
                greedy_tail: false,
            })
        })
        .collect()
}

#[test]
fn two_viewpoints_two_terms_is_the_papers_4n_passes_and_three_alpha_clears() {
    for n in 1..=4 {
        let p = plan(n, 2, &BOTH, Variant::Multipass);
        assert_eq!(
            (
                p.count(PassCategory::Prime),
                p.count(PassCategory::Layer),
                p.count(PassCategory::AlphaClear)
            ),
            (1, 4 * n, 3),
            "{p}"
        );
        // One rendering instance holds the environment and every lens pass: no barriers
        // between blending passes.
        assert_eq!(p.rendering_instances(), 1, "{p}");
    }
}

/// Three viewpoint samples (inside a spherical triangle of a 2D view space): 2·3·n layer passes
/// in six groups, five alpha clears between them, still one rendering instance.
#[test]
fn three_viewpoints_two_terms_is_6n_passes_and_five_alpha_clears() {
    for n in 1..=4 {
        let p = plan(n, 3, &BOTH, Variant::Multipass);
        assert_eq!(
            (
                p.count(PassCategory::Prime),
                p.count(PassCategory::Layer),
                p.count(PassCategory::AlphaClear)
            ),
            (1, 6 * n, 5),
            "{p}"
        );
        assert_eq!(p.rendering_instances(), 1, "{p}");
        // The groups in order: v0 T, v0 R, v1 T, v1 R, v2 T, v2 R.
        let clears: Vec<&str> = p
            .steps
            .iter()
            .filter(|s| s.pass.category == PassCategory::AlphaClear)
            .map(|s| s.pass.name.as_str())
            .collect();
        assert_eq!(
            clears,
            [
                "lens/v0/R/alpha-clear",
                "lens/v1/T/alpha-clear",
                "lens/v1/R/alpha-clear",
                "lens/v2/T/alpha-clear",
                "lens/v2/R/alpha-clear"
            ]
        );
    }
}

#[test]
fn one_viewpoint_is_2n_passes_and_one_clear() {
    for n in 1..=4 {
        let p = plan(n, 1, &BOTH, Variant::Multipass);
        assert_eq!(
            (
                p.count(PassCategory::Prime),
                p.count(PassCategory::Layer),
                p.count(PassCategory::AlphaClear)
            ),
            (1, 2 * n, 1)
        );
    }
}

#[test]
fn a_mirror_at_a_sample_is_n_passes_and_no_clear() {
    for n in 1..=4 {
        let p = plan(n, 1, &[Term::Reflection], Variant::Multipass);
        assert_eq!(
            (
                p.count(PassCategory::Prime),
                p.count(PassCategory::Layer),
                p.count(PassCategory::AlphaClear)
            ),
            (1, n, 0)
        );
    }
}

#[test]
fn single_pass_is_one_lens_draw() {
    for viewpoints in 1..=3 {
        let p = plan(3, viewpoints, &BOTH, Variant::SinglePass);
        assert_eq!(p.count(PassCategory::SinglePass), 1);
        assert_eq!(p.draws(PassCategory::SinglePass), 1);
        assert_eq!(
            p.count(PassCategory::Layer)
                + p.count(PassCategory::AlphaClear)
                + p.count(PassCategory::Prime),
            0
        );
    }
}

#[test]
fn a_zero_weight_viewpoint_and_empty_layers_are_skipped() {
    let mut shape = FrameShape::synthetic(64, 64, 3, 2, &BOTH);
    shape.viewpoint_weights = vec![1.0, 0.0];
    shape.lenses[0].empty[0][1] = true;
    let p = compiled(
        &shape,
        &readback(
            Variant::Multipass,
            BlendScheme::FrontToBack,
            TargetFormat::Rgba8,
        ),
    );
    // One viewpoint × two terms × (3 − 1 empty) layers, one clear between the two groups.
    assert_eq!(
        (
            p.count(PassCategory::Layer),
            p.count(PassCategory::AlphaClear)
        ),
        (4, 1),
        "{p}"
    );
    assert_eq!(p.culled.len(), 2, "{p}");
    // Three viewpoints, the middle one at weight 0 (the camera on an edge of a spherical
    // triangle): its groups are not declared, the other two keep theirs.
    let mut shape = FrameShape::synthetic(64, 64, 2, 3, &BOTH);
    shape.viewpoint_weights = vec![0.5, 0.0, 0.5];
    let p = compiled(
        &shape,
        &readback(
            Variant::Multipass,
            BlendScheme::FrontToBack,
            TargetFormat::Rgba8,
        ),
    );
    assert_eq!(
        (
            p.count(PassCategory::Layer),
            p.count(PassCategory::AlphaClear)
        ),
        (8, 3),
        "{p}"
    );
    assert!(p.steps.iter().all(|s| !s.pass.name.contains("/v1/")), "{p}");
}

#[test]
fn a_lens_with_both_faces_culls_nothing_in_any_pass() {
    for variant in [Variant::Multipass, Variant::SinglePass] {
        for faces in [LensFaces::Front, LensFaces::Both] {
            let mut shape = FrameShape::synthetic(64, 64, 2, 2, &BOTH);
            shape.lenses[0].faces = faces;
            let options = readback(variant, BlendScheme::FrontToBack, TargetFormat::Rgba8);
            let (graph, _) = frame_graph(&shape, &options).unwrap();
            let lens_culls: Vec<(String, Cull)> = graph
                .passes()
                .iter()
                .filter_map(|pass| match &pass.kind {
                    PassKind::Draw { cull, .. } if pass.category != PassCategory::Environment => {
                        Some((pass.name.clone(), *cull))
                    }
                    _ => None,
                })
                .collect();
            let expected = match faces {
                LensFaces::Front => Cull::Back,
                LensFaces::Both => Cull::None,
            };
            assert!(!lens_culls.is_empty());
            assert!(
                lens_culls.iter().all(|(_, cull)| *cull == expected),
                "{variant:?} {faces:?}: {lens_culls:?}"
            );
        }
    }
}

fn plan_blended(layers: usize, viewpoints: usize, terms: &[Term], blend: BlendScheme) -> FramePlan {
    let shape = FrameShape::synthetic(64, 64, layers, viewpoints, terms);
    compiled(
        &shape,
        &readback(Variant::Multipass, blend, TargetFormat::Rgba32f),
    )
}

/// Each scheme's pass, barrier and rendering-instance counts for n = 1…4 layers and G =
/// viewpoints × terms groups, derived by hand from the scheme's description.
#[test]
fn each_scheme_has_the_passes_it_is_described_with() {
    for n in 1..=4 {
        for viewpoints in 1..=3 {
            let (three, four) = (classes(3), classes(4));
            for terms in [&BOTH[..], &[Term::Reflection][..], &three[..], &four[..]] {
                let g = viewpoints * terms.len();
                let count = |p: &FramePlan| {
                    (
                        p.count(PassCategory::Layer),
                        p.count(PassCategory::AlphaClear),
                        p.count(PassCategory::ScratchClear),
                        p.count(PassCategory::GroupSum),
                    )
                };
                let front = plan_blended(n, viewpoints, terms, BlendScheme::FrontToBack);
                assert_eq!(count(&front), (g * n, g - 1, 0, 0), "{front}");
                assert_eq!((front.rendering_instances(), front.barrier_count()), (1, 3));
                // Per group a clear of the scratch image, its layers and an accumulate pass.
                let back = plan_blended(n, viewpoints, terms, BlendScheme::BackToFront);
                assert_eq!(count(&back), (g * n, 0, g, g), "{back}");
                assert_eq!(back.rendering_instances(), 1 + 2 * g, "{back}");
                // Per group its own cleared image; one sum of all of them.
                let targets = plan_blended(n, viewpoints, terms, BlendScheme::GroupTargets);
                assert_eq!(count(&targets), (g * n, 0, g, 1), "{targets}");
                assert_eq!(targets.rendering_instances(), 2 + g, "{targets}");
                // One rendering instance per layer pass, alternating images (a lone layer
                // pass renders straight into the framebuffer, in the prime's instance).
                let shader = plan_blended(n, viewpoints, terms, BlendScheme::Programmable);
                assert_eq!(count(&shader), (g * n, 0, 0, 0), "{shader}");
                let instances = if g * n == 1 { 1 } else { 1 + g * n };
                assert_eq!(shader.rendering_instances(), instances, "{shader}");
                // No pass samples the image it renders into.
                for step in &shader.steps {
                    if let PassKind::Draw {
                        colour, sampled, ..
                    } = &step.pass.kind
                    {
                        assert!(!sampled.contains(&colour.image), "{shader}");
                    }
                }
            }
        }
    }
}

/// Back-to-front composites each group's layers farthest first; the others nearest first.
#[test]
fn back_to_front_reverses_the_layer_order() {
    let layer_order = |blend| -> Vec<String> {
        plan_blended(3, 1, &[Term::Reflection], blend)
            .steps
            .iter()
            .filter(|s| s.pass.category == PassCategory::Layer)
            .map(|s| s.pass.name.rsplit('/').next().unwrap_or("").to_owned())
            .collect()
    };
    assert_eq!(
        layer_order(BlendScheme::BackToFront),
        ["layer2", "layer1", "layer0"]
    );
    for blend in [
        BlendScheme::FrontToBack,
        BlendScheme::GroupTargets,
        BlendScheme::Programmable,
    ] {
        assert_eq!(
            layer_order(blend),
            ["layer0", "layer1", "layer2"],
            "{blend:?}"
        );
    }
}

/// The programmable scheme resets α (the alpha clear) exactly where a group begins, and a
/// last group whose layers are all zero still ends in an alpha clear.
#[test]
fn programmable_resets_alpha_at_group_boundaries() {
    let mut shape = FrameShape::synthetic(64, 64, 2, 2, &BOTH);
    let resets = |shape: &FrameShape| -> Vec<(String, bool)> {
        let plan = compiled(
            shape,
            &readback(
                Variant::Multipass,
                BlendScheme::Programmable,
                TargetFormat::Rgba32f,
            ),
        );
        plan.steps
            .iter()
            .filter_map(|s| match &s.pass.kind {
                PassKind::Draw { draws, .. } => draws.first().and_then(|d| match d {
                    Draw::ProgrammableLayer { reset_alpha, .. } => {
                        Some((s.pass.name.clone(), *reset_alpha))
                    }
                    Draw::LensZero { .. } if s.pass.category == PassCategory::AlphaClear => {
                        Some((s.pass.name.clone(), true))
                    }
                    _ => None,
                }),
                _ => None,
            })
            .collect()
    };
    let all = resets(&shape);
    let reset: Vec<&str> = all
        .iter()
        .filter(|(_, r)| *r)
        .map(|(n, _)| n.as_str())
        .collect();
    assert_eq!(
        reset,
        ["lens/v0/R/layer0", "lens/v1/T/layer0", "lens/v1/R/layer0"],
        "{all:?}"
    );
    // Viewpoint 1's layers all zero: its two groups draw nothing, and α still ends cleared.
    shape.lenses[0].empty[1] = vec![true, true];
    let all = resets(&shape);
    assert_eq!(
        all.last().map(|(n, _)| n.as_str()),
        Some("lens/v1/T/alpha-clear"),
        "{all:?}"
    );
}

/// The plans `lensmap passes` prints (its defaults: 640×480, RGBA8), n = 1…4, for one, two and
/// three viewpoints, a glass (both terms) and a mirror (reflection only) lens, both variants and
/// every blending scheme, as
/// text against the golden files in `render/golden/` (read and checked by hand when written;
/// the counts above check the same plans independently). Trailing spaces are not compared.
/// `LENSMAP_BLESS=1` rewrites the files after a deliberate change, to be read before
/// committing.
#[test]
fn plans_match_the_golden_text() {
    let mut golden = Golden::new();
    let compositings = [
        (Variant::Multipass, BlendScheme::FrontToBack),
        (Variant::SinglePass, BlendScheme::FrontToBack),
        (Variant::Multipass, BlendScheme::BackToFront),
        (Variant::Multipass, BlendScheme::GroupTargets),
        (Variant::Multipass, BlendScheme::Programmable),
    ];
    for (variant, blend) in compositings {
        for viewpoints in 1..=3 {
            for (material, terms) in [("glass", &BOTH[..]), ("mirror", &[Term::Reflection][..])] {
                let mut text = String::new();
                for n in 1..=4 {
                    let shape = FrameShape::synthetic(640, 480, n, viewpoints, terms);
                    let plan = compiled(&shape, &readback(variant, blend, TargetFormat::Rgba8));
                    text.push_str(&format!("# n = {n}\n{plan}"));
                }
                // The paper's scheme keeps its files' names; the others add theirs.
                let scheme = match blend {
                    BlendScheme::FrontToBack => String::new(),
                    other => format!("-{}", other.name()),
                };
                let name = format!(
                    "{}{scheme}-{viewpoints}-viewpoint-{material}.txt",
                    variant.name()
                );
                golden.check(&name, &text);
            }
        }
    }
    // Path classes: 3 and 4 terms (R, TT, TRT and TRRT), each a group of V·n layer passes, at
    // two viewpoint samples in every multipass scheme (`lensmap passes --terms 3`).
    for blend in BlendScheme::ALL {
        for count in [3, 4] {
            let mut text = String::new();
            for n in 1..=4 {
                let shape = FrameShape::synthetic(640, 480, n, 2, &classes(count));
                let plan = compiled(
                    &shape,
                    &readback(Variant::Multipass, blend, TargetFormat::Rgba8),
                );
                text.push_str(&format!("# n = {n}\n{plan}"));
            }
            golden.check(
                &format!("multipass-{}-2-viewpoint-{count}-classes.txt", blend.name()),
                &text,
            );
        }
    }
    // The single pass of 3 and 4 classes, for every n whose K·(n + 1) varyings fit its 16.
    for count in [3, 4] {
        let mut text = String::new();
        for n in 1..=(16 / count - 1) {
            let shape = FrameShape::synthetic(640, 480, n, 2, &classes(count));
            let plan = compiled(
                &shape,
                &readback(
                    Variant::SinglePass,
                    BlendScheme::FrontToBack,
                    TargetFormat::Rgba8,
                ),
            );
            text.push_str(&format!("# n = {n}\n{plan}"));
        }
        golden.check(
            &format!(
                "{}-2-viewpoint-{count}-classes.txt",
                Variant::SinglePass.name()
            ),
            &text,
        );
    }
    golden.assert_matched();
}

/// The single pass of path classes carries K·(n + 1) varyings: within the shader's 16 it is one
/// draw (1, 2 and 4 classes at n = 2; 4 at n = 3), past them (6 classes at n = 2, 4 at n = 4)
/// it is refused naming the count and the multipass variant, whose plan of the same frame holds.
#[test]
fn the_single_pass_takes_path_classes_within_its_varyings() {
    for (count, layers) in [(1, 2), (2, 2), (4, 2), (4, 3)] {
        let p = plan(layers, 2, &classes(count), Variant::SinglePass);
        assert_eq!(p.count(PassCategory::Layer), 0, "{p}");
        assert_eq!(
            p.count(PassCategory::SinglePass),
            1,
            "{count} classes, n = {layers}: {p}"
        );
    }
    for (count, layers) in [(6, 2), (4, 4)] {
        let shape = FrameShape::synthetic(64, 64, layers, 2, &classes(count));
        let error = frame_graph(
            &shape,
            &readback(
                Variant::SinglePass,
                BlendScheme::FrontToBack,
                TargetFormat::Rgba8,
            ),
        )
        .unwrap_err();
        let slots = count * (layers + 1);
        assert!(
            error.to_string().contains(&format!(
                "sums {count} path-class terms over {layers} layers: the single-pass variant carries {count}·({layers} + 1) = {slots} varyings for them, at most 16 as its shader is compiled: use the multipass variant"
            )),
            "{error}"
        );
        let p = plan(layers, 2, &classes(count), Variant::Multipass);
        assert_eq!(p.count(PassCategory::Layer), layers * 2 * count, "{p}");
    }
}

/// The plans `lensmap passes --gpu-parts N` prints (640×480, RGBA8, three layers, two
/// viewpoints, glass): a lens object made of N parts tessellated on the GPU at the default depth
/// cap, whose every dispatch, transfer and barrier opens the frame, against the golden files
/// `gpu-parts-*.txt` (what a GPU frame records is checked against the same plan by
/// `tests/tests/gpu_tracer.rs`).
#[test]
fn gpu_frame_plans_match_the_golden_text() {
    use crate::hybrid::gpu::{Texgen, planned_part};
    let levels = crate::hybrid::tessellate::DEFAULT_MAX_DEPTH + 1;
    let mut golden = Golden::new();
    for (parts, variant) in [(1, Variant::Multipass), (2, Variant::SinglePass)] {
        let mut shape = FrameShape::synthetic(640, 480, 3, 2, &BOTH);
        shape.lenses[0].parts = (0..parts)
            .map(|object| {
                planned_part(
                    &format!("object{object} output0"),
                    object,
                    levels,
                    Texgen::On,
                )
            })
            .collect();
        let plan = compiled(
            &shape,
            &readback(variant, BlendScheme::FrontToBack, TargetFormat::Rgba8),
        );
        // Every pass of each part's work is a step of the plan, in the work's order.
        for (index, part) in shape.lenses[0].parts.iter().enumerate() {
            let work = part.work.as_ref().expect("a planned work");
            let prefix = format!("lens/part{index}/");
            let steps: Vec<&str> = plan
                .steps
                .iter()
                .filter_map(|s| s.pass.name.strip_prefix(&prefix))
                .collect();
            let passes: Vec<&str> = work.passes.iter().map(|p| p.name.as_str()).collect();
            assert_eq!(steps, passes, "{plan}");
        }
        golden.check(
            &format!("gpu-parts-{parts}-{}-glass.txt", variant.name()),
            &plan.to_string(),
        );
    }
    golden.assert_matched();
}

/// Plans against their golden text in `render/golden/`. Trailing spaces are not compared;
/// `LENSMAP_BLESS=1` rewrites the files.
struct Golden {
    dir: std::path::PathBuf,
    bless: bool,
    mismatches: Vec<String>,
}

impl Golden {
    fn new() -> Golden {
        Golden {
            dir: std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render/golden"),
            bless: std::env::var("LENSMAP_BLESS").is_ok_and(|v| v == "1"),
            mismatches: Vec::new(),
        }
    }

    fn trimmed(text: &str) -> String {
        text.lines()
            .map(|l| format!("{}\n", l.trim_end()))
            .collect()
    }

    fn check(&mut self, name: &str, text: &str) {
        let path = self.dir.join(name);
        if self.bless {
            std::fs::create_dir_all(&self.dir).unwrap();
            std::fs::write(&path, Self::trimmed(text)).unwrap();
        }
        let golden = std::fs::read_to_string(&path).unwrap_or_default();
        if Self::trimmed(&golden) != Self::trimmed(text) {
            self.mismatches.push(format!("{name}:\n{text}"));
        }
    }

    fn assert_matched(&self) {
        assert!(
            self.mismatches.is_empty(),
            "plans differ from their golden text (LENSMAP_BLESS=1 rewrites them):\n{}",
            self.mismatches.join("\n")
        );
    }
}

/// A device that interpolates fewer varyings than the shader is compiled for lowers the single
/// pass's layer limit: the plan refuses a lens past it, naming the device limit, and the
/// multipass plan of the same frame is unaffected.
#[test]
fn the_single_pass_plan_follows_the_devices_limits() {
    let limits = SinglePassLimits {
        max_layers: 2,
        layers_bound: crate::render::LimitSource::Device {
            limit: "maxFragmentInputComponents",
            value: 24,
        },
        ..SinglePassLimits::COMPILED
    };
    let shape = FrameShape::synthetic(64, 64, 3, 3, &BOTH);
    let options = |variant| PlanOptions {
        single_pass: limits,
        ..readback(variant, BlendScheme::FrontToBack, TargetFormat::Rgba8)
    };
    let error = frame_graph(&shape, &options(Variant::SinglePass)).unwrap_err();
    assert!(
        error
            .to_string()
            .contains("at most 2 on this device (maxFragmentInputComponents = 24)"),
        "{error}"
    );
    assert!(frame_graph(&shape, &options(Variant::Multipass)).is_ok());
    let two_layers = FrameShape::synthetic(64, 64, 2, 3, &BOTH);
    assert!(frame_graph(&two_layers, &options(Variant::SinglePass)).is_ok());
}

#[test]
fn shapes_alike_but_for_their_positive_weights_have_one_plan() {
    // The renderer keeps compiled plans by `plans_alike`: it must hold exactly when the plans
    // are equal, for every variant and blending scheme.
    let mut a = FrameShape::synthetic(64, 64, 2, 3, &BOTH);
    a.viewpoint_weights = vec![0.5, 0.25, 0.25];
    let mut b = a.clone();
    b.viewpoint_weights = vec![0.2, 0.7, 0.1];
    let mut c = a.clone();
    c.viewpoint_weights = vec![0.5, 0.0, 0.5];
    let mut d = a.clone();
    d.lenses[0].empty[1][0] = true;
    assert!(a.plans_alike(&b) && b.plans_alike(&a));
    assert!(!a.plans_alike(&c) && !a.plans_alike(&d));
    for (variant, blend) in [
        (Variant::SinglePass, BlendScheme::FrontToBack),
        (Variant::Multipass, BlendScheme::FrontToBack),
        (Variant::Multipass, BlendScheme::BackToFront),
    ] {
        let options = readback(variant, blend, TargetFormat::Rgba16f);
        assert_eq!(compiled(&a, &options), compiled(&b, &options));
        if variant == Variant::Multipass {
            assert_ne!(compiled(&a, &options), compiled(&c, &options));
            assert_ne!(compiled(&a, &options), compiled(&d, &options));
        }
    }
}
