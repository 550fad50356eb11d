//! `lensmap demo`: the main job on the built-in `teapot-room` scene. It builds projected layered
//! EMs, renders the hybrid frame from a novel viewpoint between two viewpoint samples with both
//! compositor variants and t = 3 and t = 5, renders the reference ray tracer at the same
//! settings, writes the images (and a side-by-side) into `out/`, and prints the paper's table,
//! the reduction factors and the PSNR over the lens pixels. `--synthetic` runs the compositor
//! alone on its synthetic sphere scene instead.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use glam::Vec3;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, HybridScene},
    layers::projected::ProjectedOptions,
    render::{RenderedImage, Renderer, TargetFormat, Variant},
    scene::{Camera, Scene},
    trace::{TraceOptions, render_reference},
};
use serde_json::json;

use crate::common::progress_bar;
use crate::render::{lens_psnr, median_stage, timed_frames, write_image};

#[derive(Args)]
pub struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Frame width (default: the scene camera's, 640).
    #[arg(long)]
    pub width: Option<u32>,
    /// Frame height (default: the scene camera's, 480).
    #[arg(long)]
    pub height: Option<u32>,
    /// Supersampling k×k (default: the scene camera's, 3).
    #[arg(long)]
    pub supersampling: Option<u32>,
    /// Projected EMs: cube-map face size in texels.
    #[arg(long, default_value_t = 128)]
    pub em_size: u32,
    /// Run the compositor-only demo on the synthetic sphere scene instead.
    #[arg(long)]
    pub synthetic: bool,
    /// Synthetic demo: layers per viewpoint sample.
    #[arg(long, default_value_t = 3)]
    pub layers: usize,
    /// Synthetic demo: timed frames per variant.
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
    /// Also write the report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The novel viewpoint of the demo: halfway (in angle) between viewpoint samples 2 and 3, so two
/// samples are blended.
pub fn novel_camera(scene: &Scene) -> Camera {
    let samples = scene.view_space.samples();
    let look_at = scene.camera.look_at;
    match (samples.get(2), samples.get(3)) {
        (Some(a), Some(b)) => {
            let (da, db) = (*a - look_at, *b - look_at);
            let direction = (da.normalize() + db.normalize()).normalize_or(da.normalize());
            scene
                .camera
                .with_position(look_at + direction * 0.5 * (da.length() + db.length()))
        }
        _ => scene.camera,
    }
}

/// Puts two equally sized images side by side.
fn side_by_side(left: &RenderedImage, right: &[Vec3]) -> RenderedImage {
    let (w, h) = (left.width, left.height);
    let mut pixels = Vec::with_capacity((2 * w * h) as usize);
    for y in 0..h as usize {
        pixels.extend_from_slice(&left.pixels[y * w as usize..(y + 1) * w as usize]);
        pixels.extend(
            right[y * w as usize..(y + 1) * w as usize]
                .iter()
                .map(|p| [p.x, p.y, p.z, 1.0]),
        );
    }
    RenderedImage {
        width: 2 * w,
        height: h,
        pixels,
    }
}

pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    if args.synthetic {
        return crate::compositor::synthetic_demo(&args);
    }
    let started = Instant::now();
    let mut scene = Scene::load_named("teapot-room")?;
    if let Some(w) = args.width {
        scene.camera.width = w;
    }
    if let Some(h) = args.height {
        scene.camera.height = h;
    }
    if let Some(k) = args.supersampling {
        scene.camera.supersampling = k;
    }
    let camera = novel_camera(&scene);
    lensmap::trace::image::validate_camera(&camera).map_err(|e| {
        crate::compositor::BadUsage(format!("--width/--height/--supersampling: {e}"))
    })?;
    // The GPU first: without a driver the demo stops here with exit code 2.
    let gpu = Gpu::new(&GpuOptions::from_env())?;
    let mut renderer = Renderer::new(&gpu)?;
    say!("device: {}", gpu.device_name());

    let prepare = Instant::now();
    let (hybrid, em_rays) = HybridScene::projected(
        scene,
        &ProjectedOptions {
            size: args.em_size,
            supersampling: 2,
        },
    )?;
    say!(
        "projected layered EMs: {} lens objects, {}² texels per face, {} rays, {:.2} s",
        hybrid.lenses.len(),
        args.em_size,
        em_rays,
        prepare.elapsed().as_secs_f64()
    );

    let bar = progress_bar(u64::from(camera.height));
    let reference = render_reference(&hybrid.trace, &camera, &TraceOptions::default(), &|rows| {
        bar.set_position(u64::from(rows))
    })?;
    bar.finish_and_clear();
    let rc = reference.stats.counters;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    reference.write(&args.out.join("teapot-room-reference"))?;

    say!(
        "teapot-room, novel view between viewpoint samples 2 and 3, {}×{} with {k}×{k} supersampling (medians of 3 frames)",
        camera.width,
        camera.height,
        k = camera.supersampling
    );
    say!(
        "{:<12} {:>3} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>11} {:>7} {:>7} {:>7} {:>8}",
        "variant",
        "t",
        "trace ms",
        "texgen",
        "tessel.",
        "other",
        "total",
        "rays",
        "tri tests",
        "×time",
        "×rays",
        "×tests",
        "PSNR dB"
    );
    let mut rows = Vec::new();
    for variant in [Variant::SinglePass, Variant::Multipass] {
        for t in [3.0f32, 5.0] {
            let options = HybridOptions {
                t,
                ..HybridOptions::default()
            };
            // The first frame compiles pipelines; then the median of three timed frames.
            let frames = timed_frames(
                &gpu,
                &mut renderer,
                &hybrid,
                &camera,
                &options,
                variant,
                TargetFormat::Rgba16f,
                (1, 3),
            )?;
            let stage = |f: &dyn Fn(&crate::render::HybridFrame) -> f64| median_stage(&frames, f);
            let (trace_ms, texgen_ms, tessellation_ms, other_ms, total_ms) = (
                stage(&|f| f.stats.trace_ms),
                stage(&|f| f.stats.texgen_ms),
                stage(&|f| f.stats.tessellation_ms),
                stage(&|f| f.other_ms()),
                stage(&|f| f.total_ms),
            );
            let frame = frames.last().context("three frames")?;
            let c = frame.stats.counters;
            let psnr = lens_psnr(&frame.image, &reference).map_or(f64::NAN, |(p, _)| p);
            let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
            let time_ratio = ratio(reference.stats.seconds * 1e3, total_ms);
            let ray_ratio = ratio(rc.all_rays() as f64, c.all_rays() as f64);
            let test_ratio = ratio(rc.triangle_tests as f64, c.triangle_tests as f64);
            say!(
                "{:<12} {:>3} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>10} {:>11} {:>7.1} {:>7.1} {:>7.1} {:>8.2}",
                variant.name(),
                t,
                trace_ms,
                texgen_ms,
                tessellation_ms,
                other_ms,
                total_ms,
                c.all_rays(),
                c.triangle_tests,
                time_ratio,
                ray_ratio,
                test_ratio,
                psnr
            );
            let stem = format!("teapot-room-hybrid-{}-t{t}", variant.name());
            write_image(&frame.image, &args.out.join(format!("{stem}.png")))?;
            if variant == Variant::SinglePass && t == 3.0 {
                write_image(
                    &side_by_side(&frame.image, &reference.radiance),
                    &args.out.join("teapot-room-side-by-side.png"),
                )?;
            }
            rows.push(json!({
                "variant": variant.name(), "t": t,
                "median_of": 3,
                "ray_tracing_at_vertices_ms": trace_ms, "texture_coordinates_ms": texgen_ms,
                "tessellation_ms": tessellation_ms, "other_ms": other_ms,
                "total_ms": total_ms, "rays": c.all_rays(), "triangle_tests": c.triangle_tests,
                "lens_triangles_out": frame.stats.triangles_out,
                "reduction_time": time_ratio, "reduction_rays": ray_ratio, "reduction_triangle_tests": test_ratio,
                "lens_psnr_db": psnr,
            }));
        }
    }
    say!(
        "reference ray tracer: {:.1} ms, {} rays, {} triangle tests ({} threads)",
        reference.stats.seconds * 1e3,
        rc.all_rays(),
        rc.triangle_tests,
        rayon::current_num_threads()
    );
    say!(
        "wrote {}/teapot-room-side-by-side.png (hybrid | reference) and the frames beside it",
        args.out.display()
    );
    let report = gpu.validation_report();
    if report.enabled {
        say!("validation messages: {}", report.messages.len());
    }
    say!("total {:.1} s", started.elapsed().as_secs_f64());
    if let Some(path) = &args.json {
        let out = json!({
            "device": gpu.device_name(), "width": camera.width, "height": camera.height,
            "supersampling": camera.supersampling, "em_size": args.em_size,
            "reference": {"ms": reference.stats.seconds * 1e3, "rays": rc.all_rays(), "triangle_tests": rc.triangle_tests},
            "rows": rows,
        });
        std::fs::write(path, serde_json::to_string_pretty(&out)?)
            .with_context(|| path.display().to_string())?;
    }
    Ok(())
}
