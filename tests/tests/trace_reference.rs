//! Reference renders of the built-in scenes: finite, non-negative, terms that add up, a lens mask
//! that matches the lens objects, and EXR/PNG files that read back.

use glam::Vec3;
use lensmap::scene::{BUILTIN_SCENES, Camera, Scene};
use lensmap::trace::{PathModel, TraceOptions, TraceScene, render_reference};

fn small(camera: Camera) -> Camera {
    Camera {
        width: 64,
        height: 48,
        supersampling: 2,
        ..camera
    }
}

#[test]
fn builtin_scenes_render_without_nan_in_both_models() {
    for name in BUILTIN_SCENES {
        let scene = Scene::load_named(name).expect("built-in scenes load");
        let world = TraceScene::new(&scene).expect("built-in scenes trace");
        let camera = small(scene.camera);
        for model in [PathModel::Greedy, PathModel::Full] {
            let options = TraceOptions {
                model,
                ..TraceOptions::default()
            };
            let image = render_reference(&world, &camera, &options, &|_| {}).unwrap();
            let pixels = (camera.width * camera.height) as usize;
            assert_eq!(image.radiance.len(), pixels);
            for buffer in [&image.radiance, &image.refraction, &image.reflection] {
                assert!(
                    buffer
                        .iter()
                        .all(|p| p.is_finite() && p.min_element() >= 0.0),
                    "{name} {model:?}: NaN, Inf or negative radiance"
                );
            }
            assert!(image.lens_mask.iter().all(|m| (0.0..=1.0).contains(m)));
            let lens_pixels: f32 = image.lens_mask.iter().sum();
            assert!(
                lens_pixels > 0.02 * pixels as f32,
                "{name}: the lens objects cover only {lens_pixels} pixels"
            );
            // Where a pixel sees only lens objects, the final image is the sum of the terms.
            for i in 0..pixels {
                if image.lens_mask[i] == 1.0 {
                    let sum = image.refraction[i] + image.reflection[i];
                    assert!(
                        (image.radiance[i] - sum).abs().max_element()
                            <= 1e-5 * (1.0 + sum.max_element())
                    );
                }
                if image.lens_mask[i] == 0.0 {
                    assert_eq!(image.refraction[i], Vec3::ZERO);
                    assert_eq!(image.reflection[i], Vec3::ZERO);
                }
            }
            let mean = image.radiance.iter().sum::<Vec3>() / pixels as f32;
            assert!(
                mean.max_element() > 0.01,
                "{name} {model:?} is black: {mean}"
            );
            let counters = image.stats.counters;
            assert_eq!(counters.primary_rays, pixels as u64 * 4);
            assert!(counters.secondary_rays > 0 && counters.triangle_tests > counters.all_rays());
        }
    }
}

#[test]
fn the_full_tree_costs_more_rays_than_the_greedy_paths_and_stays_close() {
    let scene = Scene::load_named("glass-sphere").unwrap();
    let world = TraceScene::new(&scene).unwrap();
    let camera = Camera {
        width: 48,
        height: 36,
        supersampling: 1,
        ..scene.camera
    };
    let render = |model| {
        let options = TraceOptions {
            model,
            ..TraceOptions::default()
        };
        render_reference(&world, &camera, &options, &|_| {}).unwrap()
    };
    let greedy = render(PathModel::Greedy);
    let full = render(PathModel::Full);
    let (g, f) = (greedy.stats.counters, full.stats.counters);
    assert!(
        f.secondary_rays * 10 > g.secondary_rays * 13,
        "{f:?} vs {g:?}"
    );
    // Same camera rays, same environment: identical off the sphere.
    for i in 0..greedy.radiance.len() {
        if greedy.lens_mask[i] == 0.0 {
            assert_eq!(greedy.radiance[i], full.radiance[i]);
        }
    }
    // Each greedy path is one branch of the full tree (the sphere floats free, so leaving the lens
    // object and leaving into the world are the same): the tree adds the branches the greedy
    // paths drop, pixel by pixel, and stays within a few percent on average.
    for i in 0..greedy.radiance.len() {
        let (g, f) = (greedy.radiance[i], full.radiance[i]);
        assert!(
            (f - g * (1.0 - 1e-5)).min_element() >= -1e-6,
            "pixel {i}: full {f} below greedy {g}"
        );
    }
    let mean = |v: &[Vec3]| v.iter().map(|p| p.element_sum()).sum::<f32>() / v.len() as f32;
    let (g, f) = (mean(&greedy.radiance), mean(&full.radiance));
    assert!(f >= g && f <= g * 1.1, "greedy {g}, full {f}");
}

#[test]
fn reference_images_are_written_as_exr_and_png() {
    let scene = Scene::load_named("mirror-teapot").unwrap();
    let world = TraceScene::new(&scene).unwrap();
    let camera = Camera {
        width: 20,
        height: 15,
        supersampling: 1,
        ..scene.camera
    };
    let image = render_reference(&world, &camera, &TraceOptions::default(), &|_| {}).unwrap();
    let directory = std::env::temp_dir().join(format!("lensmap-trace-{}", std::process::id()));
    let written = image.write(&directory).unwrap();
    assert_eq!(written.paths.len(), 8);
    for path in &written.paths {
        let bytes = std::fs::read(path).unwrap();
        assert!(bytes.len() > 16, "{} is empty", path.display());
        let magic: &[u8] = if path.extension().is_some_and(|e| e == "png") {
            b"\x89PNG"
        } else {
            &[0x76, 0x2f, 0x31, 0x01]
        };
        assert_eq!(&bytes[..4], magic, "{}", path.display());
    }
    std::fs::remove_dir_all(&directory).ok();
}
