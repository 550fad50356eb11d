//! `lensmap bench passes`: compositor frame time for n = 1…4 layers and one to three viewpoint
//! samples, multipass (with each blending scheme `--blend` asks for) vs single pass, in every
//! framebuffer format, on the synthetic scene (or on one hybrid frame of a scene, at its own
//! layer count); passes, barriers and rendering instances from each frame's plan; and the error
//! of every row against the multipass front-to-back frame in RGBA32F over the lens pixels, which
//! come from the frame's geometry ([`lensmap::render::frame_lens_pixels`]). Medians of repeated frames, all
//! measured in one run.

use lensmap::hybrid::FrameBuilder;
use std::path::PathBuf;

use clap::Args;
use glam::Vec3;
use indicatif::ProgressBar;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::HybridOptions,
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    metrics::{self, Channels, Encoding, ImageError, Mask},
    render::{
        BlendScheme, Compositing, FrameInput, RenderOptions, RenderedImage, Renderer, TargetFormat,
        Variant, frame_lens_pixels,
        synthetic::{SyntheticOptions, sphere_frame},
    },
    runner::{EmSource, FrameRunner, load_hybrid_scene},
    trace::LensSelection,
};
use serde_json::json;

use crate::common::{BadUsage, BlendArg, flag_error, parse_vec3, report};

#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap bench passes --width 640 --height 480 --report out/bench-passes.json"
)]
pub struct BenchPassesArgs {
    /// Frame width.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Frame height.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Timed frames per configuration (after one warm-up frame).
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Largest layer count n (from 1) of the synthetic sphere; with --scene, the scene's own.
    /// Range: [1, 6].
    #[arg(long, default_value_t = 4)]
    max_layers: usize,
    /// Blending schemes of the multipass rows: one scheme, or "all".
    #[arg(long, default_value = "front-to-back", value_parser = parse_blend)]
    blend: BlendChoice,
    /// Viewpoint samples of the synthetic sphere: 1, 2, 3 (inside a spherical triangle of a 2D
    /// view space), "both" (1 and 2: each layer count twice) or "all" (1, 2 and 3); a --scene
    /// frame has its own.
    #[arg(long, default_value = "2", value_parser = ["1", "2", "3", "both", "all"], conflicts_with = "scene")]
    viewpoints: String,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Instead of the synthetic sphere, one hybrid frame of this scene (built-in name or .toml;
    /// projected layered EMs, the scene's own layer count, at --width × --height).
    #[arg(long)]
    scene: Option<String>,
    /// With --scene: the camera position "x,y,z" (default: the scene camera's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    camera_position: Option<Vec3>,
    /// With --scene: the point the camera looks at, "x,y,z" (default: the scene camera's).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    look_at: Option<Vec3>,
    /// With --scene: the projected EMs' cube-map face size.
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    em_size: u32,
}

/// `--blend`: the schemes of the multipass rows.
#[derive(Clone, Debug)]
struct BlendChoice(Vec<BlendScheme>);

fn parse_blend(text: &str) -> Result<BlendChoice, String> {
    use clap::ValueEnum;
    if text == "all" {
        return Ok(BlendChoice(BlendScheme::ALL.to_vec()));
    }
    BlendArg::from_str(text, false)
        .map(|arg| BlendChoice(vec![BlendScheme::from(arg)]))
        .map_err(|_| {
            let names: Vec<&str> = BlendScheme::ALL.iter().map(|s| s.name()).collect();
            format!("give one of {} or all", names.join(", "))
        })
}

/// A frame to time, with its layer count and its blended viewpoint samples.
struct BenchFrame {
    layers: usize,
    viewpoints: usize,
    input: FrameInput,
}

/// The frames to time, one per layer count and viewpoint count: the synthetic sphere with
/// n = 1 … `max_layers`, or the scene's hybrid frame at its own layer count.
fn frames(args: &BenchPassesArgs) -> anyhow::Result<Vec<BenchFrame>> {
    let Some(name) = &args.scene else {
        let viewpoints: Vec<usize> = match args.viewpoints.as_str() {
            "1" => vec![1],
            "3" => vec![3],
            "both" => vec![1, 2],
            "all" => vec![1, 2, 3],
            _ => vec![2],
        };
        return Ok((1..=args.max_layers)
            .flat_map(|layers| viewpoints.iter().map(move |&v| (layers, v)))
            .map(|(layers, viewpoints)| {
                let input = sphere_frame(&SyntheticOptions {
                    width: args.width,
                    height: args.height,
                    layers,
                    viewpoints,
                    ..SyntheticOptions::default()
                });
                BenchFrame {
                    layers,
                    viewpoints,
                    input,
                }
            })
            .collect());
    };
    let scene = crate::common::load_scene(name)?;
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
    let (hybrid, _) = load_hybrid_scene(scene, &EmSource::Projected(projected).into())?;
    let (frame, _) = FrameBuilder::new().frame(&hybrid, &camera, &HybridOptions::default())?;
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
    let viewpoints = frame.viewpoint_weights.iter().filter(|w| **w > 0.0).count();
    Ok(vec![BenchFrame {
        layers,
        viewpoints,
        input: frame,
    }])
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
    check(&args)?;
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let frames = frames(&args)?;
    say!(
        "device: {}  ({}×{}, {} timed frames per row, median)",
        runner.gpu().device_id(),
        args.width,
        args.height,
        args.frames
    );
    say!(
        "{:>2} {:>2}  {:<12} {:<14} {:<8} {:>9} {:>9} {:>6} {:>5} {:>5}  {:>10} {:>10}",
        "n",
        "v",
        "variant",
        "blend",
        "format",
        "frame ms",
        "exec ms",
        "passes",
        "barr",
        "inst",
        "RMS vs ref",
        "max vs ref"
    );
    let mut rows = Vec::new();
    let schemes = &args.blend.0;
    // Rows per frame: each scheme of the multipass variant, then the single pass, in each format.
    let compositings: Vec<(Variant, BlendScheme)> = schemes
        .iter()
        .map(|&blend| (Variant::Multipass, blend))
        .chain(std::iter::once((
            Variant::SinglePass,
            BlendScheme::FrontToBack,
        )))
        .collect();
    let formats = TargetFormat::ALL.len() as u64;
    let bar = crate::common::Steps::new(1).counted(
        "compositor frames",
        frames.len() as u64 * compositings.len() as u64 * formats,
        "settings",
    );
    for frame in &frames {
        rows.extend(frame_rows(&mut runner, &args, frame, &compositings, &bar)?);
    }
    let out = json!({
        "device": runner.gpu().device_name(), "driver": runner.gpu().device_id().driver_description(), "width": args.width, "height": args.height,
        "frames": args.frames,
        "reference": "multipass, front-to-back, rgba32f", "rows": rows,
    });
    bar.finish_and_clear();
    report(&out, args.report.as_deref())?;
    Ok(())
}

/// The options a parser cannot check: a layer count the single pass composites, at least one
/// frame of at least 1×1 pixels.
fn check(args: &BenchPassesArgs) -> Result<(), BadUsage> {
    let most = lensmap::render::SinglePassProgram::MAX_LAYERS;
    if !(1..=most).contains(&args.max_layers) {
        return Err(BadUsage(format!(
            "--max-layers {}: give 1 to {most} (the single pass it is compared with composites at most {most})",
            args.max_layers
        )));
    }
    if args.frames == 0 || args.width == 0 || args.height == 0 {
        return Err(BadUsage(format!(
            "--frames {} --width {} --height {}: give at least one frame of at least 1×1 pixels",
            args.frames, args.width, args.height
        )));
    }
    Ok(())
}

/// The rows of one frame of `layers` layers and `viewpoints` viewpoint samples: each of
/// `compositings` in each format, timed, planned and judged against the multipass
/// front-to-back frame in RGBA32F over the lens pixels; printed, and as JSON.
fn frame_rows(
    runner: &mut FrameRunner,
    args: &BenchPassesArgs,
    bench_frame: &BenchFrame,
    compositings: &[(Variant, BlendScheme)],
    bar: &ProgressBar,
) -> anyhow::Result<Vec<serde_json::Value>> {
    let BenchFrame {
        layers,
        viewpoints,
        input: ref frame,
    } = *bench_frame;
    // The lens pixels, from the frame's geometry (the engine's rule): an empty set has no error
    // to report, so the benchmark stops rather than print a figure that measures nothing.
    let mask = Mask::lens(&frame_lens_pixels(frame), LensSelection::All);
    if mask.selected() == 0 {
        return Err(BadUsage(format!(
            "the lens objects cover no pixel of the {}×{} frame (n = {layers}), so there are no lens pixels to measure the formats' error over: aim the camera at a lens object (--camera-position, --look-at)",
            args.width, args.height
        ))
        .into());
    }
    let mut uploaded = runner.upload(frame)?;
    // The reference of every row: the paper's scheme in RGBA32F.
    let paper = RenderOptions {
        compositing: Compositing::Multipass(BlendScheme::FrontToBack),
        format: TargetFormat::Rgba32f,
        host: None,
    };
    let reference = runner.timed_renders(&mut uploaded, &paper, 1)?.image;
    let mut rows = Vec::new();
    for &(variant, blend) in compositings {
        for format in TargetFormat::ALL {
            let compositing = RenderOptions {
                compositing: Compositing::new(variant, blend)?,
                format,
                host: None,
            };
            let plan = Renderer::plan(&uploaded, &compositing)?;
            let renders = runner.timed_renders(&mut uploaded, &compositing, args.frames)?;
            let (frame_ms, execute_ms) = (
                renders.median(|t| t.record_ms + t.execute_ms),
                renders.median(|t| t.execute_ms),
            );
            let error = error(&renders.image, &reference, &mask)?;
            let (rms, max) = (error.rmse, error.max_abs);
            let (passes, barriers, instances) = (
                plan.steps.len(),
                plan.barrier_count(),
                plan.rendering_instances(),
            );
            let blend_name = match variant {
                Variant::Multipass => blend.name(),
                Variant::SinglePass => "-",
            };
            say!(
                "{:>2} {:>2}  {:<12} {:<14} {:<8} {:>9.2} {:>9.2} {:>6} {:>5} {:>5}  {:>10} {:>10}",
                layers,
                viewpoints,
                variant.name(),
                blend_name,
                format.name(),
                frame_ms,
                execute_ms,
                passes,
                barriers,
                instances,
                format!("{rms:.3e}"),
                format!("{max:.3e}")
            );
            rows.push(json!({
                "layers": layers, "viewpoints": viewpoints, "variant": variant.name(),
                "blend": blend_name, "format": format.name(),
                "median_frame_ms": frame_ms, "median_execute_ms": execute_ms, "steps": passes,
                "barriers": barriers, "rendering_instances": instances,
                "rms_vs_reference": rms, "max_vs_reference": max, "lens_pixels": mask.selected(),
            }));
            bar.inc(1);
        }
    }
    Ok(rows)
}
