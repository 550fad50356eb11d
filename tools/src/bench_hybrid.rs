//! `lensmap bench hybrid`: where a hybrid frame's time goes, per stage, as medians over repeated
//! frames, single pass vs multipass measured in the same run; then a still camera against a
//! moving one, latency against throughput with two frames in flight, and the thread scaling of
//! the CPU stages (1, 2 and all threads). With `--fresnel table:N`, also exact Fresnel against
//! the table, frames alternating. Then each stage for the papers' greedy terms and for 3, 4 and 6
//! path classes (traced by the CPU tracer, then by the GPU tracer; composited by the multipass
//! variant and by the single pass), frames alternating,
//! with what each stage is expected to scale by: the layer passes, the ray segments traced and
//! the vertices.

use std::path::PathBuf;

use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{
        FresnelModel, HybridOptions, HybridScene, ShadingTerms, VertexTracer, gpu::Traversal,
        paths::VertexPrecision,
    },
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    render::{BlendScheme, Compositing, TargetFormat, Variant},
    runner::{
        EmSource, FrameOptions, FrameRunner, HybridFrame, Repetitions, load_hybrid_scene, median,
        novel_camera,
    },
    scene::{Camera, Scene},
    trace::classes::ClassSet,
};
use serde_json::json;

use crate::common::{BadUsage, Steps, flag_error, report};
use crate::frame_args::FrameArgs;

#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap bench hybrid --scene teapot-room --width 640 --height 480 --t 3 --report out/bench-hybrid.json"
)]
pub struct BenchHybridArgs {
    /// Built-in scene name or path.
    #[arg(long, default_value = "teapot-room")]
    scene: String,
    /// Frame width.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Frame height.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Supersampling k×k of the framebuffer.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 1)]
    supersampling: u32,
    /// How the frames are made (`--tracer`: where the per-stage table and the camera runs trace
    /// the lens vertices; a last part times the CPU and the GPU alternately whatever it says).
    #[command(flatten)]
    frame: FrameArgs,
    /// Projected EMs: cube-map face size.
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    em_size: u32,
    /// Timed frames per variant (after two warm-up frames).
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Also write the JSON results to this file (--json prints them on stdout).
    /// Range: [1, 100000].
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
}

pub fn run(args: BenchHybridArgs) -> anyhow::Result<()> {
    let (frame_options, projected, scene, camera) = checked(&args)?;
    if crate::common::validate_only() {
        return Ok(());
    }
    let hybrid_options = frame_options.hybrid;
    // The device and the framebuffer's fit first: refused before the scene's preparation.
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let format = frame_options.format;
    runner.check_framebuffer(&camera, format)?;
    let with_table = args.frame.fresnel != FresnelModel::Exact;
    let mut steps = Steps::new(if with_table { 9 } else { 8 });
    let step = steps.step("projected layered EMs and light maps");
    let (hybrid, _) = load_hybrid_scene(scene, &EmSource::Projected(projected).into())?;
    step.finish_and_clear();
    say!(
        "device: {}  {} {}×{} ({}×{} supersampling), t = {}, {}, vertices traced on the {}, {} rayon threads, medians of {} frames",
        runner.gpu().device_id(),
        hybrid.scene().name,
        args.width,
        args.height,
        camera.supersampling,
        camera.supersampling,
        args.frame.t,
        format.name(),
        crate::common::gpu_walk(runner.gpu(), &hybrid_options)
            .map_or_else(|| "CPU".to_owned(), |walk| format!("GPU ({walk} walk)")),
        rayon::current_num_threads(),
        args.frames
    );
    let threads = rayon::current_num_threads();
    let bench = Bench {
        hybrid: &hybrid,
        camera,
        frames: args.frames,
    };
    let step = steps.step("per-stage medians, single pass and multipass");
    let rows = bench.stages(&mut runner, hybrid_options, format)?;
    // The rest composites as the flags say: the single pass, the runtime's default, unless
    // --variant asks otherwise.
    let options = frame_options;
    step.finish_and_clear();
    let still = bench.still_camera(&mut runner, &options, &mut steps)?;
    let moving = bench.moving_camera(&mut runner, &options, &mut steps)?;
    let scaling = bench.thread_scaling(&mut runner, &options, threads, &mut steps)?;
    let fresnel = if with_table {
        let exact = FrameOptions {
            hybrid: HybridOptions {
                fresnel: FresnelModel::Exact,
                ..options.hybrid
            },
            ..options
        };
        let what = format!("Fresnel exact vs {}", args.frame.fresnel.name());
        let settings = [("exact", &exact), ("table", &options)];
        Some(bench.alternating(&mut runner, &what, settings, &mut steps)?)
    } else {
        None
    };
    let on = |tracer| FrameOptions {
        hybrid: HybridOptions {
            tracer,
            ..options.hybrid
        },
        ..options
    };
    let (cpu, gpu) = (on(VertexTracer::Cpu), on(VertexTracer::Gpu));
    let tracers = bench.alternating(
        &mut runner,
        "vertex tracing on the CPU vs the GPU",
        [("cpu", &cpu), ("gpu", &gpu)],
        &mut steps,
    )?;
    let gpu_stages = bench.gpu_stages(&mut runner, &gpu, &mut steps)?;
    // The GPU tracer's variants, each against its default where the device has it: the
    // driver's walk (ray queries) and f64 (shaderFloat64), alternately, with their stages.
    let (ray_queries, float64) = (runner.gpu().ray_queries(), runner.gpu().shader_float64());
    let variant = |traversal, gpu_precision| FrameOptions {
        hybrid: HybridOptions {
            traversal,
            gpu_precision,
            ..gpu.hybrid
        },
        ..gpu
    };
    let default = variant(Traversal::Bvh, VertexPrecision::F32);
    let mut against = |offered: bool, what: &str, names: (&str, &str), other: FrameOptions| {
        if !offered {
            return Ok::<_, anyhow::Error>(serde_json::Value::Null);
        }
        let settings = [(names.0, &default), (names.1, &other)];
        let timed = bench.alternating(&mut runner, what, settings, &mut steps)?;
        let stages = bench.gpu_stages(&mut runner, &other, &mut steps)?;
        Ok(json!({"alternating": timed, "gpu_stages": stages}))
    };
    let walks = against(
        ray_queries,
        "the GPU tracer's BVH walk vs the driver's acceleration structures",
        ("bvh", "driver"),
        variant(Traversal::Driver, VertexPrecision::F32),
    )?;
    let precisions = against(
        float64,
        "the GPU tracer in f32 vs f64",
        ("f32", "f64"),
        variant(Traversal::Bvh, VertexPrecision::F64),
    )?;
    let classes = bench.classes(&mut runner, &options, VertexTracer::Cpu, &mut steps)?;
    let gpu_classes = bench.classes(&mut runner, &options, VertexTracer::Gpu, &mut steps)?;

    let out = json!({
        "device": runner.gpu().device_name(), "driver": runner.gpu().device_id().driver_description(), "scene": hybrid.scene().name, "width": args.width, "height": args.height,
        "supersampling": camera.supersampling, "t": args.frame.t, "format": format.name(),
        "threads": threads, "frames": args.frames, "rows": rows,
        "still_camera": still, "moving_camera": moving, "thread_scaling": scaling,
        "fresnel": args.frame.fresnel.name(), "fresnel_against_exact": fresnel,
        "tracer": args.frame.tracer.name(), "traced_on_gpu": hybrid_options.tracer.on_gpu(runner.gpu()),
        "walk": crate::common::gpu_walk(runner.gpu(), &hybrid_options),
        "cpu_against_gpu_tracer": tracers, "gpu_stages": gpu_stages, "bvh_against_driver_walk": walks,
        "f32_against_f64": precisions, "path_classes": classes,
        "path_classes_gpu_tracer": gpu_classes,
    });
    report(&out, args.report.as_deref())?;
    Ok(())
}

/// The options checked, and the scene with the camera the frames are rendered from (its novel
/// viewpoint at `--width` × `--height` and `--supersampling`).
fn checked(
    args: &BenchHybridArgs,
) -> anyhow::Result<(FrameOptions, ProjectedOptions, Scene, Camera)> {
    let options = args.frame.options()?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    if args.width == 0 || args.height == 0 {
        return Err(BadUsage(format!(
            "--width {} --height {}: give a frame of at least 1×1 pixels",
            args.width, args.height
        ))
        .into());
    }
    if args.supersampling == 0 || args.frames == 0 {
        return Err(BadUsage(format!(
            "--supersampling {} --frames {}: give at least 1 of each",
            args.supersampling, args.frames
        ))
        .into());
    }
    let mut scene = crate::common::load_scene(&args.scene)?;
    scene.camera.width = args.width;
    scene.camera.height = args.height;
    scene.camera.supersampling = args.supersampling;
    let camera = novel_camera(&scene);
    lensmap::trace::image::validate_camera(&camera)
        .map_err(|e| BadUsage(format!("--width/--height/--supersampling: {e}")))?;
    Ok((options, projected, scene, camera))
}

/// The frames every part of the benchmark renders: one scene, from one camera, `frames` timed
/// frames per measurement.
struct Bench<'a> {
    hybrid: &'a HybridScene,
    camera: Camera,
    frames: usize,
}

impl Bench<'_> {
    /// Per variant (single pass, multipass), the median time of each stage, printed as a table;
    /// the JSON rows with the last frame's counters.
    fn stages(
        &self,
        runner: &mut FrameRunner,
        hybrid_options: HybridOptions,
        format: TargetFormat,
    ) -> anyhow::Result<Vec<serde_json::Value>> {
        say!(
            "{:<12} {:>7} {:>7} {:>7} {:>8} {:>7} {:>7} {:>8} {:>8} {:>7} {:>7} {:>9}",
            "variant",
            "trace",
            "texgen",
            "tessel.",
            "assemble",
            "upload",
            "record",
            "execute",
            "readback",
            "filter",
            "unacc.",
            "total ms"
        );
        let mut rows = Vec::new();
        for variant in [Variant::SinglePass, Variant::Multipass] {
            let options = FrameOptions {
                hybrid: hybrid_options,
                compositing: Compositing::new(variant, BlendScheme::FrontToBack)
                    .expect("front to back is every variant's"),
                format,
            };
            let repetitions = Repetitions {
                warmup: 2,
                timed: self.frames,
            };
            let frames = runner.timed_frames(self.hybrid, &self.camera, &options, repetitions)?;
            let row = StageMedians::of(frames.frames());
            say!(
                "{:<12} {:>7.1} {:>7.1} {:>7.1} {:>8.1} {:>7.1} {:>7.1} {:>8.1} {:>8.1} {:>7.1} {:>7.1} {:>9.1}",
                variant.name(),
                row.trace,
                row.texgen,
                row.tessellation,
                row.assemble,
                row.upload,
                row.record,
                row.execute,
                row.readback,
                row.downsample,
                row.unaccounted,
                row.total
            );
            let last = frames.last();
            rows.push(json!({
                "variant": variant.name(),
                "median_ms": row.to_json(),
                "rays": last.stats.counters.all_rays(),
                "triangle_tests": last.stats.counters.triangle_tests,
                "lens_triangles_out": last.stats.triangles_out,
                "hull_triangles": last.stats.hull_triangles,
                "vertices_traced": last.stats.vertices_traced,
            }));
        }
        Ok(rows)
    }

    /// A still camera: every frame after the first reuses its tessellation, texture coordinates
    /// and upload. The medians of first and next frames, printed and as JSON.
    fn still_camera(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
        steps: &mut Steps,
    ) -> anyhow::Result<serde_json::Value> {
        let step = steps.step("a still camera");
        let mut first = Vec::new();
        let mut still = Vec::new();
        for _ in 0..self.frames {
            runner.forget_frame();
            first.push(runner.frame(self.hybrid, &self.camera, options)?.total_ms);
            let again = runner.frame(self.hybrid, &self.camera, options)?;
            if !again.stats.reused {
                anyhow::bail!("a still camera's second frame was not reused");
            }
            still.push(again.total_ms);
        }
        let (first_ms, still_ms) = (median(&mut first), median(&mut still));
        step.finish_and_clear();
        say!(
            "still camera: first frame {first_ms:.1} ms, each next frame {still_ms:.1} ms ({:.0}% of the first)",
            100.0 * still_ms / first_ms
        );
        Ok(json!({ "first_ms": first_ms, "next_ms": still_ms, "ratio": still_ms / first_ms }))
    }

    /// A moving camera (a 0.5° step per frame around the look-at point): latency of frames
    /// rendered one at a time, and throughput with two frames in flight; printed and as JSON.
    fn moving_camera(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
        steps: &mut Steps,
    ) -> anyhow::Result<serde_json::Value> {
        let timed = self.frames;
        let step = steps.step("a moving camera, one at a time and in flight");
        let path: Vec<Camera> = (0..timed + 2)
            .map(|i| self.camera.orbited(0.5 * i as f32))
            .collect();
        runner.frames_in_flight(self.hybrid, &path[..2], options)?;
        let one_at_a_time = std::time::Instant::now();
        let mut latencies = Vec::new();
        for camera in &path[2..] {
            latencies.push(runner.frame(self.hybrid, camera, options)?.total_ms);
        }
        let sequential_ms = one_at_a_time.elapsed().as_secs_f64() * 1e3;
        let (_, in_flight_ms) = runner.frames_in_flight(self.hybrid, &path[2..], options)?;
        let latency_ms = median(&mut latencies);
        step.finish_and_clear();
        let fps = |wall_ms: f64| timed as f64 / (wall_ms / 1e3);
        say!(
            "moving camera, {timed} frames: latency {latency_ms:.1} ms (median); throughput {:.1} fps one at a time, {:.1} fps with two frames in flight ({:.2}×)",
            fps(sequential_ms),
            fps(in_flight_ms),
            sequential_ms / in_flight_ms
        );
        Ok(json!({
            "latency_ms": latency_ms, "fps_one_at_a_time": fps(sequential_ms),
            "fps_in_flight": fps(in_flight_ms), "frames_in_flight": lensmap::render::FRAMES_IN_FLIGHT,
        }))
    }

    /// Thread scaling of the CPU stages (tracing, tessellation, texture coordinates, assembly)
    /// at 1, 2 and all `threads`: medians printed and as JSON, with speedups against 1 thread.
    fn thread_scaling(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
        threads: usize,
        steps: &mut Steps,
    ) -> anyhow::Result<Vec<serde_json::Value>> {
        let mut counts = vec![1, 2, threads];
        counts.dedup();
        counts.retain(|&n| n <= threads.max(2));
        let mut scaling = Vec::new();
        let bar = steps.counted("thread scaling", counts.len() as u64, "thread counts");
        for &count in &counts {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(count).build()?;
            let repetitions = Repetitions {
                warmup: 1,
                timed: self.frames,
            };
            let frames = pool
                .install(|| runner.timed_frames(self.hybrid, &self.camera, options, repetitions))?;
            let cpu = frames.median(|f| {
                f.stats.trace_ms + f.stats.tessellation_ms + f.stats.texgen_ms + f.stats.assemble_ms
            });
            let tessellation = frames.median(|f| f.stats.tessellation_ms);
            let total = frames.median(|f| f.total_ms);
            scaling.push((count, cpu, tessellation, total));
            bar.inc(1);
        }
        bar.finish_and_clear();
        let (_, cpu_1, tessellation_1, _) = scaling[0];
        // A speed-up over no time (the GPU path leaves the CPU no tessellation) has no value.
        let speedup = |one: f64, many: f64| (one > 0.0 && many > 0.0).then(|| one / many);
        let shown = |ratio: Option<f64>| ratio.map_or("no CPU time".into(), |r| format!("{r:.2}×"));
        for &(count, cpu, tessellation, total) in &scaling {
            say!(
                "{count:>2} threads: CPU stages {cpu:.1} ms ({} of 1 thread), tessellation {tessellation:.1} ms ({}), frame {total:.1} ms",
                shown(speedup(cpu_1, cpu)),
                shown(speedup(tessellation_1, tessellation))
            );
        }
        Ok(scaling.iter().map(|&(threads, cpu, tessellation, total)| json!({
            "threads": threads, "cpu_stages_ms": cpu, "tessellation_ms": tessellation, "frame_ms": total,
            "cpu_speedup": speedup(cpu_1, cpu), "tessellation_speedup": speedup(tessellation_1, tessellation),
        })).collect())
    }
}

/// One part of a frame's `(vertex tracing, whole frame)` times, ms.
type Part = fn(&(f64, f64)) -> f64;

impl Bench<'_> {
    /// Each stage for the papers' greedy terms and for the first 3, 4 and 6 path classes, on
    /// `tracer` (the CPU's in f64, or the GPU's in the options' precision), by the multipass variant
    /// (front-to-back) and by the single pass (which falls back to the multipass variant for
    /// classes whose varyings it cannot carry: each row names the variant that ran), each frame
    /// built from scratch, the eight alternating (forwards, then backwards) after a warm-up of
    /// each: the stage medians, with the layer passes, ray segments and vertices each stage is
    /// expected to scale by, each as a ratio to greedy's by the same variant asked for; printed
    /// and as JSON.
    fn classes(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
        tracer: VertexTracer,
        steps: &mut Steps,
    ) -> anyhow::Result<serde_json::Value> {
        let step = steps.step(&format!(
            "path classes against greedy, {} tracer, alternating",
            tracer.name()
        ));
        // Classes are traced with exact Fresnel (on the CPU in f64), whatever the flags say.
        let setting = |terms, compositing| FrameOptions {
            hybrid: HybridOptions {
                terms,
                tracer,
                fresnel: FresnelModel::Exact,
                precision: VertexPrecision::F64,
                ..options.hybrid
            },
            compositing,
            ..*options
        };
        let term_sets: Vec<ShadingTerms> = std::iter::once(ShadingTerms::Greedy)
            .chain([3, 4, 6].map(|n| ShadingTerms::Classes(ClassSet::First(n))))
            .collect();
        let variants = [
            Compositing::Multipass(BlendScheme::FrontToBack),
            Compositing::SinglePass,
        ];
        let settings: Vec<(String, FrameOptions)> = variants
            .iter()
            .flat_map(|&variant| {
                term_sets
                    .iter()
                    .map(move |&terms| (terms.name(), setting(terms, variant)))
            })
            .collect();
        // The warm-ups: a scene whose lens objects classes cannot shade (layered by bounce, or
        // glass and mirrors under a count) skips the part, saying why.
        for (name, options) in &settings {
            if let Err(error) = self.frame_from_scratch(runner, options) {
                step.finish_and_clear();
                say!(
                    "path classes against greedy, {} tracer: not run ({name}: {error})",
                    tracer.name()
                );
                return Ok(json!({ "not_run": error.to_string() }));
            }
        }
        let options: Vec<&FrameOptions> = settings.iter().map(|(_, options)| options).collect();
        let frames = self.rounds(runner, &options, ClassSample::of)?;
        step.finish_and_clear();
        let limits = runner.single_pass_limits();
        say!(
            "path classes against greedy ({} tracer, {} frames each, alternating; × greedy's by the variant asked for):",
            tracer.name(),
            self.frames
        );
        say!(
            "{:<8} {:<12} {:>15} {:>15} {:>17} {:>16} {:>15} {:>15}",
            "terms",
            "variant",
            "layer passes",
            "execute ms",
            "rays",
            "trace ms",
            "vertices",
            "tessel. ms"
        );
        let table: Vec<ClassRow> = frames.iter().map(|f| ClassRow::of(f)).collect();
        let mut rows = Vec::new();
        for (i, ((name, options), row)) in settings.iter().zip(&table).enumerate() {
            // Greedy by the same variant asked for: the first setting of each variant's run.
            let greedy = &table[i - i % term_sets.len()];
            let variant = match options.compositing_for(&row.stats, &limits) {
                Compositing::SinglePass => "single pass",
                Compositing::Multipass(_) => "multipass",
            };
            let ratio = |pick: fn(&ClassRow) -> f64| pick(row) / pick(greedy);
            // A stage greedy's frame spends no time in (the GPU tracer's resident frame traces
            // and tessellates in the frame's execution) has no ratio.
            let cell = |value: String, pick: fn(&ClassRow) -> f64| match pick(greedy) > 0.0 {
                true => format!("{value} ×{:.2}", ratio(pick)),
                false => format!("{value} ×–"),
            };
            say!(
                "{:<8} {:<12} {:>15} {:>15} {:>17} {:>16} {:>15} {:>15}  frame {:.1} ms ×{:.2}",
                name,
                variant,
                cell(row.passes.to_string(), |r| r.passes as f64),
                cell(format!("{:.1}", row.stages.execute), |r| r.stages.execute),
                cell(row.rays.to_string(), |r| r.rays as f64),
                cell(format!("{:.1}", row.stages.trace), |r| r.stages.trace),
                cell(row.vertices.to_string(), |r| r.vertices as f64),
                cell(format!("{:.1}", row.stages.tessellation), |r| r
                    .stages
                    .tessellation),
                row.stages.total,
                ratio(|r| r.stages.total)
            );
            rows.push(json!({
                "terms": name, "variant": variant, "varyings": row.stats.class_slots,
                "median_ms": row.stages.to_json(),
                "layer_passes": row.passes, "rays": row.rays, "vertices_traced": row.vertices,
                "total_against_greedy": ratio(|r| r.stages.total),
            }));
        }
        // On the GPU tracer the trace, split and texgen passes run inside the frame's execution:
        // their device times by timestamps, greedy's and 4 classes' by the multipass variant.
        let mut split = serde_json::Map::new();
        if tracer == VertexTracer::Gpu {
            for (name, options) in settings.iter().filter(|(name, options)| {
                matches!(options.compositing, Compositing::Multipass(_))
                    && (name == "greedy" || name == "4")
            }) {
                say!("{name}:");
                split.insert(name.clone(), self.gpu_stages(runner, options, steps)?);
            }
        }
        Ok(json!({
            "tracer": tracer.name(), "frames_each": self.frames, "rows": rows, "gpu_stages": split,
        }))
    }

    /// Frames traced on the GPU with their stages timed by the device's timestamps, each built
    /// from scratch after a warm-up: medians of the trace passes, the split passes, texgen, the
    /// rest of the tessellation (submission, read-back, the mesh rebuilt on the CPU) and the
    /// frame. The timestamps slow the frames down, so these are a split, not the frame time.
    fn gpu_stages(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
        steps: &mut Steps,
    ) -> anyhow::Result<serde_json::Value> {
        let step = steps.step("GPU stages by the device's timestamps");
        runner.time_gpu_stages(true);
        let mut frames = Vec::new();
        let mut timed = || -> anyhow::Result<()> {
            for i in 0..=self.frames {
                runner.forget_frame();
                let frame = runner.frame(self.hybrid, &self.camera, options)?;
                if i > 0 {
                    frames.push((frame.stats, frame.total_ms));
                }
            }
            Ok(())
        };
        let result = timed();
        runner.time_gpu_stages(false);
        result?;
        step.finish_and_clear();
        if frames.iter().any(|(stats, _)| stats.gpu_split_ms.is_none()) {
            say!("GPU stages: not timed (the device's queue has no timestamps)");
            return Ok(serde_json::Value::Null);
        }
        let median_of = |part: &dyn Fn(&(lensmap::hybrid::HybridStats, f64)) -> f64| {
            median(&mut frames.iter().map(part).collect::<Vec<_>>())
        };
        let trace = median_of(&|f| f.0.trace_ms);
        let split = median_of(&|f| f.0.gpu_split_ms.unwrap_or_default());
        let texgen = median_of(&|f| f.0.texgen_ms);
        let rest = median_of(&|f| f.0.tessellation_ms);
        let total = median_of(&|f| f.1);
        say!(
            "GPU stages by the device's timestamps, {} frames: trace passes {trace:.2} ms, split and T-junction passes {split:.2} ms, texgen {texgen:.2} ms (pass and assembly), the rest of the tessellation on the CPU (submissions waited for; reading back and rebuilding the mesh where it is read back) {rest:.2} ms; frame {total:.2} ms, slowed by the timestamps (medians)",
            self.frames
        );
        Ok(json!({
            "trace_ms": trace, "split_ms": split, "texgen_ms": texgen,
            "tessellation_rest_ms": rest, "total_ms": total, "frames": self.frames,
        }))
    }

    /// Two settings `(label, options)`, each frame built from scratch, alternating (A B B A …,
    /// so neither always runs first) after a warm-up of each: medians of the vertex tracing and
    /// of the whole frame per setting, and the medians of the paired differences (second −
    /// first); printed after `what` and as JSON.
    /// One frame of `options` built from scratch (its tessellation and upload not reused).
    fn frame_from_scratch(
        &self,
        runner: &mut FrameRunner,
        options: &FrameOptions,
    ) -> Result<HybridFrame, lensmap::runner::RunError> {
        runner.forget_frame();
        runner.frame(self.hybrid, &self.camera, options)
    }

    /// `--frames` rounds over `settings`, forwards in even rounds and backwards in odd ones (A B
    /// B A … for two), so that none always runs first; each frame built from scratch, and
    /// only what `keep` takes of it kept (not its image). Per setting, in order.
    fn rounds<T>(
        &self,
        runner: &mut FrameRunner,
        settings: &[&FrameOptions],
        keep: impl Fn(&HybridFrame) -> T,
    ) -> anyhow::Result<Vec<Vec<T>>> {
        let mut kept: Vec<Vec<T>> = settings.iter().map(|_| Vec::new()).collect();
        for round in 0..self.frames {
            let mut order: Vec<usize> = (0..settings.len()).collect();
            if round % 2 == 1 {
                order.reverse();
            }
            for which in order {
                kept[which].push(keep(&self.frame_from_scratch(runner, settings[which])?));
            }
        }
        Ok(kept)
    }

    fn alternating(
        &self,
        runner: &mut FrameRunner,
        what: &str,
        settings: [(&str, &FrameOptions); 2],
        steps: &mut Steps,
    ) -> anyhow::Result<serde_json::Value> {
        let step = steps.step(&format!("{what}, alternating"));
        for (_, setting) in settings {
            self.frame_from_scratch(runner, setting)?;
        }
        let times = self.rounds(runner, &settings.map(|(_, setting)| setting), |f| {
            (f.stats.trace_ms, f.total_ms)
        })?;
        step.finish_and_clear();
        let median_of = |which: usize, part: Part| {
            median(&mut times[which].iter().map(part).collect::<Vec<_>>())
        };
        let paired = |part: Part| {
            let mut differences: Vec<f64> = times[1]
                .iter()
                .zip(&times[0])
                .map(|(second, first)| part(second) - part(first))
                .collect();
            median(&mut differences)
        };
        let (trace, total): (Part, Part) = (|t| t.0, |t| t.1);
        let [(a, _), (b, _)] = settings;
        say!(
            "{what}, {} frames each, alternating: vertex tracing {:.2} vs {:.2} ms, frame {:.2} vs {:.2} ms; paired difference ({b} − {a}) {:+.2} ms tracing, {:+.2} ms frame (medians)",
            self.frames,
            median_of(0, trace),
            median_of(1, trace),
            median_of(0, total),
            median_of(1, total),
            paired(trace),
            paired(total)
        );
        Ok(json!({
            a: { "trace_ms": median_of(0, trace), "total_ms": median_of(0, total) },
            b: { "trace_ms": median_of(1, trace), "total_ms": median_of(1, total) },
            "paired_difference_ms": { "trace": paired(trace), "total": paired(total) },
            "frames_each": self.frames,
        }))
    }
}

/// What a term set's frame adds to its row: its stage times and what the stages scale by.
struct ClassSample {
    stages: StageMedians,
    passes: usize,
    stats: lensmap::hybrid::HybridStats,
}

impl ClassSample {
    fn of(frame: &HybridFrame) -> ClassSample {
        ClassSample {
            stages: StageMedians::of_frame(frame),
            passes: frame.render.passes,
            stats: frame.stats,
        }
    }
}

/// One term set's frames: the stage medians and what the stages scale by (the last frame's
/// counts, the same for every frame).
struct ClassRow {
    stages: StageMedians,
    passes: usize,
    rays: u64,
    vertices: usize,
    /// The last frame's statistics (what decides the variant that ran).
    stats: lensmap::hybrid::HybridStats,
}

impl ClassRow {
    fn of(samples: &[ClassSample]) -> ClassRow {
        let last = &samples[samples.len() - 1];
        ClassRow {
            stages: StageMedians::of_medians(samples.iter().map(|s| &s.stages)),
            passes: last.passes,
            rays: last.stats.counters.all_rays(),
            vertices: last.stats.vertices_traced,
            stats: last.stats,
        }
    }
}

/// Median stage times of one setting (or one frame's times), ms.
struct StageMedians {
    trace: f64,
    texgen: f64,
    tessellation: f64,
    assemble: f64,
    upload: f64,
    record: f64,
    execute: f64,
    readback: f64,
    downsample: f64,
    unaccounted: f64,
    total: f64,
}

impl StageMedians {
    /// The medians over `frames`.
    fn of(frames: &[HybridFrame]) -> StageMedians {
        let each: Vec<StageMedians> = frames.iter().map(StageMedians::of_frame).collect();
        StageMedians::of_medians(each.iter())
    }

    /// One frame's stage times.
    fn of_frame(f: &HybridFrame) -> StageMedians {
        StageMedians {
            trace: f.stats.trace_ms,
            texgen: f.stats.texgen_ms,
            tessellation: f.stats.tessellation_ms,
            assemble: f.stats.assemble_ms,
            upload: f.upload_ms,
            record: f.render.record_ms,
            execute: f.render.execute_ms,
            readback: f.render.readback_ms,
            downsample: f.downsample_ms,
            unaccounted: f.unaccounted_ms(),
            total: f.total_ms,
        }
    }

    /// The medians of frames' times `each` (each one frame's, [`StageMedians::of_frame`]).
    fn of_medians<'a>(each: impl Iterator<Item = &'a StageMedians> + Clone) -> StageMedians {
        let stage =
            |f: fn(&StageMedians) -> f64| median(&mut each.clone().map(f).collect::<Vec<_>>());
        StageMedians {
            trace: stage(|s| s.trace),
            texgen: stage(|s| s.texgen),
            tessellation: stage(|s| s.tessellation),
            assemble: stage(|s| s.assemble),
            upload: stage(|s| s.upload),
            record: stage(|s| s.record),
            execute: stage(|s| s.execute),
            readback: stage(|s| s.readback),
            downsample: stage(|s| s.downsample),
            unaccounted: stage(|s| s.unaccounted),
            total: stage(|s| s.total),
        }
    }

    fn to_json(&self) -> serde_json::Value {
        json!({
            "ray_tracing_at_vertices": self.trace, "texture_coordinates": self.texgen,
            "tessellation": self.tessellation, "assemble": self.assemble, "upload": self.upload,
            "record": self.record, "execute": self.execute, "readback": self.readback,
            "downsample": self.downsample, "unaccounted": self.unaccounted, "total": self.total,
        })
    }
}
