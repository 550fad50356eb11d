//! `lensmap render`: one hybrid frame — per-vertex ray paths from the actual camera, adaptive
//! tessellation, layered-EM texture coordinates, the GPU compositor — with the paper's table of
//! where the time went; `--compare` also renders the reference ray tracer at the same settings
//! and reports the reduction factors and the PSNR over the lens pixels.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{
        DEFAULT_ANGLE_DEGREES, HybridOptions, HybridScene, ViewpointBlending,
        tessellate::{DEFAULT_T, TessellationOptions},
    },
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    lightmap::{
        DEFAULT_MAX_TEXELS, DEFAULT_MAX_TEXELS_PER_METRE, DEFAULT_MIN_TEXELS_PER_METRE,
        DEFAULT_PIXELS_PER_TEXEL, LightMapOptions,
    },
    metrics::{Channels, Encoding, Mask, MetricsError, compare},
    render::{BlendScheme, Compositing, TargetFormat, Variant},
    runner::{
        EmSource, FrameOptions, FrameRunner, HybridFrame, LoadOptions, Repetitions, lens_error,
        load_hybrid_scene, non_lens_error,
    },
    scene::{Camera, Scene},
    trace::{ReferenceImage, TraceOptions, render_reference},
};
use serde_json::json;

use crate::common::{
    BlendArg, CameraArgs, FormatArg, ImageOut, Steps, VariantArg, choose_camera, flag_error,
};

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
    #[arg(long, default_value_t = DEFAULT_T, allow_negative_numbers = true)]
    pub t: f32,
    /// Outgoing rays further apart than this many degrees split a triangle.
    #[arg(long, default_value_t = DEFAULT_ANGLE_DEGREES, allow_negative_numbers = true)]
    pub angle_degrees: f64,
    #[arg(long, value_name = "exact|table:N", default_value = "exact", value_parser = crate::common::parse_fresnel, help = crate::common::FRESNEL_HELP)]
    pub fresnel: lensmap::hybrid::FresnelModel,
    #[arg(long, value_enum, default_value = "on", help = crate::common::HULL_SPLIT_HELP)]
    pub hull_split: crate::common::OnOff,
    /// Where the lens vertices are ray traced.
    #[arg(long, value_enum, default_value = "auto")]
    pub tracer: crate::common::TracerArg,
    /// How the GPU tracer finds a ray's hits (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "auto")]
    pub traversal: crate::common::TraversalArg,
    /// What the GPU tracer computes in (with the GPU tracer only).
    #[arg(long, value_enum, default_value = "f32")]
    pub gpu_precision: crate::common::GpuPrecisionArg,
    /// Footprint coarsening: a lens object spanning fewer subpixels than this on screen is
    /// tessellated with a proportionally larger t (up to 8×); 0 turns it off.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub footprint: f32,
    /// The frame's budget of lens vertices (each is ray traced): past it no triangle is split
    /// further, and a warning says how many were left unsplit.
    #[arg(long, default_value_t = lensmap::hybrid::tessellate::DEFAULT_MAX_VERTICES, allow_negative_numbers = true)]
    pub max_vertices: usize,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "single-pass")]
    pub variant: VariantArg,
    /// How the multipass variant combines layers and (viewpoint, term) groups (the single pass
    /// takes only front-to-back).
    #[arg(long, value_enum, default_value = "front-to-back")]
    pub blend: BlendArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba16f")]
    pub format: FormatArg,
    /// Projected EMs: cube-map face size in texels.
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    pub em_size: u32,
    /// Light maps of the opaque environment: the least texel density of any chart, texels per
    /// metre. Each chart gets one texel per --light-map-pixels-per-texel pixels of the scene
    /// camera's resolution seen from its nearest viewpoint (view-space samples and the scene
    /// camera), within [this, --light-map-max-density]; all densities are lowered alike where
    /// an atlas would pass 4096² or all of them --light-map-max-texels.
    #[arg(long, default_value_t = DEFAULT_MIN_TEXELS_PER_METRE, allow_negative_numbers = true)]
    pub light_map_density: f64,
    /// Light maps: the greatest texel density of any chart, texels per metre. Give the same
    /// value as --light-map-density for one uniform density.
    #[arg(long, default_value_t = DEFAULT_MAX_TEXELS_PER_METRE, allow_negative_numbers = true)]
    pub light_map_max_density: f64,
    /// Light maps: pixels per texel side at a chart's nearest viewpoint (P).
    #[arg(long, default_value_t = DEFAULT_PIXELS_PER_TEXEL, allow_negative_numbers = true)]
    pub light_map_pixels_per_texel: f64,
    /// Light maps: texels of all the atlases together (8 bytes each on the GPU); over it, every
    /// chart's density is lowered by one factor.
    #[arg(long, default_value_t = DEFAULT_MAX_TEXELS)]
    pub light_map_max_texels: u64,
    /// Draw the glossy objects by reflection-space IBR from this radiance-map bake
    /// (`lensmap bake --radiance-maps`), instead of light-mapped.
    #[arg(long, value_name = "DIR")]
    pub radiance: Option<PathBuf>,
    /// How the glossy pass reconstructs a view's radiance map (with --radiance): the paper's
    /// warped blend of three samples, or a baseline without the warp.
    #[arg(long, value_enum, default_value = "warped")]
    pub glossy_reconstruction: crate::common::ReconstructionArg,
    /// Also write the layered EMs used as a bake directory.
    #[arg(long, value_name = "DIR")]
    pub write_bake: Option<PathBuf>,
    /// Use the --bake directory even if its manifest names another scene, or none (deliberate
    /// reuse; lens objects are still matched by name).
    #[arg(long, requires = "bake")]
    pub accept_any_bake: bool,
    /// Also render the reference ray tracer at the same settings and compare.
    #[arg(long)]
    pub compare: bool,
    /// With --compare: also write the frame, the reference and their difference (×4, over the
    /// lens and glossy pixels; black elsewhere) side by side into this PNG (with its EXR).
    #[arg(long, value_name = "FILE", requires = "compare")]
    pub side_by_side: Option<PathBuf>,
    /// With --compare: directions the reference samples per camera ray at a glossy surface.
    #[arg(long, default_value_t = lensmap::trace::shade::DEFAULT_GLOSSY_SAMPLES, requires = "compare")]
    pub reference_glossy_samples: u32,
    /// Output image: a .png (sRGB) with a linear .exr written beside it (or the .exr, with the
    /// .png beside it), or a folder that gets hybrid.png and hybrid.exr.
    #[arg(long, default_value = "out/hybrid.png")]
    pub out: PathBuf,
}

/// Runs `lensmap render`.
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    // clap's `requires` is met by any member of the `ems` group (clap-rs/clap#4707): checked here.
    if args.accept_any_bake && args.bake.is_none() {
        return Err(crate::common::BadUsage(
            "--accept-any-bake: it applies to --bake DIR only; give --bake DIR or drop it".into(),
        )
        .into());
    }
    let out = ImageOut::parse(&args.out, "hybrid")?;
    let scene = Scene::load_named(&args.scene)?;
    let camera = choose_camera(&scene, &args.scene, &args.camera)?;
    let options = FrameOptions {
        hybrid: HybridOptions {
            tessellation: TessellationOptions {
                t: args.t,
                max_vertices: args.max_vertices,
                ..TessellationOptions::default()
            },
            angle_radians: args.angle_degrees.to_radians(),
            footprint_subpixels: args.footprint,
            fresnel: args.fresnel,
            hull_split: args.hull_split.is_on(),
            tracer: args.tracer.into(),
            traversal: args.traversal.into(),
            gpu_precision: args.gpu_precision.into(),
            ..HybridOptions::default()
        },
        compositing: Compositing::new(Variant::from(args.variant), BlendScheme::from(args.blend))
            .map_err(|error| {
            crate::common::BadUsage(lensmap::options::Worded::worded(
                &error,
                &crate::words::Flags,
            ))
        })?,
        format: TargetFormat::from(args.format),
    };
    options.validate().map_err(flag_error)?;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    let ems = match &args.bake {
        Some(dir) if args.accept_any_bake => EmSource::AnyBake(dir.clone()),
        Some(dir) => EmSource::Bake(dir.clone()),
        None => EmSource::Projected(projected),
    };
    // The GPU first: without a driver, fail before the expensive preparation.
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    runner.check_framebuffer(&camera, options.format)?;
    let mut steps = Steps::new(if args.compare { 3 } else { 2 });
    let step = steps.step("light maps and layered EMs");
    let prepare = Instant::now();
    let light_maps = LightMapOptions {
        min_texels_per_metre: args.light_map_density,
        max_texels_per_metre: args.light_map_max_density,
        pixels_per_texel: args.light_map_pixels_per_texel,
        max_texels: args.light_map_max_texels,
        ..LightMapOptions::default()
    };
    light_maps.validate().map_err(flag_error)?;
    let (mut hybrid, _) = load_hybrid_scene(scene, &LoadOptions { ems, light_maps })?;
    if let Some(dir) = &args.radiance {
        hybrid.use_radiance_bake(dir, args.glossy_reconstruction.into())?;
    }
    let prepare_s = prepare.elapsed().as_secs_f64();
    if let Some(dir) = &args.write_bake {
        hybrid.to_bake().write(dir)?;
    }
    step.finish_and_clear();
    let step = steps.step("hybrid frame (a warm-up, then the timed one)");
    // The first frame pays for pipeline creation and shader compilation: render it, then time a
    // second one.
    let repetitions = Repetitions {
        warmup: 1,
        timed: 1,
    };
    let frames = runner.timed_frames(&hybrid, &camera, &options, repetitions)?;
    let frame = frames.last();
    frame.image.write_files(&out.png, &out.exr)?;
    step.finish_and_clear();
    // Projected EMs are the same at every sample: only a bake's samples can be left.
    if frame.stats.outside_view_space && args.bake.is_some() {
        let how_far = hybrid
            .view_space_fit(&camera)
            .map_or(0.0, |fit| fit.outside_radians.to_degrees());
        warn!(
            "the camera is {how_far:.1}° outside the view space the samples cover; the frame blends the samples of its nearest point"
        );
    }
    if frame.render.saturated > 0 {
        warn!(
            "{} channel values passed RGBA16F's range (65504) and were clamped to it; use --format rgba32f for radiance that bright",
            frame.render.saturated
        );
    }

    let reference = if args.compare {
        let bar = steps.counted("reference ray tracer", u64::from(camera.height), "rows");
        let options = TraceOptions {
            glossy_samples: args.reference_glossy_samples.max(2),
            ..TraceOptions::default()
        };
        let image = render_reference(hybrid.trace(), &camera, &options, &|rows| {
            bar.set_position(u64::from(rows))
        })?;
        bar.finish_and_clear();
        if let Some(path) = &args.side_by_side {
            let reference = crate::common::reference_frame(&image);
            let mut difference = crate::common::difference(&frame.image, &reference, 4.0);
            let objects = image.lens_mask.iter().zip(&image.glossy_mask);
            for (pixel, (lens, glossy)) in difference.pixels.iter_mut().zip(objects) {
                if *lens <= 0.0 && *glossy <= 0.0 {
                    *pixel = [0.0, 0.0, 0.0, 1.0];
                }
            }
            crate::common::beside(&[frame.image.clone(), reference, difference])?
                .write_png_and_exr(path)?;
        }
        Some(image)
    } else {
        None
    };
    let report = report(
        &hybrid,
        &camera,
        &args,
        frame,
        reference.as_ref(),
        Run {
            prepare_s,
            device: runner.gpu().device_id(),
            written: &out,
        },
    )?;
    crate::common::report(&report, None)?;
    print_table(&report);
    Ok(())
}

/// What the report says about the run besides the frame: the scene preparation time, the device
/// and the files written.
struct Run<'a> {
    prepare_s: f64,
    device: &'a lensmap::gpu::DeviceId,
    written: &'a ImageOut,
}

fn report(
    hybrid: &HybridScene,
    camera: &Camera,
    args: &RenderArgs,
    frame: &HybridFrame,
    reference: Option<&ReferenceImage>,
    run: Run,
) -> anyhow::Result<serde_json::Value> {
    let Run {
        prepare_s,
        device,
        written,
    } = run;
    let c = frame.stats.counters;
    let mut out = json!({
        "scene": hybrid.scene().name, "device": device.device, "driver": device.driver_description(),
        "width": camera.width, "height": camera.height, "supersampling": camera.supersampling,
        "t": args.t, "fresnel": args.fresnel.name(), "hull_split": args.hull_split.is_on(), "tracer": if frame.stats.traced_on_gpu { "gpu" } else { "cpu" }, "variant": Variant::from(args.variant).name(), "blend": BlendScheme::from(args.blend).name(), "format": TargetFormat::from(args.format).name(),
        "layered_ems": if args.bake.is_some() { "bake" } else { "projected" },
        "prepare_seconds": prepare_s,
        "light_maps": {
            "min_texels_per_metre_asked": args.light_map_density,
            "max_texels_per_metre_asked": args.light_map_max_density,
            "pixels_per_texel": args.light_map_pixels_per_texel,
            "max_texels": args.light_map_max_texels,
            "min_texels_per_metre": hybrid.light_maps().min_texels_per_metre,
            "max_texels_per_metre": hybrid.light_maps().max_texels_per_metre,
            "ms": hybrid.light_maps().ms,
            "gpu_bytes": hybrid.light_maps().gpu_bytes,
            "texels": hybrid.light_maps().texels,
            "shaded_texels": hybrid.light_maps().shaded_texels,
            "supersampled_texels": hybrid.light_maps().supersampled_texels,
            "samples": hybrid.light_maps().samples,
            "shadow_rays": hybrid.light_maps().shadow_rays,
            "charts": hybrid.light_maps().charts,
        },
        "hybrid": {
            "ray_tracing_at_vertices_ms": frame.stats.trace_ms,
            "texture_coordinates_ms": frame.stats.texgen_ms,
            "tessellation_ms": frame.stats.tessellation_ms,
            "other_ms": frame.other_ms(),
            "gpu_ms": frame.gpu_ms,
            "total_ms": frame.total_ms,
            "saturated_channels": frame.render.saturated,
            "rays": c.all_rays(),
            "triangle_tests": c.triangle_tests,
            "lens_triangles_in": frame.stats.triangles_in,
            "lens_triangles_out": frame.stats.triangles_out,
            "hull_triangles": frame.stats.hull_triangles,
            "vertices_traced": frame.stats.vertices_traced,
            "leaves_stopped_by_vertex_budget": frame.stats.stopped_by_budget,
            "outside_view_space": frame.stats.outside_view_space,
            "glossy_maps_read": frame.stats.glossy_maps,
            "viewpoints": hybrid
                .viewpoint_blend(camera, ViewpointBlending::ViewSpace)
                .samples
                .iter()
                .map(|(i, w)| json!({"viewpoint": i, "weight": w}))
                .collect::<Vec<_>>(),
        },
        "out": written.png,
        "out_exr": written.exr,
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
        // The headline figure in display sRGB (clamped, what a viewer sees), and beside it the
        // linear one that also counts errors in highlights above 1. No lens pixel: no figure.
        match (
            lens_error(&frame.image, reference, Encoding::DisplaySrgb),
            lens_error(&frame.image, reference, Encoding::Linear),
        ) {
            (Ok(display), Ok(linear)) => {
                out["lens_psnr_db"] = json!(display.psnr_db);
                out["lens_psnr_linear_db"] = json!(linear.psnr_db);
                out["lens_pixels"] = json!(display.pixels);
            }
            (Err(MetricsError::EmptyMask), _) | (_, Err(MetricsError::EmptyMask)) => {}
            (Err(error), _) | (_, Err(error)) => return Err(error.into()),
        }
        // The glossy objects: pixels whose every subsample meets a glossy surface first.
        let glossy = Mask::from_flags(reference.glossy_mask.iter().map(|&m| m >= 1.0).collect());
        match compare(
            &frame.image.pixels,
            &reference.radiance,
            &glossy,
            Encoding::DisplaySrgb,
            Channels::Rgb,
        ) {
            Ok(display) => {
                out["glossy_psnr_db"] = json!(display.psnr_db);
                out["glossy_pixels"] = json!(display.pixels);
            }
            Err(MetricsError::EmptyMask) => {}
            Err(error) => return Err(error.into()),
        }
        // The opaque environment (light-mapped) and the background: pixels no lens covers.
        match non_lens_error(&frame.image, reference, Encoding::DisplaySrgb) {
            Ok(display) => {
                out["non_lens_psnr_db"] = json!(display.psnr_db);
                out["non_lens_pixels"] = json!(display.pixels);
            }
            Err(MetricsError::EmptyMask) => {}
            Err(error) => return Err(error.into()),
        }
    }
    Ok(out)
}

fn print_table(r: &serde_json::Value) {
    let h = &r["hybrid"];
    let ms = |v: &serde_json::Value| v.as_f64().unwrap_or(0.0);
    say!(
        "{} {}×{} ({}×{} supersampling), t = {}, {} {} on {} (driver {}), {} layered EMs",
        r["scene"].as_str().unwrap_or(""),
        r["width"],
        r["height"],
        r["supersampling"],
        r["supersampling"],
        r["t"],
        r["variant"].as_str().unwrap_or(""),
        r["format"].as_str().unwrap_or(""),
        r["device"].as_str().unwrap_or(""),
        r["driver"].as_str().unwrap_or(""),
        r["layered_ems"].as_str().unwrap_or("")
    );
    let l = &r["light_maps"];
    say!(
        "  light maps (once per scene): {:.0} ms, {:.1} MiB RGBA16F, {} charts at {:.1}–{:.1} texels/m, {} of {} texels shaded, {} supersampled",
        ms(&l["ms"]),
        ms(&l["gpu_bytes"]) / 1048576.0,
        l["charts"],
        ms(&l["min_texels_per_metre"]),
        ms(&l["max_texels_per_metre"]),
        l["shaded_texels"],
        l["texels"],
        l["supersampled_texels"]
    );
    say!(
        "  ray tracing at vertices ({}) {:>8.1} ms",
        r["tracer"].as_str().unwrap_or(""),
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
    if h["hull_triangles"].as_u64().unwrap_or(0) > 0 {
        say!(
            "  convex-hull split           {:>10} lens triangles drawn with the distant layer only",
            h["hull_triangles"]
        );
    }
    if h["leaves_stopped_by_vertex_budget"].as_u64().unwrap_or(0) > 0 {
        warn!(
            "the frame's vertex budget was spent: {} triangles were left unsplit (coarser than t asks); raise --max-vertices or t",
            h["leaves_stopped_by_vertex_budget"]
        );
    }
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
        match (
            r["lens_psnr_db"].as_f64(),
            r["lens_psnr_linear_db"].as_f64(),
        ) {
            (Some(display), Some(linear)) => say!(
                "  PSNR over {} lens pixels: {:.2} dB (display sRGB, clamped to [0, 1]), {:.2} dB (linear HDR)",
                r["lens_pixels"],
                display,
                linear
            ),
            _ => say!("  no pixel is entirely lens in the reference: no lens PSNR"),
        }
        if let Some(display) = r["glossy_psnr_db"].as_f64() {
            say!(
                "  PSNR over {} glossy pixels: {:.2} dB (display sRGB; {} radiance maps read{})",
                r["glossy_pixels"],
                display,
                h["glossy_maps_read"],
                if h["glossy_maps_read"].as_u64() == Some(0) {
                    ": light-mapped, diffuse only; give --radiance DIR"
                } else {
                    ""
                }
            );
        }
        if let Some(display) = r["non_lens_psnr_db"].as_f64() {
            say!(
                "  PSNR over {} non-lens pixels: {:.2} dB (display sRGB, clamped to [0, 1])",
                r["non_lens_pixels"],
                display
            );
        }
    }
    say!(
        "  wrote {} and {}",
        r["out"].as_str().unwrap_or(""),
        r["out_exr"].as_str().unwrap_or("")
    );
}
