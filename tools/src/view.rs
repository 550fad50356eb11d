//! `lensmap view`: the hybrid frame along a camera path. `--record DIR` renders the path headless
//! (no window, no display) and writes every frame as PNG and EXR plus a per-frame stats CSV, for
//! videos and for comparing runs on machines without a display.
//!
//! The window (winit, ash-window, a swapchain) is issue 27's next step and not built yet: without
//! `--record` the command says so and exits 2.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, tessellate::DEFAULT_T, tessellate::TessellationOptions},
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    lightmap::LightMapOptions,
    render::{BlendScheme, TargetFormat, Variant},
    runner::{EmSource, FrameOptions, FrameRunner, LoadOptions, load_hybrid_scene},
    scene::{CameraPath, Scene},
};
use serde_json::json;

use crate::common::{BadUsage, CameraArgs, FormatArg, VariantArg, choose_camera, flag_error};

#[derive(Args)]
#[command(
    group = clap::ArgGroup::new("ems").required(true).args(["bake", "projected"]),
    after_help = "Example:\n  lensmap view --scene glass-sphere --projected --record out/orbit --path orbit --frames 60"
)]
pub struct ViewArgs {
    /// Built-in scene name (teapot-room, glass-sphere, mirror-teapot) or path to a scene .toml.
    #[arg(long)]
    pub scene: String,
    /// Read the layered EMs from this bake directory.
    #[arg(long, value_name = "DIR")]
    pub bake: Option<PathBuf>,
    /// Build projected layered EMs from the scene (layer shells from the scene file).
    #[arg(long)]
    pub projected: bool,
    /// Render the camera path headless into DIR: frame-NNNN.png and .exr per frame and
    /// stats.csv.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// The camera path: `orbit` (a full turn around the camera's look-at point in --frames
    /// frames, starting at the camera) or a path file (TOML `[[poses]]` with position and
    /// look_at).
    #[arg(long, default_value = "orbit", value_name = "orbit|FILE")]
    pub path: String,
    /// Frames of an orbit.
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// The camera the path's poses are applied to (size, supersampling; its position and
    /// look-at start an orbit).
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Tessellation threshold in subpixels.
    #[arg(long, default_value_t = DEFAULT_T, allow_negative_numbers = true)]
    pub t: f32,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "single-pass")]
    pub variant: VariantArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba16f")]
    pub format: FormatArg,
    /// Projected EM face size, texels.
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    pub em_size: u32,
}

/// One CSV row per frame.
const CSV_HEADER: &str = "frame,position_x,position_y,position_z,look_at_x,look_at_y,look_at_z,\
total_ms,trace_ms,tessellation_ms,texture_coordinates_ms,gpu_ms,vertices_traced,lens_triangles";

pub fn run(args: ViewArgs) -> anyhow::Result<()> {
    let Some(dir) = &args.record else {
        return Err(BadUsage(
            "view: the window is not built yet; give --record DIR to render the path headless"
                .into(),
        )
        .into());
    };
    let scene = Scene::load_named(&args.scene)?;
    let base = choose_camera(&scene, &args.scene, &args.camera)?;
    let path = if args.path == "orbit" {
        if args.frames == 0 {
            return Err(BadUsage("--frames 0: an orbit needs at least 1 frame".into()).into());
        }
        let mut centred = scene.clone();
        centred.camera = base;
        CameraPath::orbit(&centred, args.frames)
    } else {
        CameraPath::load(std::path::Path::new(&args.path), &base)?
    };
    let options = FrameOptions {
        hybrid: HybridOptions {
            tessellation: TessellationOptions {
                t: args.t,
                ..TessellationOptions::default()
            },
            ..HybridOptions::default()
        },
        variant: Variant::from(args.variant),
        blend: BlendScheme::default(),
        format: TargetFormat::from(args.format),
    };
    options.validate().map_err(flag_error)?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    let ems = match &args.bake {
        Some(dir) => EmSource::Bake(dir.clone()),
        None => EmSource::Projected(projected),
    };
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    runner.check_framebuffer(&base, options.format)?;
    let (hybrid, _) = load_hybrid_scene(
        scene,
        &LoadOptions {
            ems,
            light_maps: LightMapOptions::default(),
        },
    )?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for (i, camera) in path.cameras(&base).enumerate() {
        let frame = runner.frame(&hybrid, &camera, &options)?;
        let png = dir.join(format!("frame-{i:04}.png"));
        frame.image.write_files(&png, &png.with_extension("exr"))?;
        let s = &frame.stats;
        let (p, l) = (camera.position, camera.look_at);
        writeln!(
            csv,
            "{i},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{},{}",
            p.x,
            p.y,
            p.z,
            l.x,
            l.y,
            l.z,
            frame.total_ms,
            s.trace_ms,
            s.tessellation_ms,
            s.texgen_ms,
            frame.gpu_ms,
            s.vertices_traced,
            s.triangles_out
        )
        .expect("writing to a String");
    }
    let stats = dir.join("stats.csv");
    lensmap::atomic::write_atomically(&stats, csv.as_bytes())
        .with_context(|| format!("writing {}", stats.display()))?;
    crate::common::report(
        &json!({
            "scene": hybrid.scene.name,
            "device": runner.gpu().device_name(),
            "driver": runner.gpu().device_id().driver_description(),
            "frames": path.poses.len(),
            "record": dir,
            "stats": stats,
        }),
        None,
    )?;
    say!(
        "{}: {} frames along {} into {} (stats.csv), device {}",
        hybrid.scene.name,
        path.poses.len(),
        args.path,
        dir.display(),
        runner.gpu().device_id()
    );
    Ok(())
}
