//! The frame builder checked on small scenes: the wireframe, the lens bounds, the view-space
//! fit, the frustum test against brute force.

use glam::Vec3;
use rand::{Rng, SeedableRng};

use super::{stage::hull_last, view::box_outside_view, *};
use crate::{
    hybrid::{HybridSceneOptions, LayeredEms},
    layers::projected::ProjectedOptions,
    lightmap::LightMapOptions,
    scene::Scene,
};

/// The split's triangles go last, each part in its order, their depths with them.
#[test]
fn hull_last_keeps_each_part_in_order_and_the_depths_in_step() {
    let mut triangles: Vec<[u32; 3]> = (0..6).map(|t| [t, t + 1, t + 2]).collect();
    let mut depths: Vec<u8> = (10..16).collect();
    let on_hull = [true, false, true, false, false, true];
    assert_eq!(hull_last(&mut triangles, &mut depths, &on_hull), 3);
    let firsts: Vec<u32> = triangles.iter().map(|t| t[0]).collect();
    assert_eq!(firsts, [1, 3, 4, 0, 2, 5]);
    assert_eq!(depths, [11, 13, 14, 10, 12, 15]);
}

/// Built-in scene `name` as a hybrid scene made cheaply (8² texel projected EMs at one ray a
/// texel, light maps of 1 texel a metre), and its camera at `width × height`, 1×1.
fn small_hybrid(name: &str, width: u32, height: u32) -> (HybridScene, Camera) {
    let scene = Scene::load_named(name).expect("a built-in scene");
    let camera = scene.camera.with_resolution(width, height, 1);
    let options = HybridSceneOptions {
        ems: LayeredEms::Projected(ProjectedOptions {
            size: 8,
            supersampling: 1,
        }),
        light_maps: LightMapOptions {
            supersampling: 1,
            ..LightMapOptions::uniform(1.0)
        },
    };
    let (hybrid, _) = HybridScene::new(scene, options).expect("a hybrid scene");
    (hybrid, camera)
}

fn max_depth(wireframe: &Wireframe) -> u8 {
    wireframe
        .lenses
        .iter()
        .flat_map(|l| l.depths.iter().copied())
        .max()
        .unwrap_or(0)
}

/// The last frame's wireframe is its lens meshes, triangle for triangle, with one depth per
/// triangle; a finer `t` splits deeper; a reused frame keeps it, forgetting drops it.
#[test]
fn wireframe_is_the_last_frames_tessellation() {
    let (hybrid, camera) = small_hybrid("teapot-room", 160, 120);
    let mut builder = FrameBuilder::new();
    assert!(builder.last_wireframe().is_none(), "no frame yet");
    let mut max_depths = Vec::new();
    for t in [20.0, 2.0] {
        let (frame, stats) = builder
            .frame(&hybrid, &camera, &HybridOptions::with_t(t))
            .unwrap();
        let wireframe = builder.last_wireframe().expect("a frame was built");
        assert_eq!(wireframe.lenses.len(), hybrid.trace().lenses.len());
        assert_eq!(frame.lenses.len(), wireframe.lenses.len());
        let mut triangles = 0;
        for (lens, drawn) in wireframe.lenses.iter().zip(&frame.lenses) {
            assert_eq!(lens.name, drawn.name);
            assert_eq!(lens.positions, drawn.positions);
            assert_eq!(lens.triangles, drawn.triangles);
            assert_eq!(lens.depths.len(), lens.triangles.len(), "{}", lens.name);
            triangles += lens.triangles.len();
        }
        assert_eq!(triangles, stats.triangles_out, "t = {t}");
        // No split at all leaves every triangle an input one at depth 0, and any split adds
        // triangles.
        assert_eq!(
            max_depth(&wireframe) == 0,
            stats.triangles_out == stats.triangles_in,
            "t = {t}: {stats:?}"
        );
        // A leaf at depth d holds at most 1/2^d of its input triangle's area (each split
        // child holds 1/4 or 1/2 of its parent's), and the pieces T-junction removal cuts
        // a leaf into hold less.
        for (lens, trace_lens) in wireframe.lenses.iter().zip(&hybrid.trace().lenses) {
            let largest_input = trace_lens
                .objects
                .iter()
                .flat_map(|&o| {
                    let mesh = &hybrid.scene().objects[o].mesh;
                    (0..mesh.triangles.len()).map(|t| 0.5 * mesh.triangle_normal(t).length())
                })
                .fold(0.0f32, f32::max);
            for (triangle, &depth) in lens.triangles.iter().zip(&lens.depths) {
                let [a, b, c] = triangle.map(|i| lens.positions[i as usize]);
                let area = 0.5 * (b - a).cross(c - a).length();
                let bound = largest_input / 2f32.powi(i32::from(depth));
                assert!(
                    area <= bound * 1.001 + 1e-9,
                    "{}: area {area} at depth {depth} over {bound}",
                    lens.name
                );
            }
        }
        max_depths.push(max_depth(&wireframe));
    }
    assert!(
        max_depths[1] > max_depths[0],
        "t = 2 splits deeper: {max_depths:?}"
    );

    let before = builder.last_wireframe();
    let (_, stats) = builder
        .frame(&hybrid, &camera, &HybridOptions::with_t(2.0))
        .unwrap();
    assert!(stats.reused);
    assert_eq!(
        builder.last_wireframe(),
        before,
        "a reused frame keeps its wireframe"
    );
    vertex_exact_frame(&hybrid, &camera, &HybridOptions::with_t(20.0)).unwrap();
    assert_eq!(
        builder.last_wireframe(),
        before,
        "a vertex-exact frame is not cached"
    );
    builder.forget();
    assert!(builder.last_wireframe().is_none());
}

/// Each lens object's bounds are the union of its meshes' vertices, here found by scanning
/// them; the glass sphere's are its closed form.
#[test]
fn lens_bounds_enclose_every_vertex_of_each_lens_object() {
    let (hybrid, _) = small_hybrid("teapot-room", 16, 12);
    let bounds = hybrid.lens_bounds();
    let names: Vec<&str> = bounds.iter().map(|(name, _, _)| name.as_str()).collect();
    assert_eq!(names, ["teapot", "cup"]);
    for ((name, lo, hi), lens) in bounds.iter().zip(&hybrid.trace().lenses) {
        let mut expected = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &object in &lens.objects {
            for &p in &hybrid.scene().objects[object].mesh.positions {
                expected = (expected.0.min(p), expected.1.max(p));
            }
        }
        assert_eq!((*lo, *hi), expected, "{name}");
    }
    // The cup is two objects: its bounds are wider than either alone.
    let cup = &hybrid.trace().lenses[1];
    assert_eq!(cup.objects.len(), 2);
    let volume = |(lo, hi): (Vec3, Vec3)| (hi - lo).element_product();
    for &object in &cup.objects {
        let alone = hybrid.scene().objects[object].mesh.bounds().unwrap();
        assert!(volume((bounds[1].1, bounds[1].2)) > volume(alone));
    }

    let (sphere, _) = small_hybrid("glass-sphere", 16, 12);
    let bounds = sphere.lens_bounds();
    assert_eq!(bounds.len(), 1);
    let (name, lo, hi) = &bounds[0];
    assert_eq!(name, "sphere");
    // Radius 1 m about (0, 1.2, 0): poles and the equator's quarter points are vertices.
    assert!(
        (*lo - Vec3::new(-1.0, 0.2, -1.0)).abs().max_element() < 1e-5,
        "{lo}"
    );
    assert!(
        (*hi - Vec3::new(1.0, 2.2, 1.0)).abs().max_element() < 1e-5,
        "{hi}"
    );
}

/// The scene's camera sits on viewpoint sample 0; far above the circle it has left the view
/// space; the frame's blend is the one `viewpoint_blend` reports.
#[test]
fn view_space_fit_and_blend_of_the_scene_camera() {
    let (hybrid, camera) = small_hybrid("glass-sphere", 16, 12);
    let fit = hybrid.view_space_fit(&camera).expect("a view space");
    assert_eq!(fit.nearest, 0);
    assert!(fit.nearest_radians < 1e-3, "{fit:?}");
    // Neighbouring samples are 8° apart round a circle 1.5 m above the look-at point at
    // 5 m: seen from it at elevation e = atan(1.5 / 5), cos θ = cos²e·cos 8° + sin²e.
    let e = (1.5f64 / 5.0).atan();
    let spacing = (e.cos().powi(2) * 8f64.to_radians().cos() + e.sin().powi(2)).acos();
    assert!(
        (fit.spacing_radians - spacing).abs() < 1e-6,
        "{fit:?} {spacing}"
    );
    assert!(!fit.outside);
    let above = Camera {
        position: camera.look_at + Vec3::new(0.0, 5.0, 0.5),
        ..camera
    };
    assert!(hybrid.view_space_fit(&above).unwrap().outside);
    let at_look_at = Camera {
        position: camera.look_at,
        ..camera
    };
    assert!(hybrid.view_space_fit(&at_look_at).is_none());

    let blend = hybrid.viewpoint_blend(&camera, ViewpointBlending::ViewSpace);
    assert_eq!(blend.samples, vec![(0, 1.0)], "projected EMs: one sample");
    let (frame, _) = FrameBuilder::new()
        .frame(&hybrid, &camera, &HybridOptions::default())
        .unwrap();
    let weights: Vec<f32> = blend.samples.iter().map(|(_, w)| *w as f32).collect();
    assert_eq!(frame.viewpoint_weights, weights);
}

/// The box test against brute force: a box reported outside has no sampled point inside the
/// clip volume, and boxes with a point inside are never reported outside.
#[test]
fn boxes_outside_the_view_hold_no_visible_point() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(10);
    let camera = Camera {
        position: Vec3::new(0.0, 1.0, 4.0),
        look_at: Vec3::ZERO,
        up: Vec3::Y,
        vfov_radians: 0.8,
        width: 64,
        height: 48,
        supersampling: 1,
    };
    let view_proj = camera.view_proj(0.05, 100.0);
    let inside = |p: Vec3| {
        let c = view_proj * p.extend(1.0);
        c.x.abs() <= c.w && c.y.abs() <= c.w && c.z >= 0.0 && c.z <= c.w
    };
    let (mut outside_count, mut visible_count) = (0, 0);
    for _ in 0..400 {
        let centre = Vec3::new(
            rng.gen_range(-12.0..12.0),
            rng.gen_range(-12.0..12.0),
            rng.gen_range(-12.0..12.0),
        );
        let half = Vec3::new(
            rng.gen_range(0.01..2.0),
            rng.gen_range(0.01..2.0),
            rng.gen_range(0.01..2.0),
        );
        let (lo, hi) = (centre - half, centre + half);
        let any_inside = (0..2000).any(|_| {
            inside(Vec3::new(
                rng.gen_range(lo.x..=hi.x),
                rng.gen_range(lo.y..=hi.y),
                rng.gen_range(lo.z..=hi.z),
            ))
        });
        if box_outside_view(lo, hi, &view_proj) {
            outside_count += 1;
            assert!(
                !any_inside,
                "box {lo} … {hi} reported outside holds a visible point"
            );
        } else if any_inside {
            visible_count += 1;
        }
    }
    assert!(
        outside_count > 50 && visible_count > 20,
        "{outside_count} {visible_count}"
    );
}
