//! `lensmap render`: one hybrid frame — per-vertex ray paths from the actual camera, adaptive
//! tessellation, layered-EM texture coordinates, the GPU compositor — with the paper's table of
//! where the time went; `--compare` also renders the reference ray tracer at the same settings
//! and reports the reduction factors and the PSNR over the lens pixels.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use glam::Vec3;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, HybridScene, HybridStats},
    layers::{Bake, projected::ProjectedOptions},
    render::{RenderedImage, Renderer, TargetFormat, Variant},
    scene::{Camera, Scene},
    trace::{ReferenceImage, TraceOptions, image::srgb_encode, render_reference},
};
use serde_json::json;

use crate::common::{CameraArgs, choose_camera, progress_bar};
use crate::compositor::{FormatArg, VariantArg};

#[derive(Args)]
#[command(
    group = clap::ArgGroup::new("ems").required(true).args(["bake", "projected"]),
    after_help = "Example:\n  lensmap render --scene teapot-room --projected --view 2 --t 3 --compare --out out/hybrid.png"
)]
pub struct RenderArgs {
    /// Built-in scene name (teapot-room, glass-sphere, mirror-teapot) or path to a scene .toml.
    #[arg(long)]
    pub scene: String,
    /// Read the layered EMs from this bake directory.
    #[arg(long, value_name = "DIR")]
    pub bake: Option<PathBuf>,
    /// Build projected layered EMs from the scene (layer shells from the scene file).
    #[arg(long)]
    pub projected: bool,
    /// The camera.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Tessellation threshold: triangles stop splitting when their edges are shorter than t
    /// subpixels.
    #[arg(long, default_value_t = 3.0)]
    pub t: f32,
    /// Outgoing rays further apart than this many degrees split a triangle.
    #[arg(long, default_value_t = 3.0)]
    pub angle_degrees: f64,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "single-pass")]
    pub variant: VariantArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba16f")]
    pub format: FormatArg,
    /// Projected EMs: cube-map face size in texels.
    #[arg(long, default_value_t = 128)]
    pub em_size: u32,
    /// Also write the layered EMs used as a bake directory.
    #[arg(long, value_name = "DIR")]
    pub write_bake: Option<PathBuf>,
    /// Also render the reference ray tracer at the same settings and compare.
    #[arg(long)]
    pub compare: bool,
    /// Output image (PNG, sRGB; an EXR with linear values is written beside it).
    #[arg(long, default_value = "out/hybrid.png")]
    pub out: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// One hybrid frame's image and costs.
pub struct HybridFrame {
    /// The frame at the camera's resolution (box-filtered from the supersampled framebuffer).
    pub image: RenderedImage,
    /// CPU stages.
    pub stats: HybridStats,
    /// GPU upload, rendering and readback, ms.
    pub gpu_ms: f64,
    /// Of which: uploading the frame's data (lens geometry; EMs only when new), ms.
    pub upload_ms: f64,
    /// Of which: recording, executing and reading back the frame.
    pub render: lensmap::render::FrameTimings,
    /// Whole frame, ms.
    pub total_ms: f64,
}

impl HybridFrame {
    /// "Other": everything but vertex tracing, texture coordinates and tessellation.
    pub fn other_ms(&self) -> f64 {
        (self.total_ms - self.stats.trace_ms - self.stats.texgen_ms - self.stats.tessellation_ms)
            .max(0.0)
    }
}

/// Renders one hybrid frame.
pub fn hybrid_frame(
    gpu: &Gpu,
    renderer: &mut Renderer,
    hybrid: &HybridScene,
    camera: &Camera,
    options: &HybridOptions,
    variant: Variant,
    format: TargetFormat,
) -> anyhow::Result<HybridFrame> {
    let start = Instant::now();
    let (frame, stats) = hybrid.frame(camera, options)?;
    let gpu_start = Instant::now();
    let mut uploaded = renderer.upload(gpu, &frame)?;
    let upload_ms = gpu_start.elapsed().as_secs_f64() * 1e3;
    let (image, render) = renderer.render(gpu, &mut uploaded, variant, format)?;
    let image = image.box_downsample(camera.supersampling);
    let gpu_ms = gpu_start.elapsed().as_secs_f64() * 1e3;
    Ok(HybridFrame {
        image,
        stats,
        gpu_ms,
        upload_ms,
        render,
        total_ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

/// Rejects tessellation and EM options no frame can use (exit code 2 naming the flag).
pub fn check_hybrid_options(t: f32, angle_degrees: f64, em_size: u32) -> anyhow::Result<()> {
    let bad = |s: String| Err(crate::compositor::BadUsage(s).into());
    if !(t.is_finite() && t > 0.0) {
        return bad(format!(
            "--t {t}: give a positive number of subpixels, e.g. 3"
        ));
    }
    if !(angle_degrees.is_finite() && angle_degrees > 0.0 && angle_degrees < 180.0) {
        return bad(format!(
            "--angle-degrees {angle_degrees}: give an angle in (0, 180), e.g. 3"
        ));
    }
    if !(1..=2048).contains(&em_size) {
        return bad(format!(
            "--em-size {em_size}: give a cube-map face size from 1 to 2048 texels, e.g. 128"
        ));
    }
    Ok(())
}

/// `warmup` untimed frames (the first compiles pipelines), then `count` timed ones.
#[allow(clippy::too_many_arguments)]
pub fn timed_frames(
    gpu: &Gpu,
    renderer: &mut Renderer,
    hybrid: &HybridScene,
    camera: &Camera,
    options: &HybridOptions,
    variant: Variant,
    format: TargetFormat,
    (warmup, count): (usize, usize),
) -> anyhow::Result<Vec<HybridFrame>> {
    for _ in 0..warmup {
        hybrid_frame(gpu, renderer, hybrid, camera, options, variant, format)?;
    }
    (0..count.max(1))
        .map(|_| hybrid_frame(gpu, renderer, hybrid, camera, options, variant, format))
        .collect()
}

/// Median over `frames` of one stage's time.
pub fn median_stage(frames: &[HybridFrame], stage: impl Fn(&HybridFrame) -> f64) -> f64 {
    crate::common::median(&mut frames.iter().map(stage).collect::<Vec<_>>())
}

/// Loads the scene and its layered EMs as the arguments say.
pub fn hybrid_scene(
    scene: Scene,
    bake: Option<&Path>,
    em_size: u32,
) -> anyhow::Result<HybridScene> {
    Ok(match bake {
        Some(dir) => HybridScene::from_bake(scene, Bake::read(dir)?)?,
        None => {
            HybridScene::projected(
                scene,
                &ProjectedOptions {
                    size: em_size,
                    supersampling: 2,
                },
            )?
            .0
        }
    })
}

/// PSNR (dB) of `image` against the reference over the pixels the reference sees as all lens,
/// on sRGB-encoded values in [0, 1]; `None` when no pixel is all lens.
pub fn lens_psnr(image: &RenderedImage, reference: &ReferenceImage) -> Option<(f64, usize)> {
    let mut sum = 0.0;
    let mut count = 0usize;
    for ((p, r), m) in image
        .pixels
        .iter()
        .zip(&reference.radiance)
        .zip(&reference.lens_mask)
    {
        if *m < 1.0 {
            continue;
        }
        for c in 0..3 {
            let d =
                f64::from(srgb_encode(p[c].clamp(0.0, 1.0)) - srgb_encode(r[c].clamp(0.0, 1.0)));
            sum += d * d;
        }
        count += 1;
    }
    (count > 0).then(|| {
        (
            10.0 * (1.0 / (sum / (3 * count) as f64).max(1e-20)).log10(),
            count,
        )
    })
}

/// Writes `image` as PNG (sRGB) at `path` and EXR (linear) beside it.
pub fn write_image(image: &RenderedImage, path: &Path) -> anyhow::Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let rgb: Vec<Vec3> = image
        .pixels
        .iter()
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    lensmap::trace::image::write_png(&path.with_extension("png"), image.width, image.height, &rgb)?;
    lensmap::trace::image::write_exr(&path.with_extension("exr"), image.width, image.height, &rgb)?;
    Ok(())
}

/// Runs `lensmap render`.
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let scene = Scene::load_named(&args.scene)?;
    let camera = choose_camera(&scene, &args.scene, &args.camera)?;
    let options = HybridOptions {
        t: args.t,
        angle_radians: args.angle_degrees.to_radians(),
    };
    check_hybrid_options(args.t, args.angle_degrees, args.em_size)?;
    // The GPU first: without a driver, fail before the expensive preparation.
    let gpu = Gpu::new(&GpuOptions::from_env())?;
    let mut renderer = Renderer::new(&gpu)?;
    let prepare = Instant::now();
    let hybrid = hybrid_scene(scene, args.bake.as_deref(), args.em_size)?;
    let prepare_s = prepare.elapsed().as_secs_f64();
    if let Some(dir) = &args.write_bake {
        hybrid.to_bake().write(dir)?;
    }
    let (variant, format) = (Variant::from(args.variant), TargetFormat::from(args.format));
    // The first frame pays for pipeline creation and shader compilation: render it, then time a
    // second one.
    hybrid_frame(
        &gpu,
        &mut renderer,
        &hybrid,
        &camera,
        &options,
        variant,
        format,
    )?;
    let frame = hybrid_frame(
        &gpu,
        &mut renderer,
        &hybrid,
        &camera,
        &options,
        variant,
        format,
    )?;
    write_image(&frame.image, &args.out)?;

    let reference = if args.compare {
        let bar = progress_bar(u64::from(camera.height));
        let image = render_reference(&hybrid.trace, &camera, &TraceOptions::default(), &|rows| {
            bar.set_position(u64::from(rows))
        })?;
        bar.finish_and_clear();
        Some(image)
    } else {
        None
    };
    let report = report(
        &hybrid,
        &camera,
        &args,
        &frame,
        reference.as_ref(),
        prepare_s,
        gpu.device_name(),
    );
    if args.json {
        say!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_table(&report);
    }
    Ok(())
}

fn report(
    hybrid: &HybridScene,
    camera: &Camera,
    args: &RenderArgs,
    frame: &HybridFrame,
    reference: Option<&ReferenceImage>,
    prepare_s: f64,
    device: &str,
) -> serde_json::Value {
    let c = frame.stats.counters;
    let mut out = json!({
        "scene": hybrid.scene.name, "device": device,
        "width": camera.width, "height": camera.height, "supersampling": camera.supersampling,
        "t": args.t, "variant": Variant::from(args.variant).name(), "format": TargetFormat::from(args.format).name(),
        "layered_ems": if args.bake.is_some() { "bake" } else { "projected" },
        "prepare_seconds": prepare_s,
        "hybrid": {
            "ray_tracing_at_vertices_ms": frame.stats.trace_ms,
            "texture_coordinates_ms": frame.stats.texgen_ms,
            "tessellation_ms": frame.stats.tessellation_ms,
            "other_ms": frame.other_ms(),
            "gpu_ms": frame.gpu_ms,
            "total_ms": frame.total_ms,
            "rays": c.all_rays(),
            "triangle_tests": c.triangle_tests,
            "lens_triangles_in": frame.stats.triangles_in,
            "lens_triangles_out": frame.stats.triangles_out,
            "vertices_traced": frame.stats.vertices_traced,
        },
        "out": args.out,
    });
    if let Some(reference) = reference {
        let rc = reference.stats.counters;
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        out["reference"] = json!({
            "ms": reference.stats.seconds * 1e3,
            "rays": rc.all_rays(),
            "triangle_tests": rc.triangle_tests,
        });
        out["reduction"] = json!({
            "time": ratio(reference.stats.seconds * 1e3, frame.total_ms),
            "rays": ratio(rc.all_rays() as f64, c.all_rays() as f64),
            "triangle_tests": ratio(rc.triangle_tests as f64, c.triangle_tests as f64),
        });
        if let Some((psnr, pixels)) = lens_psnr(&frame.image, reference) {
            out["lens_psnr_db"] = json!(psnr);
            out["lens_pixels"] = json!(pixels);
        }
    }
    out
}

fn print_table(r: &serde_json::Value) {
    let h = &r["hybrid"];
    let ms = |v: &serde_json::Value| v.as_f64().unwrap_or(0.0);
    say!(
        "{} {}×{} ({}×{} supersampling), t = {}, {} {} on {}, {} layered EMs",
        r["scene"].as_str().unwrap_or(""),
        r["width"],
        r["height"],
        r["supersampling"],
        r["supersampling"],
        r["t"],
        r["variant"].as_str().unwrap_or(""),
        r["format"].as_str().unwrap_or(""),
        r["device"].as_str().unwrap_or(""),
        r["layered_ems"].as_str().unwrap_or("")
    );
    say!(
        "  ray tracing at vertices     {:>10.1} ms",
        ms(&h["ray_tracing_at_vertices_ms"])
    );
    say!(
        "  texture coordinate gen.     {:>10.1} ms",
        ms(&h["texture_coordinates_ms"])
    );
    say!(
        "  tessellation                {:>10.1} ms",
        ms(&h["tessellation_ms"])
    );
    say!(
        "  other (incl. rendering)     {:>10.1} ms   (GPU upload, render, readback {:.1} ms)",
        ms(&h["other_ms"]),
        ms(&h["gpu_ms"])
    );
    say!(
        "  total frame time            {:>10.1} ms",
        ms(&h["total_ms"])
    );
    say!("  ray count                   {:>10}", h["rays"]);
    say!("  triangle intersection tests {:>10}", h["triangle_tests"]);
    say!(
        "  lens triangles {} → {} after tessellation, {} vertices traced",
        h["lens_triangles_in"],
        h["lens_triangles_out"],
        h["vertices_traced"]
    );
    if r.get("reference").is_some() {
        let f = &r["reference"];
        let red = &r["reduction"];
        say!(
            "  reference ray tracer: {:.1} ms, {} rays, {} triangle tests",
            ms(&f["ms"]),
            f["rays"],
            f["triangle_tests"]
        );
        say!(
            "  reduction: time {:.1}×, rays {:.1}×, triangle tests {:.1}×",
            ms(&red["time"]),
            ms(&red["rays"]),
            ms(&red["triangle_tests"])
        );
        if let Some(psnr) = r["lens_psnr_db"].as_f64() {
            say!(
                "  PSNR over {} lens pixels: {:.2} dB",
                r["lens_pixels"],
                psnr
            );
        }
    }
    say!("  wrote {}", r["out"].as_str().unwrap_or(""));
}
