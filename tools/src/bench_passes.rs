//! `lensmap bench passes`: compositor frame time for n = 1…4 layers, multipass vs single pass, in
//! every framebuffer format, on the synthetic scene; and the error of RGBA8 and RGBA16F against
//! RGBA32F over the lens pixels. Medians of repeated frames, all measured in one run.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    render::{
        RenderedImage, Renderer, TargetFormat, Variant,
        synthetic::{SyntheticOptions, sphere_frame},
    },
};
use serde_json::json;

use crate::common::median;
use crate::compositor::max_difference;

#[derive(Args)]
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
    /// Where to write the JSON results.
    #[arg(long, default_value = "out/bench-passes.json")]
    json: PathBuf,
}

/// Mean-square and largest difference over the pixels where `mask` holds.
fn error(a: &RenderedImage, reference: &RenderedImage, mask: &[bool]) -> (f64, f64) {
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut max: f64 = 0.0;
    for ((p, q), m) in a.pixels.iter().zip(&reference.pixels).zip(mask) {
        if !m {
            continue;
        }
        for c in 0..3 {
            let d = f64::from(p[c] - q[c]);
            sum += d * d;
            max = max.max(d.abs());
            count += 1;
        }
    }
    ((sum / count.max(1) as f64).sqrt(), max)
}

pub fn run(args: BenchPassesArgs) -> anyhow::Result<()> {
    let gpu = Gpu::new(&GpuOptions::from_env())?;
    let mut renderer = Renderer::new(&gpu)?;
    println!(
        "device: {}  ({}×{}, {} timed frames per row, median)",
        gpu.device_name(),
        args.width,
        args.height,
        args.frames
    );
    println!(
        "{:>2}  {:<12} {:<8} {:>11} {:>11} {:>8}  {:>12} {:>12}",
        "n", "variant", "format", "frame ms", "execute ms", "passes", "RMS vs f32", "max vs f32"
    );
    let mut rows = Vec::new();
    for layers in 1..=args.max_layers.max(1) {
        let frame = sphere_frame(&SyntheticOptions {
            width: args.width,
            height: args.height,
            layers,
            ..SyntheticOptions::default()
        });
        let mut uploaded = renderer.upload(&gpu, &frame)?;
        let mut by_variant = Vec::new();
        for variant in [Variant::Multipass, Variant::SinglePass] {
            let mut results: Vec<(TargetFormat, RenderedImage, f64, f64, usize)> = Vec::new();
            for format in TargetFormat::ALL {
                let plan = Renderer::plan(&uploaded, variant, format)?;
                let passes = plan.steps.len();
                let (image, _) = renderer.render(&gpu, &mut uploaded, variant, format)?;
                let mut frame_ms = Vec::new();
                let mut execute_ms = Vec::new();
                for _ in 0..args.frames.max(1) {
                    let (_, t) = renderer.render(&gpu, &mut uploaded, variant, format)?;
                    frame_ms.push(t.record_ms + t.execute_ms);
                    execute_ms.push(t.execute_ms);
                }
                results.push((
                    format,
                    image,
                    median(&mut frame_ms),
                    median(&mut execute_ms),
                    passes,
                ));
            }
            let reference = results
                .iter()
                .find(|r| r.0 == TargetFormat::Rgba32f)
                .map(|r| r.1.clone())
                .context("rgba32f result")?;
            // Lens pixels: where the frame differs from the environment alone is hard to know
            // here, so compare every pixel the lens could touch: all pixels with α < 1 after the
            // environment (the lens leaves the last group's α, the environment writes α = 1).
            let mask: Vec<bool> = reference.pixels.iter().map(|p| p[3] < 1.0).collect();
            for (format, image, frame_ms, execute_ms, passes) in &results {
                let (rms, max) = error(image, &reference, &mask);
                println!(
                    "{:>2}  {:<12} {:<8} {:>11.2} {:>11.2} {:>8}  {:>12.3e} {:>12.3e}",
                    layers,
                    variant.name(),
                    format.name(),
                    frame_ms,
                    execute_ms,
                    passes,
                    rms,
                    max
                );
                rows.push(json!({
                    "layers": layers, "variant": variant.name(), "format": format.name(),
                    "median_frame_ms": frame_ms, "median_execute_ms": execute_ms, "steps": passes,
                    "rms_vs_rgba32f": rms, "max_vs_rgba32f": max,
                }));
            }
            by_variant.push(reference);
        }
        let difference = max_difference(&by_variant[0], &by_variant[1]);
        println!(
            "    n = {layers}: single-pass vs multipass in rgba32f, max |difference| {difference:.3e}"
        );
        rows.push(json!({"layers": layers, "single_pass_vs_multipass_rgba32f_max": difference}));
    }
    let out = json!({
        "device": gpu.device_name(), "width": args.width, "height": args.height,
        "frames": args.frames, "rows": rows,
    });
    if let Some(parent) = args.json.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    std::fs::write(&args.json, serde_json::to_string_pretty(&out)?)
        .with_context(|| args.json.display().to_string())?;
    println!("wrote {}", args.json.display());
    Ok(())
}
