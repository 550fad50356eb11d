//! Path classes (R, TT, TRT, …) against independent answers: the closed-form series of Fresnel
//! terms on an exact glass sphere, an f64 enumeration of the local ray tree written here (apart
//! from the tracer's class walk), and reference renders whose classes add up towards the full
//! ray tree.

use std::collections::HashMap;

use glam::DVec3;
use lensmap::scene::Scene;
use lensmap::trace::classes::{ClassSet, PathClass, local_throughput, trace_class, trace_term};
use lensmap::trace::fresnel;
use lensmap::trace::image::camera_ray;
use lensmap::trace::path::{Interface, LensGeometry, scatter, transmittance};
use lensmap::trace::world::Part;
use lensmap::trace::{
    PathModel, Ray, RayTreeOptions, ReferenceImage, TraceCounters, TraceOptions, TraceScene,
    render_reference,
};
use lensmap_tests::fixtures::{AnalyticSphere, angle_between};

/// On an exact sphere every internal hit meets the same angle θt, and by reciprocity its
/// reflectance is the outside one, R = R(θi): so class `TR^kT` carries `(1 − R)² R^k` and
/// `a^((k + 1)·2r cos θt)` of absorption, class `R` carries R, and the first N classes sum to
/// `R + (1 − R)(1 − R^(N−1))`, which tends to 1 (all the light, for clear glass) as N grows.
#[test]
fn on_an_exact_sphere_the_classes_follow_the_closed_form_series() {
    let (r, n) = (1.0, 1.5);
    let absorption = DVec3::new(0.9, 0.6, 0.3);
    let tinted = AnalyticSphere {
        absorption,
        ..AnalyticSphere::clear(r, n)
    };
    let clear = AnalyticSphere::clear(r, n);
    // Each new ray starts 1e-9 m (relative) off the surface, which moves the next hit by ~1e-9
    // and, near the critical angle, its Fresnel coefficient by up to ~1e-8 (as in
    // trace_optics.rs's greedy test): 1e-7 per interface bounds F, Σ and G.
    let tolerance = |interfaces: usize| 1e-7 * interfaces as f64;
    let mut counters = TraceCounters::default();
    let mut worst = 0.0f64;
    for step in 0..=40 {
        let b = 0.98 * f64::from(step) / 40.0;
        let incoming = Ray::new(DVec3::new(b, 0.0, 5.0), DVec3::NEG_Z);
        let first = clear.closest_hit(&incoming, None, &mut counters).unwrap();
        let theta_i = (b / r).asin();
        let big_r = fresnel::dielectric(theta_i.cos(), 1.0, n).reflectance;
        let theta_t = (theta_i.sin() / n).asin();
        let chord = 2.0 * r * theta_t.cos();
        let mut sum = 0.0;
        for i in 0..12 {
            let class = PathClass::glass(i).unwrap();
            let expected_f = if i == 0 {
                big_r
            } else {
                (1.0 - big_r).powi(2) * big_r.powi(i as i32 - 1)
            };
            let path = trace_class(&clear, &incoming, &first, class, &mut counters)
                .unwrap_or_else(|| panic!("b = {b}: {} has a path", class.name()));
            let error = (path.fresnel.x - expected_f).abs();
            worst = worst.max(error);
            assert!(
                error < tolerance(i + 1),
                "b = {b}, {}: F {} vs {expected_f}",
                class.name(),
                path.fresnel.x
            );
            sum += path.fresnel.x;
            let closed = if i == 0 {
                big_r
            } else {
                big_r + (1.0 - big_r) * (1.0 - big_r.powi(i as i32))
            };
            assert!(
                (sum - closed).abs() < tolerance((i + 1) * (i + 2) / 2),
                "b = {b}: Σ of {} classes",
                i + 1
            );
            // Absorption: i chords for TR^(i−1)T, none for R.
            let tinted_path =
                trace_class(&tinted, &incoming, &first, class, &mut counters).unwrap();
            let chords = if i == 0 { 0.0 } else { i as f64 * chord };
            let g = transmittance(absorption, chords);
            assert!(
                (tinted_path.attenuation - g).abs().max_element() < tolerance(i + 1),
                "b = {b}, {}: G {} vs {g}",
                class.name(),
                tinted_path.attenuation
            );
        }
        // What the first 12 classes miss is (1 − R)·R^11; the local tree finds all of it.
        let all = local_throughput(
            &clear,
            &incoming,
            &first,
            RayTreeOptions {
                max_depth: 400,
                cutoff: 1e-15,
            },
            &mut counters,
        );
        assert!((all.x - 1.0).abs() < 1e-9, "b = {b}: throughput {}", all.x);
        assert!(((1.0 - sum) - (1.0 - big_r) * big_r.powi(11)).abs() < tolerance(78));
        // A class the sphere cannot follow: after TT the ray has left, so TTT has no path.
        let ttt = PathClass::parse("TTT").unwrap();
        assert!(trace_class(&clear, &incoming, &first, ttt, &mut counters).is_none());
    }
    eprintln!("worst class Fresnel product error {worst:e}");
}

/// One leaf of the local ray tree: the path's sequence, its F·G and the ray leaving the object.
struct Leaf {
    weight: DVec3,
    outgoing: Ray,
}

/// Every path of `lens`'s local ray tree from `hit`, by sequence, to `depth` interfaces: both
/// children at every interface, recursively (a separate walk from the tracer's class walk,
/// which follows one fixed sequence).
fn enumerate(
    lens: &impl LensGeometry,
    direction: DVec3,
    hit: &lensmap::trace::bvh::SurfaceHit,
    sequence: String,
    weight: DVec3,
    depth: u32,
    leaves: &mut HashMap<String, Leaf>,
) {
    let mut counters = TraceCounters::default();
    let scattering = scatter(lens.interface(hit.object), direction, hit);
    let mut children = vec![('R', scattering.reflection)];
    if let Some((ray, t)) = scattering.refraction {
        children.push(('T', (ray, DVec3::splat(t))));
    }
    for (event, (ray, coefficient)) in children {
        let name = format!("{sequence}{event}");
        let mut w = weight * coefficient;
        match lens.closest_hit(&ray, Some(hit.primitive), &mut counters) {
            None => {
                leaves.insert(
                    name,
                    Leaf {
                        weight: w,
                        outgoing: ray,
                    },
                );
            }
            Some(next) if depth > 1 => {
                if !next.is_front_facing(ray.direction)
                    && let Interface::Dielectric { absorption, .. } = lens.interface(next.object)
                {
                    w *= transmittance(absorption, next.distance);
                }
                enumerate(lens, ray.direction, &next, name, w, depth - 1, leaves);
            }
            Some(_) => {}
        }
    }
}

/// On the meshes of the built-in scenes (a glass teapot whose spout meets its body, a mirror
/// teapot), each class's path equals the enumerated leaf of its sequence, or is absent where the
/// tree has no such leaf; and the leaves' F·G sum to the local throughput.
#[test]
fn every_class_is_the_leaf_of_its_sequence_in_an_enumerated_tree() {
    let mut compared = 0;
    let mut absent = 0;
    for name in ["teapot-room", "mirror-teapot", "glass-sphere"] {
        let scene = Scene::load_named(name).unwrap();
        let world = TraceScene::new(&scene).unwrap();
        let camera = scene.camera;
        let mut counters = TraceCounters::default();
        for y in (0..camera.height).step_by(17) {
            for x in (0..camera.width).step_by(13) {
                let ray = camera_ray(&camera, f64::from(x) + 0.5, f64::from(y) + 0.5);
                let Some(hit) = world.closest_hit(&ray, None, None, &mut counters) else {
                    continue;
                };
                let Part::Lens(lens) = hit.part else { continue };
                let geometry = world.lens(lens);
                let mut leaves = HashMap::new();
                let depth = 8;
                enumerate(
                    &geometry,
                    ray.direction,
                    &hit.hit,
                    String::new(),
                    DVec3::ONE,
                    depth,
                    &mut leaves,
                );
                let mut classes: Vec<PathClass> = (0..6).filter_map(PathClass::glass).collect();
                classes.extend((1..6).filter_map(PathClass::mirror));
                classes.extend(leaves.keys().filter_map(|k| PathClass::parse(k)));
                for class in classes {
                    let path = trace_class(&geometry, &ray, &hit.hit, class, &mut counters);
                    match (path, leaves.get(&class.name())) {
                        (Some(path), Some(leaf)) => {
                            compared += 1;
                            assert!(
                                (path.weight() - leaf.weight).abs().max_element() < 1e-12,
                                "{name} ({x}, {y}) {}: {} vs {}",
                                class.name(),
                                path.weight(),
                                leaf.weight
                            );
                            assert!(
                                angle_between(path.outgoing_ray.direction, leaf.outgoing.direction)
                                    < 1e-12
                            );
                            assert!(
                                path.outgoing_ray.origin.distance(leaf.outgoing.origin) < 1e-12
                            );
                        }
                        (None, None) => absent += 1,
                        (path, leaf) => {
                            // Only a sequence longer than the enumeration's depth may differ.
                            assert!(
                                class.events_len() > depth,
                                "{name} ({x}, {y}) {}: class path {} but leaf {}",
                                class.name(),
                                path.is_some(),
                                leaf.is_some()
                            );
                        }
                    }
                }
                // The tree expanded to 3 events, greedy below: each term's path is the leaf of
                // its whole sequence, which starts with the term's prefix, and no two terms
                // share a path.
                let interface = geometry.interface(hit.hit.object);
                let mut taken: Vec<String> = Vec::new();
                for term in ClassSet::Expanded(3).terms(interface) {
                    let Some(path) = trace_term(&geometry, &ray, &hit.hit, term, &mut counters)
                    else {
                        continue;
                    };
                    let sequence = path.class.name();
                    assert!(sequence.starts_with(&term.class.name()), "{sequence}");
                    assert!(!taken.contains(&sequence), "{name}: {sequence} twice");
                    taken.push(sequence.clone());
                    if let Some(leaf) = leaves.get(&sequence) {
                        compared += 1;
                        assert!(
                            (path.weight() - leaf.weight).abs().max_element() < 1e-12,
                            "{name} ({x}, {y}) {sequence} by its greedy tail"
                        );
                    } else {
                        assert!(path.class.events_len() > depth, "{name}: {sequence}");
                    }
                }
                let sum: DVec3 = leaves.values().map(|l| l.weight).sum();
                let throughput = local_throughput(
                    &geometry,
                    &ray,
                    &hit.hit,
                    RayTreeOptions {
                        max_depth: depth,
                        cutoff: 0.0,
                    },
                    &mut counters,
                );
                assert!(
                    (sum - throughput).abs().max_element() < 1e-12,
                    "{name} ({x}, {y})"
                );
            }
        }
    }
    eprintln!("{compared} class paths equal their leaves; {absent} absent in both");
    assert!(compared > 500, "{compared} compared");
}

/// Reference renders of built-in scene `name` at `width`×`height`, one sample a pixel, under
/// the model given.
fn renderer(name: &str, width: u32, height: u32) -> impl Fn(PathModel) -> ReferenceImage {
    let mut scene = Scene::load_named(name).unwrap();
    scene.camera.width = width;
    scene.camera.height = height;
    scene.camera.supersampling = 1;
    let world = TraceScene::new(&scene).unwrap();
    move |model| {
        let options = TraceOptions {
            model,
            ..TraceOptions::default()
        };
        render_reference(&world, &scene.camera, &options, &|_| {}).unwrap()
    }
}

/// Reference renders of glass-sphere with 1, 2, 4 and 6 classes: each class adds non-negative
/// light, so the lens radiance grows with the classes towards the full tree's and the share
/// the classes drop falls; never above the full tree by more than its cutoff allows.
#[test]
fn classes_add_up_towards_the_full_tree_in_a_reference_render() {
    let render = renderer("glass-sphere", 64, 48);
    let lens_sum = |image: &ReferenceImage| -> f64 {
        image
            .radiance
            .iter()
            .zip(&image.lens_mask)
            .filter(|(_, m)| **m > 0.0)
            .map(|(r, _)| f64::from(r.x + r.y + r.z))
            .sum()
    };
    let full = lens_sum(&render(PathModel::Full));
    let mut previous = (0.0, 1.0);
    for n in [1u8, 2, 4, 6] {
        let image = render(PathModel::Classes(ClassSet::First(n)));
        let sum = lens_sum(&image);
        let dropped = image.stats.class_share.dropped().expect("lens rays");
        eprintln!(
            "{n} classes: lens radiance {:.4} of the full tree's, {:.3} % of the throughput dropped",
            sum / full,
            100.0 * dropped
        );
        assert!(
            sum >= previous.0 && dropped <= previous.1,
            "{n} classes: {sum} after {previous:?}"
        );
        // The full tree stops branches below F·G = 1e-3; the classes are not cut off.
        assert!(
            sum <= full * 1.01,
            "{n} classes: {sum} vs the full tree's {full}"
        );
        previous = (sum, dropped);
    }
    assert!(
        previous.0 > 0.98 * full,
        "6 classes: {} of the full tree",
        previous.0 / full
    );
}

/// The tree expanded to one event, greedy below, is the papers' two greedy terms: its images
/// equal the greedy model's bit for bit; expanded to two and three it keeps more of the full
/// tree's light on teapot-room, whose light the fixed classes miss.
#[test]
fn expanded_to_one_event_is_the_greedy_model_and_deeper_keeps_more() {
    for name in ["teapot-room", "glass-sphere"] {
        let render = renderer(name, 48, 36);
        let bits = |image: &ReferenceImage| -> Vec<u32> {
            image
                .radiance
                .iter()
                .chain(&image.refraction)
                .chain(&image.reflection)
                .flat_map(|v| v.to_array().map(f32::to_bits))
                .collect()
        };
        let greedy = render(PathModel::Greedy);
        let one = render(PathModel::Classes(ClassSet::Expanded(1)));
        assert_eq!(bits(&greedy), bits(&one), "{name}");
        let total = |image: &ReferenceImage| -> f64 {
            image
                .radiance
                .iter()
                .map(|r| f64::from(r.x + r.y + r.z))
                .sum()
        };
        let two = render(PathModel::Classes(ClassSet::Expanded(2)));
        let three = render(PathModel::Classes(ClassSet::Expanded(3)));
        let dropped =
            |image: &ReferenceImage| image.stats.class_share.dropped().expect("lens rays");
        assert!(
            total(&two) > total(&one) && total(&three) >= total(&two),
            "{name}: {} {} {}",
            total(&one),
            total(&two),
            total(&three)
        );
        assert!(
            dropped(&three) < dropped(&two) && dropped(&two) < dropped(&one),
            "{name}"
        );
    }
}
