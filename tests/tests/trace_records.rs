//! Intersection records (paper §4.1): every front-facing hit along an outgoing ray (ray
//! continuation, Figure 4c) and records for a lens object hidden behind another (Figure 4b),
//! checked against the scene's analytic geometry.

use glam::{DVec3, Vec2, Vec3};
use lensmap::scene::{
    Camera, Environment, LensObject, Material, PointLight, Scene, SceneObject, TriangleMesh,
    ViewSpace,
};
use lensmap::trace::{Bounces, GreedyOptions, Term, TraceOptions, TraceScene, compile_records};

/// An axis-aligned rectangle at depth `z` facing `facing` (+1: +z, −1: −z), x ∈ [x0, x1],
/// y ∈ [y0, y1].
fn wall(z: f32, x: [f32; 2], y: [f32; 2], facing: f32) -> TriangleMesh {
    let corners = [
        Vec3::new(x[0], y[0], z),
        Vec3::new(x[1], y[0], z),
        Vec3::new(x[1], y[1], z),
        Vec3::new(x[0], y[1], z),
    ];
    let triangles = if facing > 0.0 {
        vec![[0, 1, 2], [0, 2, 3]]
    } else {
        vec![[0, 2, 1], [0, 3, 2]]
    };
    TriangleMesh {
        positions: corners.to_vec(),
        normals: vec![Vec3::new(0.0, 0.0, facing); 4],
        uvs: vec![Vec2::ZERO; 4],
        triangles,
    }
}

fn floor(y: f32, half: f32) -> TriangleMesh {
    TriangleMesh {
        positions: vec![
            Vec3::new(-half, y, half),
            Vec3::new(half, y, half),
            Vec3::new(half, y, -half),
            Vec3::new(-half, y, -half),
        ],
        normals: vec![Vec3::Y; 4],
        uvs: vec![Vec2::ZERO; 4],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

fn object(name: &str, mesh: TriangleMesh, material: usize) -> SceneObject {
    SceneObject {
        name: name.to_owned(),
        mesh,
        material,
    }
}

fn scene(objects: Vec<SceneObject>, lenses: Vec<LensObject>, camera: Camera) -> Scene {
    Scene {
        name: "records".to_owned(),
        objects,
        materials: vec![
            Material::Mirror {
                reflectance: Vec3::ONE,
            },
            Material::Diffuse {
                colour: Vec3::splat(0.5),
                texture: None,
            },
        ],
        lights: vec![PointLight {
            position: Vec3::new(0.0, 5.0, 5.0),
            intensity: Vec3::splat(40.0),
        }],
        environment: Environment::Constant(Vec3::new(0.1, 0.2, 0.3)),
        lenses,
        camera,
        view_space: ViewSpace::List(Vec::new()),
        warnings: Vec::new(),
    }
}

#[test]
fn outgoing_rays_record_every_front_facing_hit_nearest_first() {
    // A mirror floor reflects camera rays up and towards −z, through a near wall (z = −3, facing
    // the mirror's reflections), a wall facing away (z = −5, back-facing: not recorded) and a
    // far wall (z = −8). Each reflected ray crossing x, y inside all three must record the near
    // and the far wall at their analytic distances.
    let objects = vec![
        object("mirror", floor(0.0, 30.0), 0),
        object("near", wall(-3.0, [-1.0, 1.0], [0.0, 20.0], 1.0), 1),
        object("backwards", wall(-5.0, [-20.0, 20.0], [0.0, 20.0], -1.0), 1),
        object("far", wall(-8.0, [-20.0, 20.0], [0.0, 20.0], 1.0), 1),
    ];
    let lenses = vec![LensObject {
        name: "mirror".to_owned(),
        objects: vec![0],
        layers: Vec::new(),
        layering: lensmap::layers::Layering::Distance,
        terms: None,
    }];
    let camera = Camera {
        position: Vec3::new(0.0, 2.0, 6.0),
        look_at: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::Y,
        vfov_radians: 50f32.to_radians(),
        width: 24,
        height: 18,
        supersampling: 2,
    };
    let scene = scene(objects, lenses, camera);
    let world = TraceScene::new(&scene).unwrap();
    let set = compile_records(&world, &camera, &TraceOptions::default()).unwrap();
    assert_eq!(set.lenses.len(), 1);
    let records = &set.lenses[0];
    assert_eq!(records.name, "mirror");
    assert!(!records.records.is_empty());
    let mut through_near_wall = 0;
    for record in &records.records {
        assert_eq!(
            record.term,
            Term::Reflection,
            "a mirror has only the reflection term"
        );
        let ray = record.outgoing_ray;
        // Visible unless a wall stands between the camera and the mirror point.
        let eye = camera.position.as_dvec3();
        let blocked_at = |z: f64, half_width: f64| {
            let s = (z - eye.z) / (ray.origin.z - eye.z);
            let x = eye.x + s * (ray.origin.x - eye.x);
            ray.origin.z < z && x.abs() < half_width
        };
        let expected_visible = !(blocked_at(-3.0, 1.0) || blocked_at(-5.0, 20.0));
        if !(blocked_at(-3.0, 1.001) ^ blocked_at(-3.0, 0.999)) {
            assert_eq!(
                record.visible, expected_visible,
                "{:?}",
                record.image_position
            );
        }
        assert!(
            ray.origin.y.abs() < 1e-6,
            "outgoing rays leave the mirror floor"
        );
        let hits = records.hits_of(record);
        assert!(hits.windows(2).all(|w| w[0].distance <= w[1].distance));
        let names: Vec<&str> = hits
            .iter()
            .map(|h| scene.objects[h.object].name.as_str())
            .collect();
        assert!(
            !names.contains(&"backwards"),
            "back-facing hits are skipped: {names:?}"
        );
        assert!(!names.contains(&"mirror"));
        // Analytic crossings of the planes z = −3 and z = −8.
        let crossing = |z: f64| {
            let t = (z - ray.origin.z) / ray.direction.z;
            (t, ray.at(t))
        };
        let (t_far, p_far) = crossing(-8.0);
        if t_far > 0.0 && p_far.x.abs() < 20.0 && p_far.y < 20.0 {
            let far = hits.last().expect("the far wall is hit");
            assert_eq!(names.last(), Some(&"far"));
            assert!((far.distance - t_far).abs() < 1e-9);
            assert!(far.radiance.min_element() >= 0.0 && far.radiance.is_finite());
        }
        let (t_near, p_near) = crossing(-3.0);
        if t_near > 0.0 && p_near.x.abs() < 0.99 && p_near.y < 19.9 {
            through_near_wall += 1;
            assert_eq!(names, ["near", "far"]);
            assert!((hits[0].distance - t_near).abs() < 1e-9);
        }
        assert_eq!(record.weight(), DVec3::ONE, "reflectance 1: F·G = 1");
        assert_eq!(
            record.background,
            DVec3::new(0.1, 0.2, 0.3).as_vec3().as_dvec3()
        );
    }
    assert!(
        through_near_wall > 10,
        "{through_near_wall} records cross the near wall"
    );
    // Records are in image order: pixel rows, then pixels (then supersamples inside a pixel).
    let pixels: Vec<(f32, f32)> = records
        .records
        .iter()
        .map(|r| (r.image_position.y.floor(), r.image_position.x.floor()))
        .collect();
    assert!(pixels.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn incoming_rays_continue_through_a_lens_object_to_one_it_occludes() {
    // Two mirrors facing the camera: a small one in front hides the middle of a large one.
    // Every supersample that hits the small mirror also yields a record for the large mirror,
    // marked not visible, at the large mirror's analytic depth.
    let objects = vec![
        object("front", wall(1.0, [-0.5, 0.5], [-0.5, 0.5], 1.0), 0),
        object("back", wall(-1.0, [-3.0, 3.0], [-3.0, 3.0], 1.0), 0),
        object("room", wall(-10.0, [-50.0, 50.0], [-50.0, 50.0], 1.0), 1),
    ];
    let lenses = vec![
        LensObject {
            name: "front".to_owned(),
            objects: vec![0],
            layers: Vec::new(),
            layering: lensmap::layers::Layering::Distance,
            terms: None,
        },
        LensObject {
            name: "back".to_owned(),
            objects: vec![1],
            layers: Vec::new(),
            layering: lensmap::layers::Layering::Distance,
            terms: None,
        },
    ];
    let camera = Camera {
        position: Vec3::new(0.0, 0.0, 6.0),
        look_at: Vec3::ZERO,
        up: Vec3::Y,
        vfov_radians: 40f32.to_radians(),
        width: 20,
        height: 20,
        supersampling: 1,
    };
    let scene = scene(objects, lenses, camera);
    let world = TraceScene::new(&scene).unwrap();
    let set = compile_records(&world, &camera, &TraceOptions::default()).unwrap();
    let front = &set.lenses[0];
    let back = &set.lenses[1];
    assert!(!front.records.is_empty());
    assert!(front.records.iter().all(|r| r.visible));
    let hidden: Vec<_> = back.records.iter().filter(|r| !r.visible).collect();
    assert_eq!(
        hidden.len(),
        front.records.len(),
        "each record of the front mirror has a hidden twin on the back mirror"
    );
    for (occluder, occluded) in front.records.iter().zip(&hidden) {
        assert_eq!(occluder.image_position, occluded.image_position);
        assert!((occluded.outgoing_ray.origin.z + 1.0).abs() < 1e-6);
        assert!((occluder.outgoing_ray.origin.z - 1.0).abs() < 1e-6);
    }
    assert!(back.records.iter().any(|r| r.visible));
    // The front mirror's reflected rays go back to +z: nothing there but the environment.
    assert!(front.records.iter().all(|r| front.hits_of(r).is_empty()));
    // The back mirror's reflections meet the front mirror from behind (back-facing: skipped) or
    // nothing; a visible record whose ray goes through the front mirror's square records nothing.
    assert!(set.counters.primary_rays == 400);
}

#[test]
fn first_bounce_records_see_the_mirror_itself_where_the_corner_predicts() {
    // A corner reflector: mirror A in the plane x = 0 (facing +x, z ∈ [0, 2]) and mirror B in
    // the plane z = 0 (facing +z, x ∈ [0, 2]), both y ∈ [−1, 1], one lens object. A first
    // bounce off one meets the other exactly where the plane crossing of its ray lies inside
    // that mirror: its record's local hit, at that distance (the PEM paper's local layer). Traced
    // until it leaves, no record has a local hit.
    let quad = |corners: [Vec3; 4], normal: Vec3| TriangleMesh {
        positions: corners.to_vec(),
        normals: vec![normal; 4],
        uvs: vec![Vec2::ZERO; 4],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    let a = quad(
        [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 2.0),
            Vec3::new(0.0, -1.0, 2.0),
        ],
        Vec3::X,
    );
    let b = quad(
        [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(2.0, -1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        Vec3::Z,
    );
    let objects = vec![object("a", a, 0), object("b", b, 0)];
    let lenses = vec![LensObject {
        name: "corner".to_owned(),
        objects: vec![0, 1],
        layers: Vec::new(),
        layering: lensmap::layers::Layering::Distance,
        terms: None,
    }];
    let camera = Camera {
        position: Vec3::new(3.0, 0.3, 3.5),
        look_at: Vec3::new(0.6, 0.0, 0.8),
        up: Vec3::Y,
        vfov_radians: 50f32.to_radians(),
        width: 24,
        height: 18,
        supersampling: 1,
    };
    let scene = scene(objects, lenses, camera);
    let world = TraceScene::new(&scene).unwrap();
    let first = TraceOptions {
        greedy: GreedyOptions {
            bounces: Bounces::First,
            ..GreedyOptions::default()
        },
        ..TraceOptions::default()
    };
    let set = compile_records(&world, &camera, &first).unwrap();
    let (mut local, mut distant_only) = (0, 0);
    for record in set.lenses[0].records.iter().filter(|r| r.visible) {
        let ray = record.outgoing_ray;
        // The other mirror's plane crossing: (its coordinate along the ray, inside, near an edge).
        let crossing = |plane: usize, span: usize| {
            let t = -ray.origin[plane] / ray.direction[plane];
            let p = ray.origin + t * ray.direction;
            let inside = t > 0.0 && (0.0..=2.0).contains(&p[span]) && p.y.abs() <= 1.0;
            let edge = (p[span].min(2.0 - p[span].abs())).abs() < 1e-3 || (1.0 - p.y.abs()) < 1e-3;
            (t, inside, edge)
        };
        let (t, inside, edge) = if ray.origin.x.abs() < 1e-6 {
            crossing(2, 0) // off A towards B
        } else {
            assert!(
                ray.origin.z.abs() < 1e-6,
                "starts on a mirror: {:?}",
                ray.origin
            );
            crossing(0, 2) // off B towards A
        };
        if edge {
            continue;
        }
        assert!(set.lenses[0].hits_of(record).is_empty(), "no environment");
        match record.local {
            Some(hit) => {
                assert!(
                    inside,
                    "a local hit where the corner predicts none: {record:?}"
                );
                assert!(
                    (hit.distance - t).abs() < 1e-6 * t.max(1.0),
                    "{} vs {t}",
                    hit.distance
                );
                // Perfect mirrors (R₀ = 1) pass the environment at infinity on unchanged.
                assert!(
                    (hit.radiance - DVec3::new(0.1, 0.2, 0.3))
                        .abs()
                        .max_element()
                        < 1e-6
                );
                local += 1;
            }
            None => {
                assert!(
                    !inside,
                    "no local hit where the corner predicts one: {record:?}"
                );
                distant_only += 1;
            }
        }
    }
    assert!(
        local > 20 && distant_only > 20,
        "{local} local, {distant_only} distant"
    );
    let traced = compile_records(&world, &camera, &TraceOptions::default()).unwrap();
    assert!(traced.lenses[0].records.iter().all(|r| r.local.is_none()));
}

/// Under path classes the records are the baker's per-class targets: one record per class
/// term a supersample's path has (every term one of the set's), and the records summed as the
/// reference sums its classes (each record's F·G times the radiance of its ray's nearest hit,
/// or the background) give the reference image of the same class set at every pixel whose
/// supersamples all see the glass ball, to f32 rounding: the records and the reference are
/// two codes over the same paths.
#[test]
fn class_records_sum_to_the_reference_of_their_classes() {
    use lensmap::trace::{PathModel, classes::ClassSet, render_reference};
    let scene = lensmap_tests::fixtures::built_in_scene("glass-sphere", 24, 18, 2);
    let camera = scene.camera;
    let world = TraceScene::new(&scene).unwrap();
    let set = ClassSet::First(4);
    let options = TraceOptions {
        model: PathModel::Classes(set),
        ..TraceOptions::default()
    };
    let records = compile_records(&world, &camera, &options).unwrap();
    let reference = render_reference(&world, &camera, &options, &|_| {}).unwrap();
    let lens = &records.lenses[0];
    let glass = world.interface(world.lenses[0].objects[0]).unwrap();
    let terms: Vec<Term> = set.terms(glass).into_iter().map(Term::Class).collect();
    assert!(!lens.records.is_empty());
    assert!(lens.records.iter().all(|r| terms.contains(&r.term)));
    let width = camera.width as usize;
    let k = camera.supersampling as usize;
    let mut sum = vec![DVec3::ZERO; width * camera.height as usize];
    let mut seen: Vec<Vec<Vec2>> = vec![Vec::new(); sum.len()];
    for record in lens.records.iter().filter(|r| r.visible) {
        let position = record.image_position;
        let pixel = position.y.floor() as usize * width + position.x.floor() as usize;
        let radiance = lens
            .hits_of(record)
            .first()
            .map_or(record.background, |hit| hit.radiance);
        sum[pixel] += record.fresnel * record.attenuation * radiance;
        if !seen[pixel].contains(&position) {
            seen[pixel].push(position);
        }
    }
    let mut compared = 0;
    for (pixel, positions) in seen.iter().enumerate() {
        if positions.len() < k * k {
            continue;
        }
        let from_records = sum[pixel] / (k * k) as f64;
        let traced = reference.radiance[pixel].as_dvec3();
        let gap = (from_records - traced).abs().max_element();
        assert!(
            gap <= 1e-4 * traced.max_element().max(1e-3),
            "pixel {pixel}: records {from_records} against the reference {traced}"
        );
        compared += 1;
    }
    assert!(compared >= 20, "only {compared} pixels wholly on the ball");
}
