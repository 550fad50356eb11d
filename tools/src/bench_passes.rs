//! `lensmap bench passes`: compositor frame time for n = 1…4 layers, multipass vs single pass, in
//! every framebuffer format, on the synthetic scene; and the error of RGBA8 and RGBA16F against
//! RGBA32F over the lens pixels. Medians of repeated frames, all measured in one run.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    metrics::{self, Channels, Encoding, ImageError, Mask},
    render::{
        RenderedImage, Renderer, TargetFormat, Variant,
        synthetic::{SyntheticOptions, sphere_frame},
    },
    runner::FrameRunner,
};
use serde_json::json;

use crate::common::report;

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
    /// Largest layer count n (from 1).
    #[arg(long, default_value_t = 4)]
    max_layers: usize,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
}

/// Linear RGB error of `image` against `reference` over `mask`; `None` when the mask is empty
/// (the figure would measure nothing, so none is reported).
fn error(image: &RenderedImage, reference: &RenderedImage, mask: &Mask) -> Option<ImageError> {
    metrics::compare(
        &image.pixels,
        &reference.pixels,
        mask,
        Encoding::Linear,
        Channels::Rgb,
    )
    .ok()
}

/// A figure for the table: `-` where there is none.
fn figure(value: Option<f64>) -> String {
    value.map_or_else(|| "-".to_owned(), |v| format!("{v:.3e}"))
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
        args.max_layers as u64 * 2 * formats,
        "settings",
    );
    for layers in 1..=args.max_layers.max(1) {
        let frame = sphere_frame(&SyntheticOptions {
            width: args.width,
            height: args.height,
            layers,
            ..SyntheticOptions::default()
        });
        let mut uploaded = runner.upload(&frame)?;
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
            // Lens pixels: where the frame differs from the environment alone is hard to know
            // here, so compare every pixel the lens could touch: all pixels with α < 1 after the
            // environment (the lens leaves the last group's α, the environment writes α = 1).
            // An empty mask (a driver that leaves α = 1 there) gives no figure, never a zero.
            let mask = Mask::from_flags(reference.pixels.iter().map(|p| p[3] < 1.0).collect());
            for (format, image, frame_ms, execute_ms, passes) in &results {
                let error = error(image, &reference, &mask);
                let (rms, max) = (error.map(|e| e.rmse), error.map(|e| e.max_abs));
                say!(
                    "{:>2}  {:<12} {:<8} {:>11.2} {:>11.2} {:>8}  {:>12} {:>12}",
                    layers,
                    variant.name(),
                    format.name(),
                    frame_ms,
                    execute_ms,
                    passes,
                    figure(rms),
                    figure(max)
                );
                rows.push(json!({
                    "layers": layers, "variant": variant.name(), "format": format.name(),
                    "median_frame_ms": frame_ms, "median_execute_ms": execute_ms, "steps": passes,
                    "rms_vs_rgba32f": rms, "max_vs_rgba32f": max,
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
