//! `lensmap view --record DIR`: the hybrid frame along a camera path, headless (no window, no
//! display): every frame as PNG and EXR plus a per-frame stats CSV, for videos and for comparing
//! runs on machines without a display.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context as _;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    runner::{FrameOptions, FrameRunner},
    scene::{Camera, CameraPath, Scene},
};
use serde_json::json;

use super::{EmChoice, ViewArgs};
use crate::common::BadUsage;

/// One CSV row per frame.
const CSV_HEADER: &str = "frame,position_x,position_y,position_z,look_at_x,look_at_y,look_at_z,\
total_ms,trace_ms,tessellation_ms,texture_coordinates_ms,gpu_ms,vertices_traced,lens_triangles,\
traced_on_gpu,glossy_maps";

pub(super) fn run(
    args: &ViewArgs,
    dir: &Path,
    scene: Scene,
    base: Camera,
    options: &FrameOptions,
    ems: &EmChoice,
) -> anyhow::Result<()> {
    let path = if args.path == "orbit" {
        let mut centred = scene.clone();
        centred.camera = base;
        // Bounded by clap (1 to MAX_ORBIT_FRAMES): the poses are made up front.
        CameraPath::orbit(&centred, args.frames.unwrap_or(60) as usize)
    } else if let Some(frames) = args.frames {
        return Err(BadUsage(format!(
            "--frames {frames}: it counts the frames of --path orbit, and the path file {} gives its own poses; remove --frames",
            args.path
        ))
        .into());
    } else {
        CameraPath::load(Path::new(&args.path), &base)?
    };
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    runner.check_framebuffer(&base, options.format)?;
    let hybrid = ems.load(&scene, ems.inferred_first)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut csv = String::from(CSV_HEADER);
    csv.push('\n');
    for (i, camera) in path.cameras(&base).enumerate() {
        let frame = runner.frame(&hybrid, &camera, options)?;
        let png = dir.join(format!("frame-{i:04}.png"));
        frame.image.write_files(&png, &png.with_extension("exr"))?;
        let s = &frame.stats;
        let (p, l) = (camera.position, camera.look_at);
        writeln!(
            csv,
            "{i},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{}",
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
            s.triangles_out,
            s.traced_on_gpu,
            s.glossy_maps
        )
        .expect("writing to a String");
    }
    let stats = dir.join("stats.csv");
    lensmap::atomic::write_atomically(&stats, csv.as_bytes())
        .with_context(|| format!("writing {}", stats.display()))?;
    crate::common::report(
        &json!({
            "scene": hybrid.scene().name,
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
        hybrid.scene().name,
        path.poses.len(),
        args.path,
        dir.display(),
        runner.gpu().device_id()
    );
    Ok(())
}
