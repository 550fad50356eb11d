//! `lensmap render`: one hybrid frame — per-vertex ray paths from the actual camera, adaptive
//! tessellation, layered-EM texture coordinates, the GPU compositor — with the paper's table of
//! where the time went; `--compare` also renders the reference ray tracer at the same settings
//! and reports the reduction factors and the PSNR over the lens pixels.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridScene, ViewpointBlending},
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    lightmap::{
        DEFAULT_MAX_TEXELS, DEFAULT_MAX_TEXELS_PER_METRE, DEFAULT_MIN_TEXELS_PER_METRE,
        DEFAULT_PIXELS_PER_TEXEL, LightMapOptions,
    },
    metrics::{Channels, Encoding, Mask, MetricsError, compare},
    render::{Compositing, TargetFormat},
    runner::{
        EmSource, FrameRunner, HybridFrame, LoadOptions, Repetitions, lens_error,
        load_hybrid_scene, non_lens_error,
    },
    scene::Camera,
    trace::{LensSelection, PathModel, ReferenceImage, TraceOptions, render_reference},
};
use serde::Serialize;

use crate::common::{CameraArgs, ImageOut, Steps, choose_camera, flag_error};
use crate::frame_args::FrameArgs;

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
    /// How the frame is made.
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Projected EMs: cube-map face size in texels.
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    pub em_size: u32,
    /// Light maps of the opaque environment: the least texel density of any chart, texels per
    /// metre. Each chart gets one texel per --light-map-pixels-per-texel pixels of the scene
    /// camera's resolution seen from its nearest viewpoint (view-space samples and the scene
    /// camera), within [this, --light-map-max-density]; all densities are lowered alike where
    /// an atlas would pass 4096² or all of them --light-map-max-texels.
    /// Range: [1, 4096].
    #[arg(long, default_value_t = DEFAULT_MIN_TEXELS_PER_METRE, allow_negative_numbers = true)]
    pub light_map_density: f64,
    /// Light maps: the greatest texel density of any chart, texels per metre. Give the same
    /// value as --light-map-density for one uniform density.
    /// Range: [1, 4096] (and at least --light-map-density).
    #[arg(long, default_value_t = DEFAULT_MAX_TEXELS_PER_METRE, allow_negative_numbers = true)]
    pub light_map_max_density: f64,
    /// Light maps: pixels per texel side at a chart's nearest viewpoint (P).
    /// Range: [0.25, 64].
    #[arg(long, default_value_t = DEFAULT_PIXELS_PER_TEXEL, allow_negative_numbers = true)]
    pub light_map_pixels_per_texel: f64,
    /// Light maps: texels of all the atlases together (8 bytes each on the GPU); over it, every
    /// chart's density is lowered by one factor.
    /// Range: [65536, 2^32].
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
    #[arg(long, value_name = "FILE")]
    pub side_by_side: Option<PathBuf>,
    /// With --compare: the reference's ray-path model: `greedy` (the papers' two terms),
    /// `full` (the full ray tree, the light itself), or a path-class set (a frame of classes
    /// against its own model).
    #[arg(long, default_value = "greedy", value_name = "greedy|full|N|CLASSES", value_parser = crate::reference::parse_tree)]
    pub reference_tree: PathModel,
    /// With --compare: the reference's supersampling per pixel side; by default the frame's.
    /// Range: [1, 16].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub reference_supersampling: Option<u32>,
    /// With --compare: directions the reference samples per camera ray at a glossy surface.
    /// Range: [2, 1048576].
    #[arg(long, default_value_t = lensmap::trace::shade::DEFAULT_GLOSSY_SAMPLES)]
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
    let scene = crate::common::load_scene(&args.scene)?;
    let camera = choose_camera(&scene, &args.scene, &args.camera)?;
    let options = args.frame.options()?;
    // The frames' own model, by name (one for all its lens objects, or the scene's terms).
    let own_model = crate::common::frame_model(options.hybrid.terms, &scene)
        .map_or_else(|_| options.hybrid.terms.name(), |model| model.name());
    let reference_model = args.reference_tree;
    let projected = ProjectedOptions::with_size(args.em_size);
    projected.validate().map_err(flag_error)?;
    let ems = match &args.bake {
        Some(dir) if args.accept_any_bake => EmSource::AnyBake(dir.clone()),
        Some(dir) => EmSource::Bake(dir.clone()),
        None => EmSource::Projected(projected),
    };
    if crate::common::validate_only() {
        return Ok(());
    }
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
    let compositing = runner.compositing_for(&options, &frame.stats);
    if compositing != options.compositing {
        warn!(
            "the single pass carries {} varyings on this device and the {} path-class terms need {}; the multipass variant (front-to-back, the same composite) rendered them (give fewer --terms or layers for the single pass)",
            runner.single_pass_limits().max_class_slots,
            frame.stats.class_terms,
            frame.stats.class_slots
        );
    }
    // A bake's maps fit the terms they were solved over: say so when the frame's are others.
    if let Some(dir) = &args.bake {
        let baked = lensmap::layers::bake::Manifest::read(dir)
            .ok()
            .and_then(|m| m.provenance)
            .and_then(|p| p.terms)
            .unwrap_or_else(|| "greedy".into());
        if baked != own_model {
            warn!(
                "the bake's maps were solved over the {baked} terms and the frame shades its lens objects with {own_model}; give --terms {baked} to draw them as they were fitted"
            );
        }
    }
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
            model: reference_model,
            glossy_samples: args.reference_glossy_samples.max(2),
            ..TraceOptions::default()
        };
        let reference_camera = Camera {
            supersampling: args.reference_supersampling.unwrap_or(camera.supersampling),
            ..camera
        };
        let image = render_reference(hybrid.trace(), &reference_camera, &options, &|rows| {
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
            compositing,
            terms: own_model,
            reference_model,
            device: runner.gpu().device_id(),
            written: &out,
        },
    )?;
    // As a value: the document's keys in the order it has always had (sorted).
    crate::common::report(&serde_json::to_value(&report)?, None)?;
    report.print_table();
    Ok(())
}

/// What the report says about the run besides the frame: the scene preparation time, the device
/// and the files written.
struct Run<'a> {
    prepare_s: f64,
    /// The compositing the frame ran with (the multipass variant for path classes the single
    /// pass cannot carry).
    compositing: Compositing,
    /// The frame's shading terms, by name.
    terms: String,
    /// The reference's ray-path model.
    reference_model: PathModel,
    device: &'a lensmap::gpu::DeviceId,
    written: &'a ImageOut,
}

/// What `lensmap render` reports: serialized as its JSON document, displayed as its table.
#[derive(Serialize)]
struct RenderReport {
    scene: String,
    device: String,
    driver: String,
    width: u32,
    height: u32,
    supersampling: u32,
    t: f32,
    fresnel: String,
    hull_split: bool,
    tracer: &'static str,
    /// The frame's shading terms (`greedy`, or the path-class set).
    terms: String,
    variant: &'static str,
    blend: &'static str,
    format: &'static str,
    layered_ems: &'static str,
    prepare_seconds: f64,
    light_maps: LightMapReport,
    hybrid: FrameReport,
    out: PathBuf,
    out_exr: PathBuf,
    #[serde(flatten)]
    reference: Option<ReferenceReport>,
}

/// The light maps: what was asked, what was made.
#[derive(Serialize)]
struct LightMapReport {
    min_texels_per_metre_asked: f64,
    max_texels_per_metre_asked: f64,
    pixels_per_texel: f64,
    max_texels: u64,
    min_texels_per_metre: f64,
    max_texels_per_metre: f64,
    ms: f64,
    gpu_bytes: u64,
    texels: u64,
    shaded_texels: u64,
    supersampled_texels: u64,
    samples: u64,
    shadow_rays: u64,
    charts: usize,
}

/// The hybrid frame's stages and counts.
#[derive(Serialize)]
struct FrameReport {
    ray_tracing_at_vertices_ms: f64,
    texture_coordinates_ms: f64,
    tessellation_ms: f64,
    other_ms: f64,
    gpu_ms: f64,
    total_ms: f64,
    saturated_channels: usize,
    rays: u64,
    triangle_tests: u64,
    lens_triangles_in: usize,
    lens_triangles_out: usize,
    hull_triangles: usize,
    vertices_traced: usize,
    leaves_stopped_by_vertex_budget: usize,
    /// Builds of the frame thrown away because the GPU tessellation's buffers grew (the times
    /// above are the last build's).
    builds_discarded: usize,
    outside_view_space: bool,
    glossy_maps_read: usize,
    viewpoints: Vec<ViewpointWeight>,
}

#[derive(Serialize)]
struct ViewpointWeight {
    viewpoint: usize,
    weight: f64,
}

/// With `--compare`: the reference, the reduction factors and the PSNRs (each absent where its
/// mask has no pixel).
#[derive(Serialize)]
struct ReferenceReport {
    reference: ReferenceCost,
    /// The reference's ray-path model (`greedy`, `full`, or a class set).
    reference_tree: PathModel,
    /// Its supersampling per pixel side.
    reference_supersampling: u32,
    /// The frame's mean lens radiance (linear, the channels' mean) over the reference's: how
    /// much of the light it keeps.
    #[serde(skip_serializing_if = "Option::is_none")]
    lens_radiance_ratio: Option<f64>,
    reduction: Reduction,
    #[serde(skip_serializing_if = "Option::is_none")]
    lens_psnr_db: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lens_psnr_linear_db: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lens_pixels: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    glossy_psnr_db: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    glossy_pixels: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    non_lens_psnr_db: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    non_lens_pixels: Option<usize>,
}

#[derive(Serialize)]
struct ReferenceCost {
    ms: f64,
    rays: u64,
    triangle_tests: u64,
}

#[derive(Serialize)]
struct Reduction {
    time: f64,
    rays: f64,
    triangle_tests: f64,
}

fn report(
    hybrid: &HybridScene,
    camera: &Camera,
    args: &RenderArgs,
    frame: &HybridFrame,
    reference: Option<&ReferenceImage>,
    run: Run,
) -> anyhow::Result<RenderReport> {
    let Run {
        prepare_s,
        compositing,
        terms,
        reference_model,
        device,
        written,
    } = run;
    let c = frame.stats.counters;
    let maps = hybrid.light_maps();
    Ok(RenderReport {
        scene: hybrid.scene().name.clone(),
        device: device.device.clone(),
        driver: device.driver_description(),
        width: camera.width,
        height: camera.height,
        supersampling: camera.supersampling,
        t: args.frame.t,
        fresnel: args.frame.fresnel.name(),
        hull_split: args.frame.hull_split.is_on(),
        tracer: if frame.stats.traced_on_gpu {
            "gpu"
        } else {
            "cpu"
        },
        terms,
        variant: compositing.variant().name(),
        blend: compositing.blend().name(),
        format: TargetFormat::from(args.frame.format).name(),
        layered_ems: if args.bake.is_some() {
            "bake"
        } else {
            "projected"
        },
        prepare_seconds: prepare_s,
        light_maps: LightMapReport {
            min_texels_per_metre_asked: args.light_map_density,
            max_texels_per_metre_asked: args.light_map_max_density,
            pixels_per_texel: args.light_map_pixels_per_texel,
            max_texels: args.light_map_max_texels,
            min_texels_per_metre: maps.min_texels_per_metre,
            max_texels_per_metre: maps.max_texels_per_metre,
            ms: maps.ms,
            gpu_bytes: maps.gpu_bytes,
            texels: maps.texels,
            shaded_texels: maps.shaded_texels,
            supersampled_texels: maps.supersampled_texels,
            samples: maps.samples,
            shadow_rays: maps.shadow_rays,
            charts: maps.charts,
        },
        hybrid: FrameReport {
            ray_tracing_at_vertices_ms: frame.stats.trace_ms,
            texture_coordinates_ms: frame.stats.texgen_ms,
            tessellation_ms: frame.stats.tessellation_ms,
            other_ms: frame.other_ms(),
            gpu_ms: frame.gpu_ms,
            total_ms: frame.total_ms,
            saturated_channels: frame.render.saturated,
            rays: c.all_rays(),
            triangle_tests: c.triangle_tests,
            lens_triangles_in: frame.stats.triangles_in,
            lens_triangles_out: frame.stats.triangles_out,
            hull_triangles: frame.stats.hull_triangles,
            vertices_traced: frame.stats.vertices_traced,
            leaves_stopped_by_vertex_budget: frame.stats.stopped_by_budget,
            builds_discarded: frame.stats.builds_discarded,
            outside_view_space: frame.stats.outside_view_space,
            glossy_maps_read: frame.stats.glossy_maps,
            viewpoints: hybrid
                .viewpoint_blend(camera, ViewpointBlending::ViewSpace)
                .samples
                .iter()
                .map(|&(viewpoint, weight)| ViewpointWeight { viewpoint, weight })
                .collect(),
        },
        out: written.png.clone(),
        out_exr: written.exr.clone(),
        reference: reference
            .map(|reference| compared(frame, reference, reference_model, args, camera))
            .transpose()?,
    })
}

/// The reference's cost, the reduction factors and the PSNRs of `frame` against `reference`.
fn compared(
    frame: &HybridFrame,
    reference: &ReferenceImage,
    reference_tree: PathModel,
    args: &RenderArgs,
    camera: &Camera,
) -> anyhow::Result<ReferenceReport> {
    let (c, rc) = (frame.stats.counters, reference.stats.counters);
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    let lens = Mask::lens(&reference.lens_pixels, LensSelection::All);
    let mut out = ReferenceReport {
        reference: ReferenceCost {
            ms: reference.stats.seconds * 1e3,
            rays: rc.all_rays(),
            triangle_tests: rc.triangle_tests,
        },
        reference_tree,
        reference_supersampling: args.reference_supersampling.unwrap_or(camera.supersampling),
        lens_radiance_ratio: crate::common::mean_ratio(&frame.image, reference, &lens),
        reduction: Reduction {
            time: ratio(reference.stats.seconds * 1e3, frame.total_ms),
            rays: ratio(rc.all_rays() as f64, c.all_rays() as f64),
            triangle_tests: ratio(rc.triangle_tests as f64, c.triangle_tests as f64),
        },
        lens_psnr_db: None,
        lens_psnr_linear_db: None,
        lens_pixels: None,
        glossy_psnr_db: None,
        glossy_pixels: None,
        non_lens_psnr_db: None,
        non_lens_pixels: None,
    };
    // The headline figure in display sRGB (clamped, what a viewer sees), and beside it the
    // linear one that also counts errors in highlights above 1. No lens pixel: no figure.
    match (
        lens_error(&frame.image, reference, Encoding::DisplaySrgb),
        lens_error(&frame.image, reference, Encoding::Linear),
    ) {
        (Ok(display), Ok(linear)) => {
            out.lens_psnr_db = Some(display.psnr_db);
            out.lens_psnr_linear_db = Some(linear.psnr_db);
            out.lens_pixels = Some(display.pixels);
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
            out.glossy_psnr_db = Some(display.psnr_db);
            out.glossy_pixels = Some(display.pixels);
        }
        Err(MetricsError::EmptyMask) => {}
        Err(error) => return Err(error.into()),
    }
    // The opaque environment (light-mapped) and the background: pixels no lens covers.
    match non_lens_error(&frame.image, reference, Encoding::DisplaySrgb) {
        Ok(display) => {
            out.non_lens_psnr_db = Some(display.psnr_db);
            out.non_lens_pixels = Some(display.pixels);
        }
        Err(MetricsError::EmptyMask) => {}
        Err(error) => return Err(error.into()),
    }
    Ok(out)
}

impl RenderReport {
    /// The table `lensmap render` prints (the same figures as the JSON).
    fn print_table(&self) {
        let h = &self.hybrid;
        // The threshold as JSON writes it (`3.0`), as the table always has.
        let t = serde_json::Value::from(self.t);
        say!(
            "{} {}×{} ({}×{} supersampling), t = {t}, {} {} on {} (driver {}), {} layered EMs",
            self.scene,
            self.width,
            self.height,
            self.supersampling,
            self.supersampling,
            self.variant,
            self.format,
            self.device,
            self.driver,
            self.layered_ems
        );
        let l = &self.light_maps;
        say!(
            "  light maps (once per scene): {:.0} ms, {:.1} MiB RGBA16F, {} charts at {:.1}–{:.1} texels/m, {} of {} texels shaded, {} supersampled",
            l.ms,
            l.gpu_bytes as f64 / 1048576.0,
            l.charts,
            l.min_texels_per_metre,
            l.max_texels_per_metre,
            l.shaded_texels,
            l.texels,
            l.supersampled_texels
        );
        say!(
            "  ray tracing at vertices ({}) {:>8.1} ms",
            self.tracer,
            h.ray_tracing_at_vertices_ms
        );
        say!(
            "  texture coordinate gen.     {:>10.1} ms",
            h.texture_coordinates_ms
        );
        say!(
            "  tessellation                {:>10.1} ms",
            h.tessellation_ms
        );
        say!(
            "  other (incl. rendering)     {:>10.1} ms   (GPU upload, render, readback {:.1} ms)",
            h.other_ms,
            h.gpu_ms
        );
        say!("  total frame time            {:>10.1} ms", h.total_ms);
        say!("  ray count                   {:>10}", h.rays);
        say!("  triangle intersection tests {:>10}", h.triangle_tests);
        say!(
            "  lens triangles {} → {} after tessellation, {} vertices traced",
            h.lens_triangles_in,
            h.lens_triangles_out,
            h.vertices_traced
        );
        if h.hull_triangles > 0 {
            say!(
                "  convex-hull split           {:>10} lens triangles drawn with the distant layer only",
                h.hull_triangles
            );
        }
        if h.builds_discarded > 0 {
            say!(
                "  built again                 {:>10} time(s): the GPU tessellation's buffers grew (the times above are the last build's)",
                h.builds_discarded
            );
        }
        if h.leaves_stopped_by_vertex_budget > 0 {
            warn!(
                "the frame's vertex budget was spent: {} triangles were left unsplit (coarser than t asks); raise --max-vertices or t",
                h.leaves_stopped_by_vertex_budget
            );
        }
        if let Some(r) = &self.reference {
            self.print_comparison(r);
        }
        say!(
            "  wrote {} and {}",
            self.out.display(),
            self.out_exr.display()
        );
    }

    fn print_comparison(&self, r: &ReferenceReport) {
        let (f, red) = (&r.reference, &r.reduction);
        say!(
            "  reference ray tracer ({} paths, {}×{} supersampling): {:.1} ms, {} rays, {} triangle tests",
            r.reference_tree.name(),
            r.reference_supersampling,
            r.reference_supersampling,
            f.ms,
            f.rays,
            f.triangle_tests
        );
        say!(
            "  reduction: time {:.1}×, rays {:.1}×, triangle tests {:.1}×",
            red.time,
            red.rays,
            red.triangle_tests
        );
        match (r.lens_psnr_db, r.lens_psnr_linear_db, r.lens_pixels) {
            (Some(display), Some(linear), Some(pixels)) => say!(
                "  PSNR over {pixels} lens pixels: {display:.2} dB (display sRGB, clamped to [0, 1]), {linear:.2} dB (linear HDR)"
            ),
            _ => say!("  no pixel is entirely lens in the reference: no lens PSNR"),
        }
        if let Some(ratio) = r.lens_radiance_ratio {
            say!("  mean lens radiance, frame / reference: {ratio:.3}");
        }
        if let (Some(display), Some(pixels)) = (r.glossy_psnr_db, r.glossy_pixels) {
            let maps = self.hybrid.glossy_maps_read;
            say!(
                "  PSNR over {pixels} glossy pixels: {display:.2} dB (display sRGB; {maps} radiance maps read{})",
                if maps == 0 {
                    ": light-mapped, diffuse only; give --radiance DIR"
                } else {
                    ""
                }
            );
        }
        if let (Some(display), Some(pixels)) = (r.non_lens_psnr_db, r.non_lens_pixels) {
            say!(
                "  PSNR over {pixels} non-lens pixels: {display:.2} dB (display sRGB, clamped to [0, 1])"
            );
        }
    }
}
