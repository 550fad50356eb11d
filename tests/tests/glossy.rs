//! Glossy surfaces in the reference ray tracer (`engine/src/trace/glossy.rs`) against closed forms
//! and a second algorithm: a Lambertian, a Phong and a coated sphere under a uniform environment
//! (each reflects a known share of it at normal incidence), a Phong sphere at oblique incidence
//! against a deterministic quadrature of the same BRDF over the hemisphere, and a glossy plane
//! under one point light (the direct term, exact). The estimates must lie within 4 standard
//! errors (their own, reported) of the answers; images are bit-identical at any thread count, and
//! two seeds differ within their errors.

use std::f64::consts::{FRAC_1_PI, PI, TAU};
use std::path::Path;

use glam::DVec3;
use lensmap::scene::{Material, Scene};
use lensmap::trace::glossy::Lobes;
use lensmap::trace::{Ray, TraceCounters, TraceOptions, TraceScene, render_reference};

/// A scene of one unit sphere at the origin in material `glossy` (the TOML inline table), under
/// a constant environment `environment` and the given `[[lights]]` tables, seen from +z.
fn sphere_scene(glossy: &str, environment: f64, lights: &str) -> (Scene, TraceScene) {
    let text = format!(
        r#"
name = "glossy-test"
[camera]
position = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
vfov_degrees = 30.0
width = 24
height = 24
supersampling = 1
[environment]
constant = [{environment}, {environment}, {environment}]
{lights}
[[materials]]
name = "shiny"
glossy = {glossy}
[[objects]]
name = "ball"
material = "shiny"
sphere = {{ radius = 1.0, segments = 256, rings = 128 }}
"#
    );
    let scene =
        Scene::from_toml_str(&text, Path::new("glossy-test.toml")).expect("the scene loads");
    let trace = TraceScene::new(&scene).expect("the scene traces");
    (scene, trace)
}

/// The camera ray from +z through the sphere's point at polar angle `theta` from +z (in the xz
/// plane): the hit's normal makes `theta` with the view direction only approximately (the ray
/// comes from a finite eye), so the tests use the hit's own normal.
fn ray_to(theta: f64) -> Ray {
    let eye = DVec3::new(0.0, 0.0, 5.0);
    let target = DVec3::new(theta.sin(), 0.0, theta.cos());
    Ray {
        origin: eye,
        direction: (target - eye).normalize(),
    }
}

/// Where `ray` meets the sphere.
fn first_hit(trace: &TraceScene, ray: &Ray) -> lensmap::trace::bvh::SurfaceHit {
    trace
        .closest_hit(ray, None, None, &mut TraceCounters::default())
        .expect("the ray meets the sphere")
        .hit
}

fn options(samples: u32, seed: u64) -> TraceOptions {
    TraceOptions {
        glossy_samples: samples,
        glossy_seed: seed,
        ..TraceOptions::default()
    }
}

/// The estimate along `ray` and its standard error (mean over channels: the tests' materials and
/// lights are grey).
fn estimate(trace: &TraceScene, ray: &Ray, options: &TraceOptions) -> Estimate {
    let mut counters = TraceCounters::default();
    let sample = trace.trace_camera_ray(ray, options, &mut counters);
    assert!(sample.lens.is_none());
    Estimate {
        value: sample.radiance.element_sum() / 3.0,
        error: sample.standard_error.element_sum() / 3.0,
    }
}

/// A Monte Carlo estimate and its standard error.
#[derive(Clone, Copy, Debug)]
struct Estimate {
    value: f64,
    error: f64,
}

/// `found` is `expected` within four standard errors and `slack` of `expected`.
fn assert_within(what: &str, found: Estimate, expected: f64, slack: f64) {
    let Estimate { value, error } = found;
    eprintln!("{what}: {value:.6} ± {error:.2e} against {expected:.6}");
    assert!(
        (value - expected).abs() <= 4.0 * error + slack * expected.abs(),
        "{what}: {value} ± {error} is not {expected}"
    );
}

#[test]
fn a_lambertian_sphere_reflects_its_albedo_of_a_uniform_environment() {
    let (_, trace) = sphere_scene("{ diffuse = [0.6, 0.6, 0.6] }", 0.5, "");
    for theta in [0.0, 0.6, 1.2] {
        let found = estimate(&trace, &ray_to(theta), &options(64, 0));
        // Cosine-weighted sampling of a Lambertian lobe has no variance: the only departure is
        // the faceted sphere's sliver between its face and its shading normal.
        assert_within(&format!("Lambert at θ = {theta}"), found, 0.6 * 0.5, 2e-3);
    }
}

#[test]
fn phong_and_coated_spheres_reflect_their_closed_forms_at_normal_incidence() {
    let environment = 0.5f64;
    // At normal incidence the lobes' axis is the normal, and (m + 2)/2π·∫cos^m θ cos θ dω = 1.
    let (_, phong) = sphere_scene(
        "{ diffuse = [0.2, 0.2, 0.2], specular = [0.5, 0.5, 0.5], exponent = 40 }",
        environment,
        "",
    );
    let found = estimate(&phong, &ray_to(0.0), &options(4096, 1));
    assert_within("Phong at normal incidence", found, 0.7 * environment, 1e-3);
    let (_, coated) = sphere_scene(
        "{ diffuse = [0.3, 0.3, 0.3], specular = [0.2, 0.2, 0.2], exponent = 20, coat = { ior = 1.5, exponent = 800 } }",
        environment,
        "",
    );
    let f0 = ((1.5f64 - 1.0) / (1.5 + 1.0)).powi(2);
    let found = estimate(&coated, &ray_to(0.0), &options(4096, 2));
    assert_within(
        "coat at normal incidence",
        found,
        environment * (f0 + (1.0 - f0) * 0.5),
        1e-3,
    );
}

/// ∫ f(ωi)·cos θi dω over the directions above both the shading and the face normal, by the
/// midpoint rule in (cos θ, φ) about the shading normal: the integrator's answer for a uniform
/// environment of radiance 1, by a second, deterministic algorithm.
fn quadrature(lobes: &Lobes, normal: DVec3, face: DVec3) -> f64 {
    let (n_theta, n_phi) = (2000, 1000);
    let (tangent, bitangent) = normal.any_orthonormal_pair();
    let mut sum = 0.0;
    for i in 0..n_theta {
        let cos_theta = (f64::from(i) + 0.5) / f64::from(n_theta);
        let sin_theta = (1.0 - cos_theta * cos_theta).sqrt();
        for j in 0..n_phi {
            let phi = TAU * (f64::from(j) + 0.5) / f64::from(n_phi);
            let direction =
                (tangent * phi.cos() + bitangent * phi.sin()) * sin_theta + normal * cos_theta;
            if direction.dot(face) <= 0.0 {
                continue;
            }
            sum += lobes.eval(direction).element_sum() / 3.0 * cos_theta;
        }
    }
    // dω = d(cos θ) dφ.
    sum * (1.0 / f64::from(n_theta)) * (TAU / f64::from(n_phi))
}

#[test]
fn a_phong_sphere_at_oblique_incidence_matches_a_quadrature_of_its_brdf() {
    let (scene, trace) = sphere_scene(
        "{ diffuse = [0.1, 0.1, 0.1], specular = [0.6, 0.6, 0.6], exponent = 12 }",
        1.0,
        "",
    );
    let Material::Glossy(brdf) = scene.materials[0] else {
        panic!("the test scene's material is glossy");
    };
    for theta in [0.5, 1.0, 1.3] {
        let ray = ray_to(theta);
        let hit = first_hit(&trace, &ray);
        let (normal, face) = (hit.shading_normal, hit.geometric_normal);
        let lobes = Lobes::new(&brdf, normal, -ray.direction);
        let expected = quadrature(&lobes, normal, face);
        let found = estimate(&trace, &ray, &options(4096, 3));
        // The horizon cuts the lobe more as θ grows: the share reflected falls below kd + ks.
        assert!(expected < 0.7 + 1e-9);
        assert_within(&format!("Phong at θ = {theta}"), found, expected, 2e-3);
    }
}

/// The exact unpolarized Fresnel reflectance from air into index `n`, written out.
fn fresnel(cos_i: f64, n: f64) -> f64 {
    let cos_t = (1.0 - (1.0 - cos_i * cos_i) / (n * n)).sqrt();
    let rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)).powi(2);
    let rp = ((n * cos_i - cos_t) / (n * cos_i + cos_t)).powi(2);
    0.5 * (rs + rp)
}

#[test]
fn a_coated_sphere_under_one_point_light_has_the_exact_direct_term() {
    let light = DVec3::new(0.7, 2.0, 1.5);
    let intensity = 3.0;
    let lights = format!(
        "[[lights]]\nposition = [{}, {}, {}]\nintensity = [{intensity}, {intensity}, {intensity}]",
        light.x, light.y, light.z
    );
    let (kd, ks, m, ior, c) = (0.3, 0.4, 25.0, 1.5, 300.0);
    let (_, trace) = sphere_scene(
        &format!(
            "{{ diffuse = [{kd}, {kd}, {kd}], specular = [{ks}, {ks}, {ks}], exponent = {m}, coat = {{ ior = {ior}, exponent = {c} }} }}"
        ),
        0.0,
        &lights,
    );
    for theta in [0.0, 0.4, 0.8, 1.2] {
        let ray = ray_to(theta);
        let hit = first_hit(&trace, &ray);
        let n = hit.shading_normal;
        let to_light = light - hit.position;
        let d2 = to_light.length_squared();
        let l = to_light / d2.sqrt();
        let v = -ray.direction;
        let r = 2.0 * n.dot(v) * n - v;
        let cos_alpha = l.dot(r).max(0.0);
        // The closed form, written out: ((1 − F)·(kd/π + ks·(m + 2)/2π·cos^m α)
        // + F·(c + 2)/2π·cos^c α)·I·cos θ/d², with F at the viewing angle.
        let f = fresnel(n.dot(v), ior);
        let brdf = (1.0 - f) * (kd * FRAC_1_PI + ks * (m + 2.0) / (2.0 * PI) * cos_alpha.powf(m))
            + f * (c + 2.0) / (2.0 * PI) * cos_alpha.powf(c);
        let expected = brdf * intensity * n.dot(l).max(0.0) / d2;
        let Estimate { value, error } = estimate(&trace, &ray, &options(16, 0));
        assert_eq!(error, 0.0, "a black environment adds no sampled light");
        // The scene holds the light's position and intensity in f32.
        assert!(
            (value - expected).abs() <= 1e-6 * expected,
            "θ = {theta}: {value} against {expected}"
        );
    }
}

#[test]
fn glossy_images_are_the_same_at_any_thread_count_and_seeds_agree_within_their_errors() {
    let (scene, trace) = sphere_scene(
        "{ diffuse = [0.2, 0.2, 0.2], specular = [0.5, 0.5, 0.5], exponent = 30, coat = { ior = 1.5, exponent = 300 } }",
        0.5,
        "[[lights]]\nposition = [1.0, 3.0, 3.0]\nintensity = [5.0, 5.0, 5.0]",
    );
    let render = |threads: usize, seed: u64| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a pool")
            .install(|| render_reference(&trace, &scene.camera, &options(64, seed), &|_| {}))
            .expect("the reference renders")
    };
    let (one, two) = (render(1, 0), render(2, 0));
    assert!(one.radiance == two.radiance && one.glossy_error == two.glossy_error);
    let other = render(2, 1);
    let (mut glossy, mut normalized) = (0usize, 0.0f64);
    for (((a, b), (ea, eb)), mask) in one
        .radiance
        .iter()
        .zip(&other.radiance)
        .zip(one.glossy_error.iter().zip(&other.glossy_error))
        .zip(&one.glossy_mask)
    {
        if *mask == 0.0 {
            continue;
        }
        glossy += 1;
        let difference = f64::from((*a - *b).element_sum() / 3.0);
        let spread = f64::from(ea * ea + eb * eb).sqrt();
        normalized += (difference / spread).powi(2);
        assert!(a.is_finite() && a.min_element() >= 0.0);
    }
    assert!(glossy > 100, "{glossy} glossy pixels");
    assert_ne!(one.radiance, other.radiance, "two seeds give two estimates");
    // The seeds' differences over their combined standard errors: unit variance if the errors are
    // right (a mean square far from 1 means the reported errors are not the estimates' spread).
    let mean_square = normalized / glossy as f64;
    eprintln!(
        "{glossy} glossy pixels: mean square of normalized seed differences {mean_square:.3}"
    );
    assert!((0.5..=2.0).contains(&mean_square), "{mean_square}");
}

/// A glass ball over a coated glossy floor: the floor's samples see the ball's two terms, whose
/// outgoing rays see the floor again (shaded by its diffuse base, so that nothing recurses).
#[test]
fn a_glass_ball_over_a_glossy_floor_renders_finite() {
    let text = lensmap_tests::fixtures::edit_scene(
        lensmap_tests::fixtures::SMALL_SCENE,
        "diffuse = { colour = [0.5, 0.5, 0.5] }",
        "glossy = { diffuse = [0.3, 0.1, 0.1], specular = [0.2, 0.2, 0.2], exponent = 50, coat = { ior = 1.5, exponent = 900 } }",
    );
    let scene = Scene::from_toml_str(&text, Path::new("small-glossy.toml")).expect("it loads");
    let trace = TraceScene::new(&scene).expect("it traces");
    let camera = lensmap::scene::Camera {
        width: 48,
        height: 36,
        ..scene.camera
    };
    let image = render_reference(&trace, &camera, &options(32, 0), &|_| {}).expect("it renders");
    assert!(
        image
            .radiance
            .iter()
            .all(|p| p.is_finite() && p.min_element() >= 0.0)
    );
    let glossy = image.glossy_mask.iter().filter(|&&m| m > 0.0).count();
    let lens = image.lens_mask.iter().filter(|&&m| m > 0.0).count();
    assert!(
        glossy > 100 && lens > 50,
        "{glossy} glossy and {lens} lens pixels"
    );
}

/// Radiance maps (`engine/src/trace/radiance_map.rs`) under a uniform environment: the normal
/// warp's map of a Lambertian lobe is kd·L wherever the element faces the viewer, and the mirror
/// warp's map of a Phong lobe is ks·L where the mirror direction is the view (normal incidence),
/// falling where the horizon cuts the lobe; nothing faces away, and the map is the same on 1 and
/// 2 threads.
#[test]
fn radiance_maps_under_a_uniform_environment_hold_their_closed_forms() {
    use lensmap::scene::Glossy;
    use lensmap::trace::radiance_map::{RadianceMapRequest, Warp};
    let (_, trace) = sphere_scene("{ diffuse = [0.6, 0.6, 0.6] }", 0.5, "");
    let view = DVec3::new(0.3, 0.4, 0.866_025_403_784_438_6).normalize();
    let request = |brdf, warp| RadianceMapRequest {
        centre: DVec3::ZERO,
        radius: 1.01,
        view,
        brdf,
        warp,
        size: 8,
        samples: 512,
        seed: 0,
    };
    let lambert = Glossy {
        diffuse: glam::Vec3::splat(0.6),
        specular: glam::Vec3::ZERO,
        exponent: 1.0,
        coat: None,
    };
    let map = trace.radiance_map(&request(lambert, Warp::Normal), &options(0, 0));
    let (mut facing, mut away) = (0, 0);
    for face in &map.map.levels[0] {
        for texel in face {
            if texel[3] > 0.0 {
                facing += 1;
                let radiance = f64::from(texel[0]) / f64::from(texel[3]);
                assert!((radiance - 0.3).abs() < 2e-6, "{texel:?}");
            } else {
                away += 1;
                assert_eq!(texel[..3], [0.0; 3]);
            }
        }
    }
    assert!(facing > 100 && away > 100, "{facing} facing, {away} away");
    let phong = Glossy {
        diffuse: glam::Vec3::ZERO,
        specular: glam::Vec3::splat(0.5),
        exponent: 30.0,
        coat: None,
    };
    let threads = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("a pool")
            .install(|| trace.radiance_map(&request(phong, Warp::Mirror), &options(0, 0)))
    };
    let (one, two) = (threads(1), threads(2));
    assert!(one.map.levels[0] == two.map.levels[0] && one.errors == two.errors);
    // The texel nearest the view direction: the mirror direction is the view, so the lobe is
    // about the normal and reflects ks·L whole.
    let face = lensmap::cubemap::face::major_face(view);
    let coordinates = lensmap::cubemap::face::face_coordinates_on(face, view);
    let edge = 8usize;
    let at = |c: f64| (((c / coordinates.major + 1.0) * 0.5 * edge as f64) as usize).min(edge - 1);
    let index = at(coordinates.tc) * edge + at(coordinates.sc);
    let texel = one.map.levels[0][face.index()][index];
    let error = f64::from(one.errors[face.index()][index]);
    eprintln!("mirror map near the view: {texel:?} ± {error:.2e}");
    assert!(
        (f64::from(texel[0]) / f64::from(texel[3]) - 0.25).abs() <= 4.0 * error + 0.01,
        "{texel:?} ± {error}"
    );
}
