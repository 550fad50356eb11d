//! `lensmap bench passes`: compositor frame time for n = 1…4 layers, multipass vs single pass, in
//! every framebuffer format, on the synthetic scene (or on one hybrid frame of a scene, at its own
//! layer count); and the error of RGBA8 and RGBA16F against RGBA32F over the lens pixels, which
//! come from the geometry ([`FrameRunner::lens_coverage`]). Medians of repeated frames, all
//! measured in one run.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use glam::Vec3;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::HybridOptions,
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    metrics::{self, Channels, Encoding, ImageError, Mask},
    render::{
        FrameInput, RenderedImage, Renderer, TargetFormat, Variant,
        synthetic::{SyntheticOptions, sphere_frame},
    },
    runner::{EmSource, FrameRunner, load_hybrid_scene},
    scene::Scene,
};
use serde_json::json;

use crate::common::{BadUsage, flag_error, parse_vec3, report};

#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap bench passes --width 640 --height 480 --report out/bench-passes.json"
)]
pub struct BenchPassesArgs {
    /// Frame width.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Timed frames per configuration (after one warm-up frame).
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Largest layer count n (from 1) of the synthetic sphere; with --scene, the scene's own.
    #[arg(long, default_value_t = 4)]
    max_layers: usize,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Instead of the synthetic sphere, one hybrid frame of this scene (built-in name or .toml;
    /// projected layered EMs, the scene's own layer count, at --width × --height).
    #[arg(long)]
    scene: Option<String>,
    /// With --scene: the camera position "x,y,z" (default: the scene camera's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, requires = "scene")]
    camera_position: Option<Vec3>,
    /// With --scene: the point the camera looks at, "x,y,z" (default: the scene camera's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, requires = "scene")]
    look_at: Option<Vec3>,
    /// With --scene: the projected EMs' cube-map face size.
    #[arg(long, default_value_t = DEFAULT_EM_SIZE, requires = "scene")]
    em_size: u32,
}

/// The frames to time, one per layer count: the synthetic sphere with n = 1 … `max_layers`, or
/// the scene's hybrid frame at its own layer count.
fn frames(args: &BenchPassesArgs) -> anyhow::Result<Vec<(usize, FrameInput)>> {
    let Some(name) = &args.scene else {
        return Ok((1..=args.max_layers)
            .map(|layers| {
                let frame = sphere_frame(&SyntheticOptions {
                    width: args.width,
                    height: args.height,
                    layers,
                    ..SyntheticOptions::default()
                });
                (layers, frame)
            })
            .collect());
    };
    let scene = Scene::load_named(name)?;
    let mut camera = scene.camera;
    (camera.width, camera.height, camera.supersampling) = (args.width, args.height, 1);
    camera.position = args.camera_position.unwrap_or(camera.position);
    camera.look_at = args.look_at.unwrap_or(camera.look_at);
    lensmap::trace::image::validate_camera(&camera).map_err(|error| {
        BadUsage(format!(
            "--camera-position / --look-at: {error}; give a position and a look-at point apart"
        ))
    })?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    let (hybrid, _) = load_hybrid_scene(scene, &EmSource::Projected(projected))?;
    let (frame, _) = hybrid.frame(&camera, &HybridOptions::default())?;
    let layers = frame
        .lenses
        .iter()
        .map(|lens| lens.layer_count())
        .max()
        .unwrap_or(0);
    let most = lensmap::render::SinglePassProgram::MAX_LAYERS;
    if layers > most {
        return Err(BadUsage(format!(
            "--scene {name}: its lens objects have {layers} layers; the single pass this benchmark compares with composites at most {most}: give a scene with fewer shells"
        ))
        .into());
    }
    Ok(vec![(layers, frame)])
}

/// Linear RGB error of `image` against `reference` over `mask` (an empty mask is an error).
fn error(
    image: &RenderedImage,
    reference: &RenderedImage,
    mask: &Mask,
) -> Result<ImageError, metrics::MetricsError> {
    metrics::compare(
        &image.pixels,
        &reference.pixels,
        mask,
        Encoding::Linear,
        Channels::Rgb,
    )
}

pub fn run(args: BenchPassesArgs) -> anyhow::Result<()> {
    let most = lensmap::render::SinglePassProgram::MAX_LAYERS;
    if !(1..=most).contains(&args.max_layers) {
        return Err(crate::common::BadUsage(format!(
            "--max-layers {}: give 1 to {most} (the single pass it is compared with composites at most {most})",
            args.max_layers
        ))
        .into());
    }
    if args.frames == 0 || args.width == 0 || args.height == 0 {
        return Err(crate::common::BadUsage(format!(
            "--frames {} --width {} --height {}: give at least one frame of at least 1×1 pixels",
            args.frames, args.width, args.height
        ))
        .into());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let frames = frames(&args)?;
    say!(
        "device: {}  ({}×{}, {} timed frames per row, median)",
        runner.gpu().device_name(),
        args.width,
        args.height,
        args.frames
    );
    say!(
        "{:>2}  {:<12} {:<8} {:>11} {:>11} {:>8}  {:>12} {:>12}",
        "n",
        "variant",
        "format",
        "frame ms",
        "execute ms",
        "passes",
        "RMS vs f32",
        "max vs f32"
    );
    let mut rows = Vec::new();
    let formats = TargetFormat::ALL.len() as u64;
    let bar = crate::common::Steps::new(1).counted(
        "compositor frames",
        frames.len() as u64 * 2 * formats,
        "settings",
    );
    for (layers, frame) in &frames {
        let layers = *layers;
        // The lens pixels, from the geometry: an empty set has no error to report, so the
        // benchmark stops rather than print a figure that measures nothing.
        let mask = runner.lens_coverage(frame)?;
        if mask.selected() == 0 {
            return Err(BadUsage(format!(
                "the lens objects cover no pixel of the {}×{} frame (n = {layers}), so there are no lens pixels to measure the formats' error over: aim the camera at a lens object (--camera-position, --look-at)",
                args.width, args.height
            ))
            .into());
        }
        let mut uploaded = runner.upload(frame)?;
        let mut by_variant = Vec::new();
        for variant in [Variant::Multipass, Variant::SinglePass] {
            let mut results: Vec<(TargetFormat, RenderedImage, f64, f64, usize)> = Vec::new();
            for format in TargetFormat::ALL {
                let plan = Renderer::plan(&uploaded, variant, format)?;
                let passes = plan.steps.len();
                let renders = runner.timed_renders(&mut uploaded, variant, format, args.frames)?;
                let (frame_ms, execute_ms) = (
                    renders.median(|t| t.record_ms + t.execute_ms),
                    renders.median(|t| t.execute_ms),
                );
                results.push((format, renders.image, frame_ms, execute_ms, passes));
                bar.inc(1);
            }
            let reference = results
                .iter()
                .find(|r| r.0 == TargetFormat::Rgba32f)
                .map(|r| r.1.clone())
                .context("rgba32f result")?;
            for (format, image, frame_ms, execute_ms, passes) in &results {
                let error = error(image, &reference, &mask)?;
                let (rms, max) = (error.rmse, error.max_abs);
                say!(
                    "{:>2}  {:<12} {:<8} {:>11.2} {:>11.2} {:>8}  {:>12} {:>12}",
                    layers,
                    variant.name(),
                    format.name(),
                    frame_ms,
                    execute_ms,
                    passes,
                    format!("{rms:.3e}"),
                    format!("{max:.3e}")
                );
                rows.push(json!({
                    "layers": layers, "variant": variant.name(), "format": format.name(),
                    "median_frame_ms": frame_ms, "median_execute_ms": execute_ms, "steps": passes,
                    "rms_vs_rgba32f": rms, "max_vs_rgba32f": max, "lens_pixels": mask.selected(),
                }));
            }
            by_variant.push(reference);
        }
        let difference = by_variant[0].max_abs_difference(&by_variant[1])?;
        say!(
            "    n = {layers}: single-pass vs multipass in rgba32f, max |difference| {difference:.3e}"
        );
        rows.push(json!({"layers": layers, "single_pass_vs_multipass_rgba32f_max": difference}));
    }
    let out = json!({
        "device": runner.gpu().device_name(), "width": args.width, "height": args.height,
        "frames": args.frames, "rows": rows,
    });
    bar.finish_and_clear();
    report(&out, args.report.as_deref())?;
    Ok(())
}
