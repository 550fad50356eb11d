//! `lensmap bench infer`: the baker's core at one viewpoint sample. For each lens object of a
//! scene, the layered EM is inferred on the projected shells' geometry from the reference ray
//! tracer's intersection records at the scene camera, and the hybrid frames with projected and
//! with inferred EMs are compared with an independent, better-converged reference (more
//! supersamples than the targets had, so fitting the targets' own noise earns nothing). The
//! inference is repeated and its median time reported, stage by stage.

use std::{path::PathBuf, sync::Arc, time::Instant};

use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::HybridScene,
    index::LensIndex,
    layers::projected::ProjectedOptions,
    metrics::Encoding,
    runner::{EmSource, FrameOptions, FrameRunner, lens_error, load_hybrid_scene, median},
    scene::Camera,
    trace::{ReferenceImage, TraceOptions, compile_records, render_reference},
};
use lensmap_baker::infer::{
    DEFAULT_MAX_EM_SIZE, EmSize, InferOptions, Inference, View, infer_lens,
};
use serde_json::json;

use crate::common::{BadUsage, JudgeArgs, Steps, flag_error, report};
use crate::frame_args::FrameArgs;

#[derive(Args)]
#[command(
    mut_arg("format", |a| a.default_value("rgba32f")),
    mut_arg("tracer", |a| a.default_value("cpu")),
    after_help = "Example:\n  lensmap bench infer --scene glass-sphere --width 320 --height 240"
)]
pub struct BenchInferArgs {
    /// Built-in scene name or path.
    #[arg(long, default_value = "teapot-room")]
    scene: String,
    #[command(flatten)]
    judge: JudgeArgs,
    /// How the judged frames are made (RGBA32F and the CPU tracer unless asked otherwise).
    #[command(flatten)]
    frame: FrameArgs,
    /// Largest EM face size the resolution search considers (power of two).
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_MAX_EM_SIZE)]
    max_em_size: u32,
    /// Projected EMs' face size (the baseline).
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = 128)]
    em_size: u32,
    /// Confidence threshold θ_c in degrees (paper: 5).
    /// Range: (0, 180).
    #[arg(long, default_value_t = lensmap_baker::targets::DEFAULT_CONFIDENCE_DEGREES, allow_negative_numbers = true)]
    confidence_degrees: f64,
    /// The solver's iterative method.
    #[arg(long, value_enum, default_value = "cg")]
    solver: SolverArg,
    /// Relative smoothness weight of the solve.
    /// Range: [0, ∞).
    #[arg(long, default_value_t = lensmap_baker::solve::DEFAULT_SMOOTHNESS, allow_negative_numbers = true)]
    smoothness: f64,
    /// CG stops at this relative residual.
    /// Range: (0, 1).
    #[arg(long, default_value_t = lensmap_baker::solve::SolveOptions::default().tolerance, allow_negative_numbers = true)]
    tolerance: f64,
    /// Inference runs; the median time is reported.
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
}

/// `--solver`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum SolverArg {
    /// Conjugate gradient on the normal equations.
    Cg,
    /// LSQR on the least-squares system.
    Lsqr,
}

pub fn run(args: BenchInferArgs) -> anyhow::Result<()> {
    let projected = checked(&args)?;
    let frame_options = args.frame.options()?;
    let scene = crate::common::load_scene(&args.scene)?;
    let camera = args.judge.frame_camera(&scene.camera);
    let reference_camera = args.judge.reference_camera(&camera);
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let mut steps = Steps::new(4);
    let step = steps.step("projected layered EMs and light maps");
    let (mut hybrid, _) = load_hybrid_scene(scene, &EmSource::Projected(projected).into())?;
    step.finish_and_clear();
    let device = runner.gpu().device_id().clone();
    say!(
        "{}: {}×{}, targets {k}×{k}, reference {r}×{r}, device {device}",
        args.scene,
        args.judge.width,
        args.judge.height,
        k = args.judge.supersampling,
        r = args.judge.reference_supersampling
    );
    let trace_options = TraceOptions::default();
    let start = Instant::now();
    let bar = steps.counted(
        "reference ray tracer",
        u64::from(reference_camera.height),
        "rows",
    );
    let reference = render_reference(hybrid.trace(), &reference_camera, &trace_options, &|rows| {
        bar.set_position(u64::from(rows))
    })?;
    bar.finish_and_clear();
    say!("reference traced in {:.1} s", start.elapsed().as_secs_f64());
    let judge = Judge {
        camera: &camera,
        reference: &reference,
        options: &frame_options,
    };
    let (projected_srgb, projected_linear) = judge.lens_psnr(&mut runner, &hybrid)?;
    let step = steps.step("intersection records");
    let records_start = Instant::now();
    let records = compile_records(hybrid.trace(), &camera, &trace_options)?;
    step.finish_and_clear();
    let records_ms = records_start.elapsed().as_secs_f64() * 1e3;
    let options = infer_options(&args);
    let mut lenses = Vec::new();
    let mut inferred_maps = Vec::new();
    let runs = args.runs.max(1);
    let bar = steps.counted(
        "inference",
        (records.lenses.len() * runs) as u64,
        "inferences",
    );
    for (lens, lens_records) in LensIndex::all(records.lenses.len()).zip(&records.lenses) {
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..runs {
            let view = View {
                camera: &camera,
                records: lens_records,
            };
            let inference = infer_lens(&mut runner, &hybrid, lens, &[view], &options, &mut |_| {})?;
            times.push(inference.total_ms);
            last = Some(inference);
            bar.inc(1);
        }
        let Some(inference) = last else { continue };
        lenses.push(say_inference(
            &lens_records.name,
            &inference,
            times,
            args.max_em_size,
        ));
        inferred_maps.push((lens, inference.maps));
    }
    bar.finish_and_clear();
    for (lens, maps) in inferred_maps {
        hybrid.set_lens_maps(lens, vec![maps.into_iter().map(Arc::new).collect()]);
    }
    let (inferred_srgb, inferred_linear) = judge.lens_psnr(&mut runner, &hybrid)?;
    say!(
        "lens PSNR vs the {r}×{r} reference: projected {projected_srgb:.2} dB sRGB / {projected_linear:.2} dB linear; inferred {inferred_srgb:.2} dB sRGB / {inferred_linear:.2} dB linear ({:+.2} / {:+.2} dB); records {:.1} s",
        inferred_srgb - projected_srgb,
        inferred_linear - projected_linear,
        records_ms / 1e3,
        r = args.judge.reference_supersampling
    );
    report(
        &json!({
            "scene": args.scene,
            "device": device.device,
            "driver": device.driver_description(),
            "width": args.judge.width,
            "height": args.judge.height,
            "supersampling": args.judge.supersampling,
            "reference_supersampling": args.judge.reference_supersampling,
            "records_ms": records_ms,
            "lenses": lenses,
            "lens_psnr_db": {
                "projected": {"srgb": projected_srgb, "linear": projected_linear},
                "inferred": {"srgb": inferred_srgb, "linear": inferred_linear},
            },
        }),
        args.report.as_deref(),
    )?;
    Ok(())
}

/// The projected EMs' options, once every option is checked.
fn checked(args: &BenchInferArgs) -> anyhow::Result<ProjectedOptions> {
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    args.judge.validate()?;
    if !args.max_em_size.is_power_of_two() {
        return Err(BadUsage(format!(
            "--max-em-size {}: give a power of two, e.g. 256",
            args.max_em_size
        ))
        .into());
    }
    Ok(projected)
}

/// The inference's options from the command line (the rest the baker's defaults).
fn infer_options(args: &BenchInferArgs) -> InferOptions {
    InferOptions {
        em_size: EmSize::Auto {
            cap: args.max_em_size,
        },
        theta_c: args.confidence_degrees.to_radians(),
        solve: lensmap_baker::solve::SolveOptions {
            method: match args.solver {
                SolverArg::Cg => lensmap_baker::solve::SolveMethod::ConjugateGradient,
                SolverArg::Lsqr => lensmap_baker::solve::SolveMethod::Lsqr,
            },
            smoothness: args.smoothness,
            tolerance: args.tolerance,
            ..lensmap_baker::solve::SolveOptions::default()
        },
        ..InferOptions::default()
    }
}

/// The hybrid frame at the judged camera, against the reference over the lens pixels.
struct Judge<'a> {
    camera: &'a Camera,
    reference: &'a ReferenceImage,
    options: &'a FrameOptions,
}

impl Judge<'_> {
    /// Lens PSNR of `hybrid`'s frame (by default single-pass RGBA32F) in display sRGB and in
    /// linear, dB.
    fn lens_psnr(
        &self,
        runner: &mut FrameRunner,
        hybrid: &HybridScene,
    ) -> anyhow::Result<(f64, f64)> {
        let frame = runner.frame(hybrid, self.camera, self.options)?;
        Ok((
            lens_error(&frame.image, self.reference, Encoding::DisplaySrgb)?.psnr_db,
            lens_error(&frame.image, self.reference, Encoding::Linear)?.psnr_db,
        ))
    }
}

/// Says what one lens object's inference found and took (its median time over the `times` of
/// its runs, ms, which end sorted; `cap`: `--max-em-size`), layer by layer; its JSON.
fn say_inference(
    name: &str,
    inference: &Inference,
    mut times: Vec<f64>,
    cap: u32,
) -> serde_json::Value {
    let total_ms = median(&mut times);
    say!(
        "lens \"{name}\": EM {s}² (finest level read at {cap}²: {:?}; {} search renders), inference median {:.1} s of {} runs (frame {:.0} ms)",
        inference.finest_level_at_cap,
        inference.search_renders,
        total_ms / 1e3,
        times.len(),
        inference.frame_ms,
        s = inference.size,
    );
    for layer in &inference.layers {
        say!(
            "  layer {}: {} test renders, non-zeros {:?}, matrices {:.0} ms, targets {:.0} ms, solve {:.0} ms ({} iterations, residual {:.1e}, {} seen texels, {} pinned to range)",
            layer.layer,
            layer.renders,
            layer.nonzeros,
            layer.matrix_ms,
            layer.targets_ms,
            layer.solve.ms,
            layer.solve.iterations,
            layer.solve.relative_residual,
            layer.solve.seen_texels,
            layer.solve.clamped_texels
        );
    }
    json!({
        "lens": name,
        "em_size": inference.size,
        "finest_level_at_cap": inference.finest_level_at_cap,
        "search_renders": inference.search_renders,
        "median_ms": total_ms,
        "ms": times,
        "frame_ms": inference.frame_ms,
        "layers": inference.layers,
    })
}
