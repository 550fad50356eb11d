//! The glossy pass (reflection-space IBR on the GPU, `shaders/wgsl/glossy.wgsl`) against the CPU
//! f64 model of the same frame (`render::model`, which shades glossy fragments with
//! `rsibr::shade`): a coated sphere whose three lobes read three view samples' maps, one warped
//! and two turned, over an environment backdrop, with validation on.
//!
//! The maps are smooth (a quadratic of the direction), their confidence never below 0.5, so the only freedom a conformant driver has is the bilinear weights' snapping to
//! `subTexelPrecisionBits` (at least 4 bits, [`FilterPrecision::SPEC_MINIMUM`]): a sample may move
//! by at most half a sub-texel step times the largest difference between neighbouring texels.
//! The tolerance carries that through the blend `Σ w·rgb / Σ w·α` and the lobes' sum, plus f32
//! rounding.

use lensmap::hybrid::FrameBuilder;
use lensmap::render::BlendScheme;
use lensmap::render::Compositing;
use std::sync::Arc;

use glam::{DVec3, Mat3, Vec3};
use lensmap::cubemap::sampling::FilterPrecision;
use lensmap::cubemap::{CubeFace, CubeMap};
use lensmap::render::model::{ModelOptions, render_model};
use lensmap::render::{EnvironmentMesh, FrameInput, GlossyDraw, GlossyMesh, GlossySlot, Renderer};
use lensmap::rsibr::MapLobe;
use lensmap::scene::{Coat, Glossy, Scene};
use lensmap_tests::{assert_clean, gpu, render_rgba32f};

/// A smooth premultiplied map: confidence 0.5…1 rising towards `towards`, colour a quadratic
/// of the direction with `seed`'s coefficients.
fn smooth_map(size: u32, towards: DVec3, seed: f64) -> CubeMap {
    CubeMap::from_fn(size, |d| {
        let d = d.normalize();
        let alpha = 0.5 + 0.5 * (0.5 + 0.5 * d.dot(towards)).powi(2);
        let colour = DVec3::new(
            0.6 + 0.3 * d.x + 0.1 * seed * d.y * d.z,
            0.5 + 0.2 * d.y * seed - 0.2 * d.z * d.x,
            0.4 + 0.3 * d.z + 0.2 * d.x * d.x,
        );
        let c = colour * alpha;
        [c.x as f32, c.y as f32, c.z as f32, alpha as f32]
    })
}

/// The largest difference of any channel between neighbouring level-0 texels of `map` (within a
/// face; across a face edge the seamless filter pairs texels a smooth map has as close).
fn neighbour_difference(map: &CubeMap) -> f64 {
    let edge = map.size as usize;
    let mut largest = 0f64;
    for face in CubeFace::ALL {
        let texels = &map.levels[0][face.index()];
        for j in 0..edge {
            for i in 0..edge {
                let here = texels[j * edge + i];
                for (di, dj) in [(1, 0), (0, 1)] {
                    let (x, y) = (i + di, j + dj);
                    if x < edge && y < edge {
                        let there = texels[y * edge + x];
                        for c in 0..4 {
                            largest = largest.max(f64::from((here[c] - there[c]).abs()));
                        }
                    }
                }
            }
        }
    }
    largest
}

#[test]
fn the_glossy_pass_matches_the_f64_model() {
    let scene = Scene::load_named("glossy-studio").expect("the built-in scene");
    let sphere = scene
        .objects
        .iter()
        .find(|o| o.name == "sphere")
        .expect("a sphere");
    let camera = scene.camera.with_resolution(128, 96, 1);
    let brdf = Glossy {
        diffuse: Vec3::new(0.4, 0.1, 0.1),
        specular: Vec3::splat(0.3),
        exponent: 40.0,
        coat: Some(Coat {
            ior: 1.5,
            exponent: 400.0,
        }),
    };
    let lobes = MapLobe::of(&brdf);
    assert_eq!(lobes.len(), 3);
    let views = [
        DVec3::new(0.0, 0.3, 1.0).normalize(),
        DVec3::new(0.5, 0.2, 0.8).normalize(),
        DVec3::new(-0.3, 0.6, 0.7).normalize(),
    ];
    let rotations = [
        Mat3::IDENTITY,
        Mat3::from_axis_angle(Vec3::Y, 0.35),
        Mat3::from_axis_angle(Vec3::new(1.0, 0.0, 0.2).normalize(), -0.25),
    ];
    let weights = [0.5f32, 0.3, 0.2];
    let slots: Vec<GlossySlot> = (0..3)
        .map(|s| GlossySlot {
            weight: weights[s],
            rotation: rotations[s],
            maps: (0..lobes.len())
                .map(|k| Arc::new(smooth_map(64, views[s], (s * 3 + k) as f64 - 3.0)))
                .collect(),
        })
        .collect();
    let frame = FrameInput {
        width: camera.width,
        height: camera.height,
        view_proj: camera.view_proj(0.1, 50.0),
        environment: vec![Arc::new(EnvironmentMesh {
            positions: vec![
                Vec3::new(-20.0, -20.0, -5.0),
                Vec3::new(20.0, -20.0, -5.0),
                Vec3::new(0.0, 20.0, -5.0),
            ],
            colours: vec![Vec3::new(0.2, 0.3, 0.4); 3],
            triangles: vec![[0, 1, 2]],
            light_map: None,
        })],
        glossy: vec![GlossyDraw {
            name: "sphere".into(),
            mesh: Arc::new(GlossyMesh {
                positions: sphere.mesh.positions.clone(),
                normals: sphere.mesh.normals.clone(),
                triangles: sphere.mesh.triangles.clone(),
            }),
            brdf,
            lobes: lobes.clone(),
            slots: slots.clone(),
            eye: camera.position,
        }],
        lenses: Vec::new(),
        viewpoint_weights: vec![1.0],
    };
    let gpu = gpu();
    let mut renderer = Renderer::new(&gpu).expect("a renderer");
    let mut uploaded = renderer.upload(&gpu, &frame).expect("the frame uploads");
    let image = render_rgba32f(
        &mut renderer,
        &gpu,
        &mut uploaded,
        Compositing::Multipass(BlendScheme::FrontToBack),
    );
    assert_clean(&gpu);
    let model = render_model(&frame, &ModelOptions::default());
    // The sphere's pixels: nearer than the backdrop alone.
    let backdrop = render_model(
        &FrameInput {
            glossy: Vec::new(),
            ..frame.clone()
        },
        &ModelOptions::default(),
    );

    // The tolerance: per lobe, sub-texel snapping moves each slot's rgb by at most
    // step/2·Δrgb and its α by step/2·Δα (Δ the largest neighbour difference); the ratio
    // N/D moves by at most (Σw·δrgb + (N/D)·Σw·δα)/D with D ≥ 0.5·Σw and N/D ≤ 1.5 (the
    // colours' largest value); the lobes' weights 1 − F, 1 − F and F sum to at most 2.
    let step = FilterPrecision::SPEC_MINIMUM.sub_texel_step();
    let delta = slots
        .iter()
        .flat_map(|s| s.maps.iter())
        .map(|m| neighbour_difference(m))
        .fold(0.0, f64::max);
    let largest_ratio = 1.5;
    let per_lobe = (0.5 * step * delta * (1.0 + largest_ratio)) / 0.5;
    let tolerance = 2.0 * per_lobe + 1e-4;
    let (mut glossy, mut compared, mut worst) = (0usize, 0usize, 0f64);
    for (i, (gpu_pixel, model_pixel)) in image.pixels.iter().zip(&model.rgba).enumerate() {
        if model.depth[i] >= backdrop.depth[i] {
            continue;
        }
        glossy += 1;
        if model.exclusion[i].is_some() {
            continue;
        }
        compared += 1;
        for c in 0..4 {
            let d = (f64::from(gpu_pixel[c]) - model_pixel[c]).abs();
            worst = worst.max(d);
            assert!(
                d <= tolerance,
                "pixel {i} channel {c}: GPU {} against the model's {} (tolerance {tolerance:.2e})",
                gpu_pixel[c],
                model_pixel[c]
            );
        }
    }
    eprintln!(
        "{compared} of {glossy} sphere pixels compared: largest difference {worst:.2e}, tolerance {tolerance:.2e} (Δ {delta:.3})"
    );
    assert!(compared > 500, "{compared} sphere pixels compared");
}

/// Radiance maps in a hybrid scene: the glossy objects given maps leave the light-mapped
/// environment, maps for other objects put them back, and a frame built after the reconstruction
/// changed is not the cached one.
#[test]
fn radiance_maps_replace_light_maps_and_change_the_frame() {
    use lensmap::hybrid::{HybridOptions, HybridScene, HybridSceneOptions};
    use lensmap::rsibr::maps::all_maps;
    use lensmap::rsibr::{GlossyViews, RadianceMapOptions, Reconstruction};
    let scene = Scene::load_named("glossy-room").expect("the built-in scene");
    let (mut hybrid, _) =
        HybridScene::new(scene.clone(), HybridSceneOptions::default()).expect("a hybrid scene");
    let light_mapped = hybrid.environment().to_vec();
    let views = GlossyViews::geodesic(12).expect("12");
    let options = RadianceMapOptions {
        size: 2,
        samples: 2,
        seed: 0,
        views: 12,
    };
    let maps_of = |name: &str| {
        let object = lensmap::rsibr::glossy_objects(&scene)
            .into_iter()
            .find(|o| o.name == name)
            .expect("a glossy object");
        all_maps(hybrid.trace(), &object, &views, &options).0
    };
    let (sphere, teapot) = (maps_of("sphere"), maps_of("teapot"));
    // The environment meshes are the non-lens objects in order: the sphere is the first.
    let sphere_mesh = light_mapped[0].clone();
    hybrid.use_radiance_maps(views.clone(), vec![sphere], Reconstruction::Warped);
    assert_eq!(hybrid.environment().len(), light_mapped.len() - 1);
    assert!(
        !hybrid
            .environment()
            .iter()
            .any(|m| Arc::ptr_eq(m, &sphere_mesh))
    );
    hybrid.use_radiance_maps(views, vec![teapot], Reconstruction::Warped);
    assert_eq!(hybrid.environment().len(), light_mapped.len() - 1);
    assert!(
        Arc::ptr_eq(&hybrid.environment()[0], &sphere_mesh),
        "the sphere is light-mapped again"
    );
    assert!(
        !hybrid
            .environment()
            .iter()
            .any(|m| Arc::ptr_eq(m, &light_mapped[1])),
        "the teapot is not"
    );

    let camera = scene.camera.with_resolution(32, 24, 1);
    let rotations = |hybrid: &HybridScene| {
        let (frame, stats) = FrameBuilder::new()
            .frame(hybrid, &camera, &HybridOptions::default())
            .expect("a frame");
        assert_eq!(stats.glossy_maps, frame.glossy[0].slots.len() * 3);
        frame.glossy[0]
            .slots
            .iter()
            .map(|s| s.rotation)
            .collect::<Vec<_>>()
    };
    let warped = rotations(&hybrid);
    assert!(warped.iter().all(|r| *r == Mat3::IDENTITY));
    hybrid.set_glossy_reconstruction(Reconstruction::BlendedUnwarped);
    let unwarped = rotations(&hybrid);
    assert!(
        unwarped.iter().any(|r| *r != Mat3::IDENTITY),
        "a stale cached frame"
    );
}
