//! `lensmap demo` and `lensmap passes`: the compositor on the built-in synthetic scene, and its
//! pass plans for experiments.

use std::time::Instant;

use anyhow::Context;
use clap::{Args, ValueEnum};
use lensmap::trace::Term;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    render::{
        FrameShape, RenderedImage, Renderer, SinglePassProgram, TargetFormat, Variant,
        plan::frame_graph,
        synthetic::{SyntheticOptions, sphere_frame},
    },
};
use serde_json::json;

use crate::common::median;

/// A usage error the parser cannot catch (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadUsage(pub String);

/// `--variant`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VariantArg {
    /// The paper's 4n-pass scheme.
    Multipass,
    /// One draw per lens object.
    SinglePass,
}

impl From<VariantArg> for Variant {
    fn from(v: VariantArg) -> Variant {
        match v {
            VariantArg::Multipass => Variant::Multipass,
            VariantArg::SinglePass => Variant::SinglePass,
        }
    }
}

/// `--format`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FormatArg {
    /// 8-bit unorm.
    Rgba8,
    /// 16-bit float.
    Rgba16f,
    /// 32-bit float.
    Rgba32f,
}

impl From<FormatArg> for TargetFormat {
    fn from(f: FormatArg) -> TargetFormat {
        match f {
            FormatArg::Rgba8 => TargetFormat::Rgba8,
            FormatArg::Rgba16f => TargetFormat::Rgba16f,
            FormatArg::Rgba32f => TargetFormat::Rgba32f,
        }
    }
}

#[derive(Args)]
pub struct PassesArgs {
    /// Layers n per viewpoint sample.
    #[arg(long, default_value_t = 3)]
    layers: usize,
    /// Viewpoint samples blended (1 when the camera sits on a sample, else 2).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    viewpoints: u8,
    /// Shading terms: 2 (glass: refraction and reflection) or 1 (mirror: reflection only).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    terms: u8,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "multipass")]
    variant: VariantArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba8")]
    format: FormatArg,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
}

/// Prints the plan of one lens object's frame.
pub fn passes(args: PassesArgs) -> anyhow::Result<()> {
    let terms: &[Term] = if args.terms == 2 {
        &[Term::Refraction, Term::Reflection]
    } else {
        &[Term::Reflection]
    };
    let shape = FrameShape::synthetic(640, 480, args.layers, args.viewpoints as usize, terms);
    let variant = Variant::from(args.variant);
    let format = TargetFormat::from(args.format);
    let (graph, _) = frame_graph(&shape, variant, format)
        .map_err(|error| BadUsage(format!("--layers {}: {error}", args.layers)))?;
    let plan = graph.compile()?;
    let counts = json!({
        "prime": plan.count("prime"),
        "layer": plan.count("layer"),
        "alpha_clear": plan.count("alpha-clear"),
        "single_pass": plan.count("single-pass"),
        "environment": plan.count("environment"),
        "rendering_instances": plan.rendering_instances(),
        "barriers": plan.barrier_count(),
    });
    if args.json {
        let steps: Vec<_> = plan
            .steps
            .iter()
            .map(|s| {
                let key = s.pass.pipeline_key(&plan.images);
                json!({
                    "pass": s.pass.name,
                    "category": s.pass.category,
                    "draws": s.pass.draw_count(),
                    "blend": key.map(|k| k.blend.to_string()),
                    "write_mask": key.map(|k| k.write_mask.to_string()),
                    "barriers": s.barriers.len(),
                })
            })
            .collect();
        let out = json!({
            "layers": args.layers, "viewpoints": args.viewpoints, "terms": args.terms,
            "variant": variant.name(), "format": format.name(), "counts": counts, "steps": steps,
            "culled": plan.culled.iter().map(|(n, r)| json!({"pass": n, "reason": r.to_string()})).collect::<Vec<_>>(),
        });
        say!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print!("{plan}");
        say!(
            "{} lens passes: {} prime + {} layer + {} alpha clear + {} single-pass; {} rendering instance(s), {} barrier(s)",
            variant.name(),
            counts["prime"],
            counts["layer"],
            counts["alpha_clear"],
            counts["single_pass"],
            counts["rendering_instances"],
            counts["barriers"]
        );
    }
    Ok(())
}

/// Largest per-channel difference between two frames.
pub fn max_difference(a: &RenderedImage, b: &RenderedImage) -> f64 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| f64::from((p[c] - q[c]).abs())))
        .fold(0.0, f64::max)
}

/// Renders the synthetic scene with both variants, writes PNG and EXR, prints counts and times.
pub fn synthetic_demo(args: &crate::demo::DemoArgs) -> anyhow::Result<()> {
    let (width, height) = (args.width.unwrap_or(640), args.height.unwrap_or(480));
    if width == 0 || height == 0 || args.layers == 0 || args.layers > SinglePassProgram::MAX_LAYERS
    {
        return Err(BadUsage(format!(
            "--width/--height must be ≥ 1 and --layers within 1..={} (got {}×{}, {} layers)",
            SinglePassProgram::MAX_LAYERS,
            width,
            height,
            args.layers
        ))
        .into());
    }
    let started = Instant::now();
    let gpu = Gpu::new(&GpuOptions::from_env())?;
    say!("device: {}", gpu.device_name());
    let frame = sphere_frame(&SyntheticOptions {
        width,
        height,
        layers: args.layers,
        ..SyntheticOptions::default()
    });
    let mut renderer = Renderer::new(&gpu)?;
    let mut uploaded = renderer.upload(&gpu, &frame)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let format = TargetFormat::Rgba32f;
    let mut images = Vec::new();
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let plan = Renderer::plan(&uploaded, variant, format)?;
        // Warm-up frame: the first frame after creating a pipeline pays for shader compilation.
        let (image, _) = renderer.render(&gpu, &mut uploaded, variant, format)?;
        let mut times: Vec<f64> = Vec::new();
        for _ in 0..args.frames.max(1) {
            let (_, timings) = renderer.render(&gpu, &mut uploaded, variant, format)?;
            times.push(timings.record_ms + timings.execute_ms);
        }
        let stem = format!("demo-{}", variant.name());
        crate::render::write_image(&image, &args.out.join(format!("{stem}.png")))?;
        say!(
            "{:<12} {} prime + {} layer + {} alpha-clear + {} single-pass passes, median frame {:.2} ms → {}/{stem}.png, .exr",
            variant.name(),
            plan.count("prime"),
            plan.count("layer"),
            plan.count("alpha-clear"),
            plan.count("single-pass"),
            median(&mut times),
            args.out.display()
        );
        images.push(image);
    }
    say!(
        "single-pass vs multipass ({}): max |difference| {:.3e}",
        format.name(),
        max_difference(&images[0], &images[1])
    );
    let report = gpu.validation_report();
    if report.enabled {
        say!("validation messages: {}", report.messages.len());
    }
    say!("total {:.2} s", started.elapsed().as_secs_f64());
    Ok(())
}
