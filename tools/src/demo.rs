//! `lensmap demo`: the main job on the built-in `teapot-room` scene. It bakes inferred layered
//! EMs at the two viewpoint samples a novel viewpoint lies between (cached in `out/bake`, reused
//! while the scene and the bake options are unchanged: the bake's provenance is the key), builds
//! projected layered EMs beside them, renders the hybrid frame from that viewpoint with both
//! kinds of EMs, both compositor variants and t = 3 and t = 5, renders the reference ray tracer
//! at the same settings, writes the images (and a side-by-side: inferred | projected | reference)
//! into `out/`, and prints the paper's table, the reduction factors and the PSNR over the lens
//! pixels. `--synthetic` runs the compositor
//! alone on its synthetic sphere scene instead.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, HybridScene, VertexTracer},
    layers::{
        Bake,
        projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    },
    metrics::Encoding,
    render::{
        BlendScheme, Compositing, PassCategory, RenderedImage, SinglePassProgram, TargetFormat,
        Variant, synthetic,
    },
    runner::{
        EmSource, FrameOptions, FrameRunner, HybridFrame, Repetitions, TimedFrames, lens_error,
        load_hybrid_scene, novel_camera,
    },
    scene::{Camera, Scene},
    trace::{ReferenceImage, TraceOptions, render_reference},
};
use lensmap_baker::bake::{BakeJob, BakeOptions, bake, reuse};
use serde_json::json;

use crate::common::{BadUsage, Steps, beside, flag_error, reference_frame, report};

#[derive(Args)]
#[command(after_help = "Examples:
  lensmap demo                       (bakes into out/bake on the first run, then reuses it)
  lensmap demo --json > demo.json    (the report as JSON, nothing else on stdout)
  lensmap demo --synthetic --report out/synthetic.json")]
pub struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Frame width (default: the scene camera's, 640).
    /// Range: [1, 16384].
    #[arg(long)]
    pub width: Option<u32>,
    /// Frame height (default: the scene camera's, 480).
    /// Range: [1, 16384].
    #[arg(long)]
    pub height: Option<u32>,
    /// Supersampling k×k (default: the scene camera's, 3). Not for --synthetic.
    /// Range: [1, 16384].
    #[arg(long, conflicts_with = "synthetic")]
    pub supersampling: Option<u32>,
    /// Projected EMs: cube-map face size in texels. Not for --synthetic.
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_EM_SIZE, conflicts_with = "synthetic")]
    pub em_size: u32,
    /// Run the compositor-only demo on the synthetic sphere scene instead.
    #[arg(long)]
    pub synthetic: bool,
    /// Synthetic demo: layers per viewpoint sample.
    /// Range: [1, 256].
    #[arg(long, default_value_t = 3)]
    pub layers: usize,
    /// Synthetic demo: timed frames per variant.
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
    /// Where the lens vertices of the hybrid frames are ray traced. Not for --synthetic.
    #[arg(long, value_enum, default_value = "auto", conflicts_with = "synthetic")]
    pub tracer: crate::common::TracerArg,
    /// How the GPU tracer finds a ray's hits (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "auto", conflicts_with = "synthetic")]
    pub traversal: crate::common::TraversalArg,
    /// What the GPU tracer computes in (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "f32", conflicts_with = "synthetic")]
    pub gpu_precision: crate::common::GpuPrecisionArg,
    /// Also write the report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    if args.synthetic {
        return synthetic_demo(&args);
    }
    let started = Instant::now();
    let (scene, camera, projected) = checked(&args)?;
    if crate::common::validate_only() {
        return Ok(());
    }
    // The GPU first: without a driver the demo stops here with exit code 2.
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    runner.check_framebuffer(&camera, TargetFormat::Rgba16f)?;
    let tracer = VertexTracer::from(args.tracer);
    let walk = crate::common::gpu_walk(
        runner.gpu(),
        &HybridOptions {
            tracer,
            traversal: args.traversal.into(),
            ..HybridOptions::default()
        },
    );
    say!(
        "device: {}; lens vertices traced on the {}",
        runner.gpu().device_id(),
        walk.map_or_else(|| "CPU".to_owned(), |walk| format!("GPU ({walk} walk)"))
    );

    let mut steps = Steps::new(5);
    let inferred = inferred_scene(
        &mut runner,
        &scene,
        &camera,
        &args.out.join(BAKE_CACHE),
        &mut steps,
    )?;
    let hybrid = projected_scene(scene, projected, args.em_size, &mut steps)?;
    let reference = reference(&hybrid, &camera, &args.out, &mut steps)?;
    let rc = reference.stats.counters;
    let table = Table {
        camera: &camera,
        reference: &reference,
        out: &args.out,
        tracer,
        traversal: args.traversal.into(),
        gpu_precision: args.gpu_precision.into(),
    };
    let (rows, mut side_by_side) = table.rows(
        &mut runner,
        [("inferred", &inferred), ("projected", &hybrid)],
        &mut steps,
    )?;
    let step = steps.step("side-by-side image");
    side_by_side.push(reference_frame(&reference));
    beside(&side_by_side)?.write_png_and_exr(&args.out.join("teapot-room-side-by-side.png"))?;
    step.finish_and_clear();
    say!(
        "PSNR dB: display sRGB clamped to [0, 1] over the lens pixels (every subpixel's camera ray hits the same lens object first); lin. dB: linear HDR, unclamped"
    );
    say!(
        "reference ray tracer: {:.1} ms, {} rays, {} triangle tests ({} threads)",
        reference.stats.seconds * 1e3,
        rc.all_rays(),
        rc.triangle_tests,
        rayon::current_num_threads()
    );
    say!(
        "wrote {}/teapot-room-side-by-side.png (inferred | projected | reference, single pass, t = 3) and the frames beside it",
        args.out.display()
    );
    let validation = runner.gpu().validation_report();
    if validation.enabled {
        say!("validation messages: {}", validation.messages.len());
    }
    say!("total {:.1} s", started.elapsed().as_secs_f64());
    let out = json!({
        "device": runner.gpu().device_name(), "driver": runner.gpu().device_id().driver_description(), "width": camera.width, "height": camera.height,
        "supersampling": camera.supersampling, "em_size": args.em_size,
        "tracer": args.tracer.name(), "traced_on_gpu": tracer.on_gpu(runner.gpu()), "walk": walk,
        "reference": {"ms": reference.stats.seconds * 1e3, "rays": rc.all_rays(), "triangle_tests": rc.triangle_tests},
        "rows": rows,
        "side_by_side": args.out.join("teapot-room-side-by-side.png"),
        "seconds": started.elapsed().as_secs_f64(),
    });
    report(&out, args.report.as_deref())
}

/// The options checked: teapot-room with the camera at its novel viewpoint (`--width`,
/// `--height`, `--supersampling` applied), and the projected EMs' options.
fn checked(args: &DemoArgs) -> anyhow::Result<(Scene, Camera, ProjectedOptions)> {
    let mut scene = crate::common::load_scene("teapot-room")?;
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
    lensmap::trace::image::validate_camera(&camera)
        .map_err(|e| BadUsage(format!("--width/--height/--supersampling: {e}")))?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    Ok((scene, camera, projected))
}

/// The hybrid scene with projected layered EMs of `em_size`² texels per face; says how many
/// lens objects and rays they took.
fn projected_scene(
    scene: Scene,
    projected: ProjectedOptions,
    em_size: u32,
    steps: &mut Steps,
) -> anyhow::Result<HybridScene> {
    let step = steps.step("projected layered EMs and light maps");
    let prepare = Instant::now();
    let (hybrid, em_rays) = load_hybrid_scene(scene, &EmSource::Projected(projected).into())?;
    step.finish_and_clear();
    say!(
        "projected layered EMs: {} lens objects, {}² texels per face, {} rays, {:.2} s",
        hybrid.lenses().len(),
        em_size,
        em_rays,
        prepare.elapsed().as_secs_f64()
    );
    Ok(hybrid)
}

/// The reference ray tracer's image at `camera`, written into `out` (created).
fn reference(
    hybrid: &HybridScene,
    camera: &Camera,
    out: &Path,
    steps: &mut Steps,
) -> anyhow::Result<ReferenceImage> {
    let bar = steps.counted("reference ray tracer", u64::from(camera.height), "rows");
    let reference = render_reference(hybrid.trace(), camera, &TraceOptions::default(), &|rows| {
        bar.set_position(u64::from(rows))
    })?;
    bar.finish_and_clear();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    reference.write(&out.join("teapot-room-reference"))?;
    Ok(reference)
}

/// The paper's table: hybrid frames judged against the reference ray tracer at one camera,
/// their images written into `out`.
struct Table<'a> {
    camera: &'a Camera,
    reference: &'a ReferenceImage,
    out: &'a Path,
    /// Where the lens vertices are traced.
    tracer: VertexTracer,
    /// How the GPU tracer finds a ray's hits.
    traversal: lensmap::hybrid::gpu::Traversal,
    /// What the GPU tracer computes in.
    gpu_precision: lensmap::hybrid::paths::VertexPrecision,
}

impl Table<'_> {
    /// Every row: each scene's EMs with both variants at t = 3 and t = 5, printed after the
    /// table's header; the JSON rows, and the single-pass t = 3 frames for the side-by-side.
    fn rows(
        &self,
        runner: &mut FrameRunner,
        scenes: [(&str, &HybridScene); 2],
        steps: &mut Steps,
    ) -> anyhow::Result<(Vec<serde_json::Value>, Vec<RenderedImage>)> {
        say!(
            "teapot-room, novel view between viewpoint samples 2 and 3, {}×{} with {k}×{k} supersampling (medians of 3 frames)",
            self.camera.width,
            self.camera.height,
            k = self.camera.supersampling
        );
        say!(
            "{:<10} {:<12} {:>3} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>11} {:>7} {:>7} {:>7} {:>8} {:>8}",
            "EMs",
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
            "PSNR dB",
            "lin. dB"
        );
        let mut rows = Vec::new();
        let mut side_by_side = Vec::new();
        let bar = steps.counted("hybrid frames", 8, "settings");
        for (ems, hybrid) in scenes {
            for variant in [Variant::SinglePass, Variant::Multipass] {
                for t in [3.0f32, 5.0] {
                    let options = FrameOptions {
                        hybrid: HybridOptions {
                            tracer: self.tracer,
                            traversal: self.traversal,
                            gpu_precision: self.gpu_precision,
                            ..HybridOptions::with_t(t)
                        },
                        compositing: Compositing::new(variant, BlendScheme::FrontToBack)
                            .expect("front to back is every variant's"),
                        format: TargetFormat::Rgba16f,
                    };
                    // The first frame compiles pipelines; then the median of three timed frames.
                    let repetitions = Repetitions {
                        warmup: 1,
                        timed: 3,
                    };
                    let frames = runner.timed_frames(hybrid, self.camera, &options, repetitions)?;
                    rows.push(self.row(&frames, ems, variant, t)?);
                    if variant == Variant::SinglePass && t == 3.0 {
                        side_by_side.push(frames.last().image.clone());
                    }
                    bar.inc(1);
                }
            }
        }
        bar.finish_and_clear();
        Ok((rows, side_by_side))
    }

    /// One row: the median stage times of `frames`, the last frame's counters and lens PSNR,
    /// and the reductions against the reference ray tracer; printed, the last image written
    /// into `out`, and the JSON row.
    fn row(
        &self,
        frames: &TimedFrames,
        ems: &str,
        variant: Variant,
        t: f32,
    ) -> anyhow::Result<serde_json::Value> {
        let stage = |f: &dyn Fn(&HybridFrame) -> f64| frames.median(f);
        let (trace_ms, texgen_ms, tessellation_ms, other_ms, total_ms) = (
            stage(&|f| f.stats.trace_ms),
            stage(&|f| f.stats.texgen_ms),
            stage(&|f| f.stats.tessellation_ms),
            stage(&|f| f.other_ms()),
            stage(&|f| f.total_ms),
        );
        let frame = frames.last();
        let c = frame.stats.counters;
        let rc = self.reference.stats.counters;
        // Display sRGB, clamped, and beside it the linear figure that also counts errors in
        // highlights above 1.
        let psnr = |encoding| {
            lens_error(&frame.image, self.reference, encoding).map_or(f64::NAN, |e| e.psnr_db)
        };
        let (psnr_display, psnr_linear) = (psnr(Encoding::DisplaySrgb), psnr(Encoding::Linear));
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        let time_ratio = ratio(self.reference.stats.seconds * 1e3, total_ms);
        let ray_ratio = ratio(rc.all_rays() as f64, c.all_rays() as f64);
        let test_ratio = ratio(rc.triangle_tests as f64, c.triangle_tests as f64);
        say!(
            "{:<10} {:<12} {:>3} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>10} {:>11} {:>7.1} {:>7.1} {:>7.1} {:>8.2} {:>8.2}",
            ems,
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
            psnr_display,
            psnr_linear
        );
        let stem = format!("teapot-room-hybrid-{ems}-{}-t{t}", variant.name());
        frame
            .image
            .write_png_and_exr(&self.out.join(format!("{stem}.png")))?;
        Ok(json!({
            "ems": ems, "variant": variant.name(), "t": t,
            "median_of": 3,
            "ray_tracing_at_vertices_ms": trace_ms, "texture_coordinates_ms": texgen_ms,
            "tessellation_ms": tessellation_ms, "other_ms": other_ms,
            "total_ms": total_ms, "rays": c.all_rays(), "triangle_tests": c.triangle_tests,
            "lens_triangles_out": frame.stats.triangles_out,
            "reduction_time": time_ratio, "reduction_rays": ray_ratio, "reduction_triangle_tests": test_ratio,
            "lens_psnr_db": psnr_display,
            "lens_psnr_linear_db": psnr_linear,
        }))
    }
}

/// The hybrid scene with EMs inferred at the two viewpoint samples `camera` lies between (the
/// two nearest by angle), baked into `dir` unless a bake there already holds them for this scene
/// and these options (its provenance says so): the first demo bakes, later ones reuse it.
fn inferred_scene(
    runner: &mut FrameRunner,
    scene: &Scene,
    camera: &lensmap::scene::Camera,
    dir: &std::path::Path,
    steps: &mut Steps,
) -> anyhow::Result<HybridScene> {
    let positions: Vec<glam::DVec3> = scene
        .view_space
        .samples()
        .iter()
        .map(|p| p.as_dvec3())
        .collect();
    let blend = lensmap::hybrid::viewpoints::blend(
        &positions,
        camera.look_at.as_dvec3(),
        camera.position.as_dvec3(),
    )
    .map_or_else(|| vec![0], |b| b.samples.iter().map(|(i, _)| *i).collect());
    let mut samples = blend;
    samples.sort_unstable();
    let options = bake_options(camera);
    let cached = reuse::check(dir, scene, &options, &samples).is_ok();
    let start = Instant::now();
    if cached {
        say!(
            "inferred layered EMs: samples {samples:?} cached in {}",
            dir.display()
        );
        steps
            .step("inferred layered EMs (cached)")
            .finish_and_clear();
    } else {
        let step = steps.step(&format!(
            "baking inferred layered EMs at samples {samples:?} (once; cached)"
        ));
        say!(
            "inferred layered EMs: baking samples {samples:?} into {} (cached for the next run)",
            dir.display()
        );
        let bars = crate::bake::BakeBars::new(samples.len());
        let job = BakeJob {
            dir,
            samples: &samples,
            options: &options,
            resume: true,
        };
        bake(runner, scene, &job, &mut |progress| bars.show(progress))?;
        bars.finish();
        step.finish_and_clear();
    }
    let ems = lensmap::hybrid::LayeredEms::Baked(Bake::read(dir)?);
    let (hybrid, _) = HybridScene::new(scene.clone(), ems.into())?;
    say!(
        "inferred layered EMs ready in {:.1} s",
        start.elapsed().as_secs_f64()
    );
    Ok(hybrid)
}

/// `lensmap demo --synthetic`: the compositor alone on the synthetic sphere scene with both
/// variants; writes PNG and EXR, prints pass counts, median frame times and the variants'
/// difference.
fn synthetic_demo(args: &DemoArgs) -> anyhow::Result<()> {
    let (width, height) = (args.width.unwrap_or(640), args.height.unwrap_or(480));
    if width == 0
        || height == 0
        || args.layers == 0
        || args.layers > SinglePassProgram::MAX_LAYERS
        || args.frames == 0
    {
        return Err(BadUsage(format!(
            "--width/--height must be ≥ 1, --layers within 1..={} and --frames ≥ 1 (got {}×{}, {} layers, {} frames)",
            SinglePassProgram::MAX_LAYERS,
            width,
            height,
            args.layers,
            args.frames
        ))
        .into());
    }
    if crate::common::validate_only() {
        return Ok(());
    }
    let started = Instant::now();
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    say!("device: {}", runner.gpu().device_id());
    let frame = synthetic::sphere_frame(&synthetic::SyntheticOptions {
        width,
        height,
        layers: args.layers,
        ..synthetic::SyntheticOptions::default()
    });
    let mut uploaded = runner.upload(&frame)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let format = TargetFormat::Rgba32f;
    let mut images = Vec::new();
    let mut rows = Vec::new();
    let mut steps = Steps::new(2);
    for variant in [Variant::Multipass, Variant::SinglePass] {
        let step = steps.step(&format!("{} frames", variant.name()));
        let compositing = lensmap::render::RenderOptions {
            compositing: Compositing::new(variant, BlendScheme::FrontToBack)
                .expect("front to back is every variant's"),
            format,
            host: None,
        };
        let plan = lensmap::render::Renderer::plan(&uploaded, &compositing)?;
        let renders = runner.timed_renders(&mut uploaded, &compositing, args.frames)?;
        let stem = format!("demo-{}", variant.name());
        renders
            .image
            .write_png_and_exr(&args.out.join(format!("{stem}.png")))?;
        say!(
            "{:<12} {} prime + {} layer + {} alpha-clear + {} single-pass passes, median frame {:.2} ms → {}/{stem}.png, .exr",
            variant.name(),
            plan.count(PassCategory::Prime),
            plan.count(PassCategory::Layer),
            plan.count(PassCategory::AlphaClear),
            plan.count(PassCategory::SinglePass),
            renders.median(|t| t.record_ms + t.execute_ms),
            args.out.display()
        );
        rows.push(json!({
            "variant": variant.name(), "prime": plan.count(PassCategory::Prime), "layer": plan.count(PassCategory::Layer),
            "alpha_clear": plan.count(PassCategory::AlphaClear), "single_pass": plan.count(PassCategory::SinglePass),
            "median_frame_ms": renders.median(|t| t.record_ms + t.execute_ms),
            "png": args.out.join(format!("{stem}.png")), "exr": args.out.join(format!("{stem}.exr")),
        }));
        images.push(renders.image);
        step.finish_and_clear();
    }
    let difference = images[0].max_abs_difference(&images[1])?;
    say!(
        "single-pass vs multipass ({}): max |difference| {difference:.3e}",
        format.name()
    );
    let validation = runner.gpu().validation_report();
    if validation.enabled {
        say!("validation messages: {}", validation.messages.len());
    }
    say!("total {:.2} s", started.elapsed().as_secs_f64());
    let out = json!({
        "device": runner.gpu().device_name(), "driver": runner.gpu().device_id().driver_description(), "width": width, "height": height,
        "layers": args.layers, "frames": args.frames, "format": format.name(),
        "variants": rows, "single_pass_vs_multipass_max_difference": difference,
    });
    report(&out, args.report.as_deref())
}

/// Where the demo caches its inferred layered EMs, under its `--out` folder (`out/bake` by
/// default): `lensmap view` looks for a reusable bake there too.
pub const BAKE_CACHE: &str = "bake";

/// The bake options of the demo's cached bake for `camera`: its size and supersampling, no
/// judge. A bake is reused only when its provenance names exactly these.
pub fn bake_options(camera: &lensmap::scene::Camera) -> BakeOptions {
    BakeOptions {
        width: camera.width,
        height: camera.height,
        supersampling: camera.supersampling,
        judge: false,
        ..BakeOptions::default()
    }
}
