//! `lensmap bench glossy`: reflection-space IBR judged against the reference ray tracer. For
//! each glossy scene, material and glossy object, cameras look at the object on a view sample,
//! inside a spherical triangle and on an edge; each camera's frame is reconstructed three ways
//! (three warped maps blended, the nearest map unwarped, three maps blended unwarped) and
//! compared over the object's pixels with a converged reference (its Monte Carlo error stated).
//! Then the number of view samples (12, 42, 162) against the warped reconstruction's error.

use lensmap::hybrid::FrameBuilder;
use std::time::Instant;

use clap::Args;
use glam::{DVec3, Vec3};
use lensmap::metrics::{Channels, Encoding, Mask, compare};
use lensmap::rsibr::maps::all_maps;
use lensmap::rsibr::{
    GlossyMaps, GlossyObject, GlossyShading, GlossyViews, RadianceMapOptions, Reconstruction,
    glossy_objects, shade,
};
use lensmap::scene::{Camera, Material, Scene};
use lensmap::trace::image::{camera_ray, subsample_position};
use lensmap::trace::{TraceCounters, TraceOptions, TraceScene, render_reference};
use rayon::prelude::*;
use serde_json::{Value, json};

use crate::common::{BadUsage, report};

#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap bench glossy --scenes glossy-studio --width 160 --height 120"
)]
pub struct BenchGlossyArgs {
    /// Glossy scenes (built-in names or paths), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = lensmap::scene::GLOSSY_SCENES.map(String::from))]
    scenes: Vec<String>,
    /// View-sample counts compared (geodesic: 12, 42, 162).
    /// Range: one of 12, 42, 162.
    #[arg(long, value_delimiter = ',', default_values_t = [12, 42, 162])]
    views: Vec<usize>,
    /// Radiance maps' face size, texels (as `bake --radiance-maps` takes).
    /// Range: [1, 1024].
    #[arg(long, default_value_t = lensmap::rsibr::maps::DEFAULT_MAP_SIZE,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(crate::bake_radiance::MAX_MAP_SIZE)))]
    map_size: u32,
    /// Directions sampled per map texel.
    /// Range: [2, 65536].
    #[arg(long, default_value_t = lensmap::rsibr::maps::DEFAULT_MAP_SAMPLES,
          value_parser = clap::value_parser!(u32).range(2..))]
    map_samples: u32,
    /// Directions sampled per pixel by the reference.
    /// Range: [2, 1048576].
    #[arg(long, default_value_t = 2048)]
    reference_samples: u32,
    /// Frame width, pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 160)]
    width: u32,
    /// Frame height, pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 120)]
    height: u32,
    /// Camera distance from the object's centre, metres.
    /// Range: (0, 100000].
    #[arg(long, default_value_t = 2.0)]
    distance: f64,
    /// Frames rendered per variant for the glossy pass's time (0: no timing).
    /// Range: [0, 100000].
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Width of the timed frames, pixels (the height is 3/4 of it).
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640)]
    frame_width: u32,
    /// Also write the JSON results to this file.
    #[arg(long)]
    report: Option<std::path::PathBuf>,
}

/// Where the cameras of one object sit, as directions from its centre.
struct Placements {
    /// `(name, direction)`: on a sample, inside a triangle, on an edge.
    cameras: Vec<(&'static str, DVec3)>,
}

/// The three cameras: the 12-sample view space's sample nearest to "up and in front", the
/// centroid of its triangle facing that way most, and the midpoint of that triangle's edge from
/// the sample (all above the horizon, so room cameras stay inside the room).
fn placements(views: &GlossyViews) -> Placements {
    let toward = DVec3::new(0.0, 0.5, 1.0).normalize();
    let d = views.directions();
    let sample = (0..d.len())
        .max_by(|&a, &b| d[a].dot(toward).total_cmp(&d[b].dot(toward)))
        .expect("samples");
    let triangle = views
        .triangles()
        .iter()
        .filter(|t| t.contains(&sample))
        .max_by(|a, b| {
            let c = |t: &[usize; 3]| (d[t[0]] + d[t[1]] + d[t[2]]).normalize().dot(toward);
            c(a).total_cmp(&c(b))
        })
        .expect("a triangle at every sample");
    let other = triangle
        .iter()
        .copied()
        .filter(|&v| v != sample)
        .max_by(|&a, &b| d[a].dot(toward).total_cmp(&d[b].dot(toward)))
        .expect("two other vertices");
    Placements {
        cameras: vec![
            ("on a sample", d[sample]),
            (
                "inside a triangle",
                (d[triangle[0]] + d[triangle[1]] + d[triangle[2]]).normalize(),
            ),
            ("on an edge", (d[sample] + d[other]).normalize()),
        ],
    }
}

/// A camera at `distance` from `object` along `direction`, looking at its centre.
fn camera_for(base: &Camera, object: &GlossyObject, direction: DVec3, distance: f64) -> Camera {
    let up = if direction.y.abs() > 0.95 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    Camera {
        position: (object.centre + direction * distance).as_vec3(),
        look_at: object.centre.as_vec3(),
        up,
        ..*base
    }
}

/// The reconstructed frame: per pixel whose centre ray meets `object` first, its RSIBR shading;
/// `None` elsewhere.
fn reconstruct(
    trace: &TraceScene,
    camera: &Camera,
    maps: &GlossyMaps,
    views: &GlossyViews,
    reconstruction: Reconstruction,
) -> Vec<Option<Vec3>> {
    let object = &maps.object;
    let view = camera.position.as_dvec3() - object.centre;
    let slots = views
        .slots(view, reconstruction)
        .expect("a camera off the centre");
    let shading = GlossyShading {
        brdf: object.brdf,
        lobes: object.lobes.clone(),
        slots: slots
            .iter()
            .map(|s| (s.weight, s.rotation, maps.maps[s.sample].clone()))
            .collect(),
    };
    (0..camera.width * camera.height)
        .into_par_iter()
        .map(|i| {
            let (x, y) = subsample_position(i % camera.width, i / camera.width, 0, 0, 1);
            let ray = camera_ray(camera, x, y);
            let mut counters = TraceCounters::default();
            let hit = trace.closest_hit(&ray, None, None, &mut counters)?;
            (hit.hit.object == object.object)
                .then(|| shade(&shading, hit.hit.shading_normal, -ray.direction).as_vec3())
        })
        .collect()
}

/// The scene with `material` on every glossy object.
fn with_material(scene: &Scene, material: usize) -> Scene {
    let mut scene = scene.clone();
    for object in &mut scene.objects {
        if matches!(scene.materials[object.material], Material::Glossy(_)) {
            object.material = material;
        }
    }
    scene
}

/// Every glossy material of `scene` (used by an object or not), by index, named by its lobes.
fn materials(scene: &Scene) -> Vec<(usize, String)> {
    scene
        .materials
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match m {
            Material::Glossy(g) => Some((
                i,
                match g.coat {
                    Some(c) => format!(
                        "coat (ior {}, c = {}) over Phong m = {}",
                        c.ior, c.exponent, g.exponent
                    ),
                    None => format!("Phong m = {}", g.exponent),
                },
            )),
            _ => None,
        })
        .collect()
}

/// Runs `lensmap bench glossy`.
pub fn run(args: BenchGlossyArgs) -> anyhow::Result<()> {
    for &count in &args.views {
        if GlossyViews::geodesic(count).is_none() {
            return Err(BadUsage(format!(
                "--views {count}: give geodesic counts (12, 42, 162)"
            ))
            .into());
        }
    }
    if crate::common::validate_only() {
        for scene_name in &args.scenes {
            crate::common::load_scene(scene_name)?;
        }
        return Ok(());
    }
    let mut results = Vec::new();
    let mut timings = Vec::new();
    for scene_name in &args.scenes {
        let base = crate::common::load_scene(scene_name)?;
        if args.frames > 0 {
            timings.push(frame_time(&args, &base)?);
        }
        for (material, material_name) in materials(&base) {
            let scene = with_material(&base, material);
            results.push(bench_scene(&args, &scene, &material_name)?);
        }
    }
    let document = json!({ "frame_time": timings, "results": results });
    report(&document, args.report.as_deref())?;
    Ok(())
}

/// One scene with one material on its glossy objects.
fn bench_scene(args: &BenchGlossyArgs, scene: &Scene, material: &str) -> anyhow::Result<Value> {
    let trace = TraceScene::new(scene)?;
    let base_camera = scene.camera.with_resolution(args.width, args.height, 1);
    let reference_options = TraceOptions {
        glossy_samples: args.reference_samples,
        ..TraceOptions::default()
    };
    let mut objects_out = Vec::new();
    for object in glossy_objects(scene) {
        let mut by_views = Vec::new();
        let mut cameras_out = Vec::new();
        let twelve = GlossyViews::geodesic(12).expect("12");
        let cameras: Vec<(&str, Camera)> = placements(&twelve)
            .cameras
            .into_iter()
            .map(|(name, d)| (name, camera_for(&base_camera, &object, d, args.distance)))
            .collect();
        let references = cameras
            .iter()
            .map(|(_, camera)| render_reference(&trace, camera, &reference_options, &|_| {}))
            .collect::<Result<Vec<_>, _>>()?;
        // The reference's own noise: a second reference with another seed against it.
        let second_options = TraceOptions {
            glossy_seed: reference_options.glossy_seed ^ 0x5eed,
            ..reference_options
        };
        let noise = cameras
            .iter()
            .zip(&references)
            .map(|((_, camera), reference)| {
                let second = render_reference(&trace, camera, &second_options, &|_| {})?;
                let mask = image_mask(&trace, camera, &object);
                Ok(compare(
                    &second.radiance,
                    &reference.radiance,
                    &mask,
                    Encoding::DisplaySrgb,
                    Channels::Rgb,
                )?
                .psnr_db)
            })
            .collect::<anyhow::Result<Vec<f64>>>()?;
        for &count in &args.views {
            let views = GlossyViews::geodesic(count).expect("checked");
            let options = RadianceMapOptions {
                size: args.map_size,
                samples: args.map_samples,
                seed: 0,
                views: count,
            };
            let start = Instant::now();
            let (maps, counters) = all_maps(&trace, &object, &views, &options);
            let map_seconds = start.elapsed().as_secs_f64();
            let mut psnrs = Vec::new();
            for (((name, camera), reference), noise) in cameras.iter().zip(&references).zip(&noise)
            {
                let mut settings = serde_json::Map::new();
                for reconstruction in Reconstruction::ALL {
                    if count != 12 && reconstruction != Reconstruction::Warped {
                        continue;
                    }
                    let image = reconstruct(&trace, camera, &maps, &views, reconstruction);
                    let mask = Mask::from_flags(image.iter().map(Option::is_some).collect());
                    let pixels: Vec<Vec3> = image.iter().map(|p| p.unwrap_or(Vec3::ZERO)).collect();
                    let error = compare(
                        &pixels,
                        &reference.radiance,
                        &mask,
                        Encoding::DisplaySrgb,
                        Channels::Rgb,
                    )?;
                    if reconstruction == Reconstruction::Warped {
                        psnrs.push(error.psnr_db);
                    }
                    settings.insert(
                        reconstruction.name().into(),
                        json!({ "psnr_db": error.psnr_db, "pixels": error.pixels }),
                    );
                }
                if count == 12 {
                    say!(
                        "{} / {material} / {}: {name}: warped {:.2} dB, nearest unwarped {:.2} dB, blended unwarped {:.2} dB (two reference seeds: {:.2} dB)",
                        scene.name,
                        object.name,
                        psnr_of(&settings, "warped"),
                        psnr_of(&settings, "nearest-unwarped"),
                        psnr_of(&settings, "blended-unwarped"),
                        noise
                    );
                    cameras_out.push(json!({ "camera": name, "settings": settings, "two_seed_reference_psnr_db": noise }));
                }
            }
            let mean = psnrs.iter().sum::<f64>() / psnrs.len() as f64;
            say!(
                "{} / {material} / {}: {count} views: warped {:.2} dB mean over the three cameras (maps {:.1} s, {} rays)",
                scene.name,
                object.name,
                mean,
                map_seconds,
                counters.all_rays()
            );
            by_views.push(json!({ "views": count, "warped_psnr_db": psnrs, "mean_psnr_db": mean, "map_seconds": map_seconds, "rays": counters.all_rays() }));
        }
        objects_out.push(json!({ "object": object.name, "lobes": object.lobes.iter().map(|l| l.name()).collect::<Vec<_>>(), "cameras": cameras_out, "views": by_views }));
    }
    Ok(json!({
        "scene": scene.name,
        "material": material,
        "width": args.width,
        "height": args.height,
        "map_size": args.map_size,
        "map_samples": args.map_samples,
        "reference_samples": args.reference_samples,
        "objects": objects_out,
    }))
}

fn psnr_of(settings: &serde_json::Map<String, Value>, name: &str) -> f64 {
    settings[name]["psnr_db"].as_f64().unwrap_or(f64::NAN)
}

/// The object's pixels (centre ray meets it first).
fn image_mask(trace: &TraceScene, camera: &Camera, object: &GlossyObject) -> Mask {
    Mask::from_flags(
        (0..camera.width * camera.height)
            .map(|i| {
                let (x, y) = subsample_position(i % camera.width, i / camera.width, 0, 0, 1);
                let ray = camera_ray(camera, x, y);
                let mut counters = TraceCounters::default();
                trace
                    .closest_hit(&ray, None, None, &mut counters)
                    .is_some_and(|h| h.hit.object == object.object)
            })
            .collect(),
    )
}

/// The glossy pass's device time in `scene` (its own materials, 12 view samples, the scene
/// camera at `--frame-width`, one sample per pixel): the frame with its glossy draws against the
/// same frame without them, alternating, medians of `--frames` each; for the warped blend of
/// three samples and for the nearest sample alone (a third of the maps read per fragment).
fn frame_time(args: &BenchGlossyArgs, scene: &Scene) -> anyhow::Result<Value> {
    use lensmap::gpu::{Gpu, GpuOptions};
    use lensmap::render::{FrameInput, RenderOptions, Renderer};
    use lensmap::runner::{EmSource, load_hybrid_scene, median};
    let trace = TraceScene::new(scene)?;
    let views = GlossyViews::geodesic(12).expect("12");
    let options = RadianceMapOptions {
        size: args.map_size,
        samples: args.map_samples,
        seed: 0,
        views: 12,
    };
    let maps: Vec<GlossyMaps> = glossy_objects(scene)
        .iter()
        .map(|object| all_maps(&trace, object, &views, &options).0)
        .collect();
    let (mut hybrid, _) = load_hybrid_scene(
        scene.clone(),
        &EmSource::Projected(lensmap::layers::projected::ProjectedOptions::default()).into(),
    )?;
    hybrid.use_radiance_maps(views, maps, Reconstruction::Warped);
    let camera = scene
        .camera
        .with_resolution(args.frame_width, args.frame_width * 3 / 4, 1);
    let gpu = Gpu::new(&GpuOptions::from_env())?;
    let device = gpu.device_id().clone();
    let mut renderer = Renderer::new(&gpu)?;
    let mut out = serde_json::Map::new();
    for reconstruction in [Reconstruction::Warped, Reconstruction::NearestUnwarped] {
        hybrid.set_glossy_reconstruction(reconstruction);
        let (with, stats) = FrameBuilder::new().frame(
            &hybrid,
            &camera,
            &lensmap::hybrid::HybridOptions::default(),
        )?;
        let without = FrameInput {
            glossy: Vec::new(),
            ..with.clone()
        };
        let mut uploaded = [
            renderer.upload(&gpu, &with)?,
            renderer.upload(&gpu, &without)?,
        ];
        let render_options = RenderOptions::default();
        let (mut times, mut images) = ([Vec::new(), Vec::new()], [None, None]);
        // A warm-up of each, then A B B A … so that drift in the machine's speed cancels.
        for round in 0..=args.frames {
            let order = if round % 2 == 0 { [0, 1] } else { [1, 0] };
            for k in order {
                let (image, timing) = renderer.render(&gpu, &mut uploaded[k], &render_options)?;
                if round > 0 {
                    times[k].push(timing.execute_ms);
                }
                images[k] = Some(image);
            }
        }
        let glossy_pixels = match (&images[0], &images[1]) {
            (Some(a), Some(b)) => a
                .pixels
                .iter()
                .zip(&b.pixels)
                .filter(|(p, q)| p != q)
                .count(),
            _ => 0,
        };
        let [with_ms, without_ms] = [median(&mut times[0]), median(&mut times[1])];
        let pass_ms = with_ms - without_ms;
        say!(
            "{}: {} at {}×{}: frame {with_ms:.2} ms with the glossy pass, {without_ms:.2} ms without: the pass {pass_ms:.2} ms for {glossy_pixels} pixels ({:.1} ns each), {} maps read over the glossy objects; {device}",
            scene.name,
            reconstruction.name(),
            camera.width,
            camera.height,
            pass_ms * 1e6 / glossy_pixels.max(1) as f64,
            stats.glossy_maps
        );
        out.insert(
            reconstruction.name().into(),
            json!({
                "frame_ms": with_ms,
                "without_glossy_ms": without_ms,
                "glossy_pass_ms": pass_ms,
                "glossy_pixels": glossy_pixels,
                "maps_read": stats.glossy_maps,
                "frames": args.frames,
            }),
        );
    }
    Ok(json!({
        "scene": scene.name,
        "device": device.device,
        "driver": device.driver_description(),
        "width": camera.width,
        "height": camera.height,
        "times": out,
    }))
}
