//! Two faults of the hybrid frame, checked against the reference ray tracer: (1) the environment
//! at infinity must show behind every non-lens pixel whose camera ray leaves the scene (an open
//! scene under a sky, not a closed room); (2) no pixel that the reference sees as lens may be
//! left unshaded where the lens mesh is open and the camera sees its inside (the glass teapot
//! between lid and rim). GPU work runs with validation on.

use glam::Vec3;
use lensmap::hybrid::FrameBuilder;
use lensmap::render::BlendScheme;
use lensmap::render::Compositing;
use lensmap::{
    hybrid::{HybridOptions, HybridScene, LayeredEms},
    layers::projected::ProjectedOptions,
    render::{LensFaces, RenderedImage, TargetFormat, Variant},
    runner::{FrameOptions, FrameRunner},
    scene::Scene,
    trace::{TraceOptions, image::camera_ray, render_reference, stats::TraceCounters},
};
use lensmap_tests::fixtures::{
    built_in_scene, smooth_sky, temp_dir, with_projected_ems, write_smooth_sky,
};
use lensmap_tests::{assert_clean, gpu};

/// The closed-form radiance of a test sky along a direction.
type SkyRadiance = dyn Fn(Vec3) -> Vec3;

/// A glass sphere floating over a small floor quad, nothing else: most camera rays leave the
/// scene.
fn open_scene(dir: &std::path::Path, environment: &str) -> Scene {
    let text = format!(
        r#"
name = "open-sky"
[camera]
position = [0.0, 1.6, 3.2]
look_at = [0.0, 0.4, 0.0]
vfov_degrees = 50.0
width = 96
height = 72

[environment]
{environment}

[[lights]]
position = [2.0, 5.0, 3.0]
intensity = [40.0, 40.0, 40.0]

[[materials]]
name = "glass"
glass = {{ ior = 1.5, absorption = [0.9, 0.95, 1.0] }}

[[materials]]
name = "floor"
diffuse = {{ colour = [0.7, 0.6, 0.5] }}

[[objects]]
name = "sphere"
material = "glass"
sphere = {{ radius = 0.5, segments = 32, rings = 16 }}
transform = {{ translate = [0.0, 0.7, 0.0] }}

[[objects]]
name = "floor"
material = "floor"
plane = {{ size = [2.0, 2.0], subdivisions = 2 }}

[[lenses]]
name = "sphere"
objects = ["sphere"]
layers = [{{ sphere = 50.0 }}]
"#
    );
    let path = dir.join("open.toml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path).unwrap()
}

/// (1) Every pixel whose camera ray (through the pixel centre, as the reference casts it at
/// k = 1) hits nothing, and whose eight neighbours' rays hit nothing either (so rasterization at
/// an edge cannot decide otherwise), shows the environment's radiance in that direction: exactly
/// (to float rounding) for a constant sky, within 1% for a smooth lat-long sky through the sky
/// dome's interpolation; none of them is black. Lens pixels are the same with and without the
/// sky.
#[test]
fn the_environment_shows_where_camera_rays_escape() {
    let dir = temp_dir("faults", "sky");
    write_smooth_sky(&dir.join("sky.exr"));
    let constant = Vec3::new(0.3, 0.5, 0.8);
    let cases: [(&str, &SkyRadiance, f32); 2] = [
        ("constant = [0.3, 0.5, 0.8]", &move |_| constant, 1e-6),
        ("latlong = { path = \"sky.exr\" }", &smooth_sky, 1e-2),
    ];
    let mut runner = FrameRunner::new(gpu()).unwrap();
    for (environment, sky, tolerance) in cases {
        let scene = open_scene(&dir, environment);
        let camera = scene.camera;
        let mut hybrid = with_projected_ems(scene, 16);
        assert!(
            hybrid.sky().is_some(),
            "{environment}: a lit sky has a dome"
        );
        let (w, h) = (camera.width as i64, camera.height as i64);
        let escapes: Vec<bool> = (0..w * h)
            .map(|p| {
                let ray = camera_ray(&camera, (p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                let mut counters = TraceCounters::default();
                hybrid
                    .trace()
                    .closest_hit(&ray, None, None, &mut counters)
                    .is_none()
            })
            .collect();
        let interior: Vec<usize> = (0..w * h)
            .filter(|&p| {
                let (x, y) = (p % w, p / w);
                (-1..=1).all(|dy| {
                    (-1..=1).all(|dx| {
                        let (u, v) = (x + dx, y + dy);
                        u < 0 || v < 0 || u >= w || v >= h || escapes[(v * w + u) as usize]
                    })
                })
            })
            .map(|p| p as usize)
            .collect();
        assert!(
            interior.len() > 2000,
            "{environment}: {} sky pixels",
            interior.len()
        );
        let reference =
            render_reference(hybrid.trace(), &camera, &TraceOptions::default(), &|_| {}).unwrap();
        let mut frames: Vec<RenderedImage> = Vec::new();
        for variant in [Variant::Multipass, Variant::SinglePass] {
            let options = FrameOptions {
                hybrid: HybridOptions::default(),
                compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
                format: TargetFormat::Rgba32f,
            };
            let frame = runner.frame(&hybrid, &camera, &options).unwrap();
            let mut worst = 0.0f32;
            for &p in &interior {
                let (x, y) = (p as i64 % w, p as i64 / w);
                let got = Vec3::from_slice(&frame.image.pixels[p][..3]);
                assert_ne!(
                    got,
                    Vec3::ZERO,
                    "{environment} {variant:?}: ({x}, {y}) is black"
                );
                let direction = camera_ray(&camera, x as f64 + 0.5, y as f64 + 0.5)
                    .direction
                    .as_vec3();
                let want = sky(direction);
                // The reference tracer agrees with the closed form where its ray escapes.
                assert!(
                    (reference.radiance[p] - want).abs().max_element() <= tolerance.max(1e-3),
                    "{environment}: reference {} vs {want} at ({x}, {y})",
                    reference.radiance[p]
                );
                let error = ((got - want).abs() / want.max(Vec3::splat(1e-3))).max_element();
                worst = worst.max(error);
                assert!(
                    error <= tolerance,
                    "{environment} {variant:?}: ({x}, {y}) shows {got}, the sky is {want}"
                );
            }
            println!(
                "{environment} {variant:?}: {} sky pixels, worst relative error {worst:.2e}",
                interior.len()
            );
            frames.push(frame.image);
        }
        // The lens pixels do not see the sky dome: the same frame without it has the same lens.
        hybrid.set_sky(None);
        for (variant, with_sky) in [Variant::Multipass, Variant::SinglePass]
            .iter()
            .zip(&frames)
        {
            let options = FrameOptions {
                hybrid: HybridOptions::default(),
                compositing: Compositing::new(*variant, BlendScheme::FrontToBack).unwrap(),
                format: TargetFormat::Rgba32f,
            };
            let without = runner.frame(&hybrid, &camera, &options).unwrap();
            let lens: Vec<usize> = (0..reference.lens_mask.len())
                .filter(|&p| reference.lens_mask[p] >= 1.0)
                .collect();
            assert!(lens.len() > 300, "{} lens pixels", lens.len());
            let changed = lens
                .iter()
                .filter(|&&p| with_sky.pixels[p] != without.image.pixels[p])
                .count();
            assert_eq!(
                changed, 0,
                "{environment} {variant:?}: the sky changed lens pixels"
            );
        }
    }
    assert_clean(runner.gpu());
}

/// (2) The glass teapot is an open mesh: through the gap between lid and rim the camera sees the
/// inside of the body, i.e. back faces, which the reference shades. A lens pixel is *unshaded*
/// when the reference sees only lens in it (coverage 1) and the hybrid frame's value there is
/// bit for bit what the same frame without its lens objects has (no lens pass wrote it). No
/// lens pixel may be unshaded. The camera is the scene's, narrowed onto the lid (drawing front
/// faces only leaves 44 pixels of this view unshaded).
#[test]
fn no_lens_pixel_is_left_unshaded_in_the_teapots_lid_gap() {
    let mut scene = built_in_scene("teapot-room", 160, 120, 2);
    scene.camera.vfov_radians = 15f32.to_radians();
    scene.camera.look_at = Vec3::new(0.0, 0.55, 0.0);
    let camera = scene.camera;
    let hybrid = with_projected_ems(scene, 16);
    // The teapot is open (the cup's cylinder and torus are closed).
    assert_eq!(hybrid.faces(), vec![LensFaces::Both, LensFaces::Front]);
    let reference =
        render_reference(hybrid.trace(), &camera, &TraceOptions::default(), &|_| {}).unwrap();
    let lens: Vec<usize> = (0..reference.lens_mask.len())
        .filter(|&p| reference.lens_mask[p] >= 1.0)
        .collect();
    assert!(lens.len() > 5000, "{} lens pixels", lens.len());
    let mut runner = FrameRunner::new(gpu()).unwrap();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let options = FrameOptions {
            hybrid: HybridOptions::with_t(3.0),
            compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
            format: TargetFormat::Rgba32f,
        };
        let frame = runner.frame(&hybrid, &camera, &options).unwrap();
        let (mut input, _) = FrameBuilder::new()
            .frame(&hybrid, &camera, &options.hybrid)
            .unwrap();
        input.lenses.clear();
        let mut uploaded = runner.upload(&input).unwrap();
        let without_lenses = runner
            .timed_renders(&mut uploaded, &options.compositing(), 1)
            .unwrap()
            .image
            .box_downsample(camera.supersampling);
        let unshaded: Vec<(usize, usize)> = lens
            .iter()
            .filter(|&&p| frame.image.pixels[p][..3] == without_lenses.pixels[p][..3])
            .map(|&p| (p % camera.width as usize, p / camera.width as usize))
            .collect();
        println!(
            "{variant:?}: {} of {} lens pixels unshaded, {} lens triangles",
            unshaded.len(),
            lens.len(),
            frame.stats.triangles_out
        );
        assert!(
            unshaded.is_empty(),
            "{variant:?}: {} unshaded lens pixels, e.g. {:?}",
            unshaded.len(),
            &unshaded[..unshaded.len().min(8)]
        );
    }
    assert_clean(runner.gpu());
}

/// The flag that decides it: open lens meshes draw both faces, closed ones front faces only.
#[test]
fn open_lens_meshes_draw_both_faces_and_closed_ones_front_faces() {
    let scene = Scene::load_named("glass-sphere").unwrap();
    let (hybrid, _) = HybridScene::new(
        scene,
        LayeredEms::Projected(ProjectedOptions {
            size: 4,
            supersampling: 1,
        })
        .into(),
    )
    .unwrap();
    assert_eq!(hybrid.faces(), vec![LensFaces::Front]);
    let mut camera = hybrid.scene().camera;
    camera.width = 32;
    camera.height = 24;
    let (frame, _) = FrameBuilder::new()
        .frame(&hybrid, &camera, &HybridOptions::default())
        .unwrap();
    assert_eq!(frame.lenses[0].faces, LensFaces::Front);
    let scene = Scene::load_named("mirror-teapot").unwrap();
    let faces = HybridScene::lens_faces(
        &scene,
        &lensmap::trace::world::TraceScene::new(&scene).unwrap(),
    );
    // The body is open at the rim; the lid is open at its rim too.
    assert!(faces.contains(&LensFaces::Both), "{faces:?}");
}
