//! `lensmap bench hybrid`: where a hybrid frame's time goes, per stage, as medians over repeated
//! frames, single pass vs multipass measured in the same run.

use std::path::PathBuf;

use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, tessellate::DEFAULT_T},
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    render::{TargetFormat, Variant},
    runner::{
        EmSource, FrameOptions, FrameRunner, HybridFrame, Repetitions, load_hybrid_scene,
        novel_camera,
    },
    scene::Scene,
};
use serde_json::json;

use crate::common::{BadUsage, FormatArg, flag_error, write_json};

#[derive(Args)]
pub struct BenchHybridArgs {
    /// Built-in scene name or path.
    #[arg(long, default_value = "teapot-room")]
    scene: String,
    /// Frame width.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Frame height.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Supersampling k×k of the framebuffer.
    #[arg(long, default_value_t = 1)]
    supersampling: u32,
    /// Tessellation threshold in subpixels.
    #[arg(long, default_value_t = DEFAULT_T)]
    t: f32,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba16f")]
    format: FormatArg,
    /// Projected EMs: cube-map face size.
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    em_size: u32,
    /// Timed frames per variant (after two warm-up frames).
    #[arg(long, default_value_t = 9)]
    frames: usize,
    /// Where to write the JSON results.
    #[arg(long, default_value = "out/bench-hybrid.json")]
    json: PathBuf,
}

pub fn run(args: BenchHybridArgs) -> anyhow::Result<()> {
    let hybrid_options = HybridOptions::with_t(args.t);
    hybrid_options.validate().map_err(flag_error)?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    if args.width == 0 || args.height == 0 {
        return Err(BadUsage(format!(
            "--width {} --height {}: give a frame of at least 1×1 pixels",
            args.width, args.height
        ))
        .into());
    }
    let mut scene = Scene::load_named(&args.scene)?;
    scene.camera.width = args.width;
    scene.camera.height = args.height;
    scene.camera.supersampling = args.supersampling.max(1);
    let camera = novel_camera(&scene);
    let (hybrid, _) = load_hybrid_scene(scene, &EmSource::Projected(projected))?;
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let format = TargetFormat::from(args.format);
    say!(
        "device: {}  {} {}×{} ({}×{} supersampling), t = {}, {}, {} rayon threads, medians of {} frames",
        runner.gpu().device_name(),
        hybrid.scene.name,
        args.width,
        args.height,
        camera.supersampling,
        camera.supersampling,
        args.t,
        format.name(),
        rayon::current_num_threads(),
        args.frames
    );
    say!(
        "{:<12} {:>9} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9}",
        "variant",
        "trace",
        "texgen",
        "tessel.",
        "upload",
        "record",
        "execute",
        "readback",
        "other",
        "total ms"
    );
    let mut rows = Vec::new();
    for variant in [Variant::SinglePass, Variant::Multipass] {
        let options = FrameOptions {
            hybrid: hybrid_options,
            variant,
            format,
        };
        let repetitions = Repetitions {
            warmup: 2,
            timed: args.frames,
        };
        let frames = runner.timed_frames(&hybrid, &camera, &options, repetitions)?;
        let stage = |f: &dyn Fn(&HybridFrame) -> f64| frames.median(f);
        let trace = stage(&|f| f.stats.trace_ms);
        let texgen = stage(&|f| f.stats.texgen_ms);
        let tessellation = stage(&|f| f.stats.tessellation_ms);
        let upload = stage(&|f| f.upload_ms);
        let record = stage(&|f| f.render.record_ms);
        let execute = stage(&|f| f.render.execute_ms);
        let readback = stage(&|f| f.render.readback_ms);
        let other = stage(&|f| f.other_ms());
        let total = stage(&|f| f.total_ms);
        say!(
            "{:<12} {:>9.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1}",
            variant.name(),
            trace,
            texgen,
            tessellation,
            upload,
            record,
            execute,
            readback,
            other,
            total
        );
        let last = frames.last();
        rows.push(json!({
            "variant": variant.name(),
            "median_ms": {
                "ray_tracing_at_vertices": trace, "texture_coordinates": texgen, "tessellation": tessellation,
                "upload": upload, "record": record, "execute": execute, "readback": readback,
                "other": other, "total": total,
            },
            "rays": last.stats.counters.all_rays(),
            "triangle_tests": last.stats.counters.triangle_tests,
            "lens_triangles_out": last.stats.triangles_out,
        }));
    }
    let out = json!({
        "device": runner.gpu().device_name(), "scene": hybrid.scene.name, "width": args.width, "height": args.height,
        "supersampling": camera.supersampling, "t": args.t, "format": format.name(),
        "threads": rayon::current_num_threads(), "frames": args.frames.max(1), "rows": rows,
    });
    write_json(&args.json, &out)?;
    say!("wrote {}", args.json.display());
    Ok(())
}
