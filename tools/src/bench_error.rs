//! `lensmap bench error`: run time against error. It sweeps the knobs that trade one for the other
//! (the tessellation threshold t, the angle threshold, the layer count, the EM size, the
//! compositor variant, the framebuffer format, supersampling, and inferred EMs when a bake is
//! given) at three cameras around a viewpoint sample (on it, halfway to the next, 15° above), and
//! measures for each setting the median frame time and the lens-pixel PSNR and SSIM against a
//! reference traced with more supersamples. Three baselines run in the same sweep: a classic single EM at
//! infinity, a parallax-corrected box probe (one box shell, what game engines ship), and the
//! reference ray tracer at one sample per pixel. The result is a table, JSON, CSV, and a Pareto
//! plot of time against error with the frontier marked.
//!
//! The reference's ray-path model is `--reference-tree`: the papers' greedy two terms (what the
//! frames' default model traces, so the error is the EMs' and the tessellation's alone) or the
//! full ray tree (the light; its own convergence between two supersampling levels is reported
//! beside it). The path-class settings (3, 4 and 6 classes, and 4 classes with t) put the class
//! set on the sweep's axes: against the full tree they show what the classes recover, against
//! the greedy reference how far they stand from the papers' model. A scene with a lens object
//! classes cannot shade (layered by bounce, or of glass and mirrors together) leaves them out,
//! saying so.
//!
//! The per-vertex CPU stages run in f64; the "CPU precision" settings run them in f32
//! ([`VertexPrecision::F32`]) at the default and at RGBA32F, and also report how far each f32
//! frame lies from its f64 twin over the lens pixels (linear RMS and largest difference): the
//! error single precision would add.

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use glam::Vec3;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{
        HybridOptions, HybridScene, ShadingTerms, paths::VertexPrecision, tessellate::DEFAULT_T,
    },
    layers::{
        Bake,
        projected::{DEFAULT_EM_SIZE, ProjectedOptions, em_origin},
    },
    metrics::{Channels, Encoding, ImageError, Mask},
    render::{BlendScheme, Compositing, RenderedImage, TargetFormat},
    runner::{EmSource, FrameOptions, FrameRunner, Repetitions, lens_error, load_hybrid_scene},
    scene::{Camera, LayerSpec, Scene},
    trace::{
        LensSelection, PathModel, ReferenceImage, TraceOptions, TraceScene, classes::ClassSet,
        image::srgb8, render_reference,
    },
};
use serde_json::json;

use crate::common::{BadUsage, Steps, reference_frame, report};

#[derive(Args)]
#[command(after_help = "Example:
  lensmap bench error --scene teapot-room --report out/error.json --csv out/error.csv --plot out/pareto")]
pub struct BenchErrorArgs {
    /// Built-in scene name or path.
    #[arg(long, default_value = "teapot-room")]
    scene: String,
    /// A bake of the scene holding samples A and A+1: adds settings with its inferred EMs.
    #[arg(long, value_name = "DIR")]
    bake: Option<PathBuf>,
    /// Viewpoint sample A the three cameras are placed around.
    /// Range: [0, ∞) (A and A + 1 must be samples of the scene).
    #[arg(long, default_value_t = 2)]
    sample: usize,
    /// Frame width.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Frame height.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 240)]
    height: u32,
    /// Supersampling k×k of the reference the frames are judged against.
    /// Range: [2, 16384].
    #[arg(long, default_value_t = 4)]
    reference_supersampling: u32,
    /// The reference's ray-path model: `greedy` (the papers' two terms, the frames' default
    /// model), `full` (the full ray tree: the light, also traced at half the supersampling to
    /// show it converged), or a path-class set. The 1-spp ray tracer baseline traces it too.
    #[arg(long, default_value = "greedy", value_name = "greedy|full|N|CLASSES", value_parser = crate::reference::parse_tree)]
    reference_tree: PathModel,
    /// Timed frames per setting and camera (after one warm-up frame); the median counts.
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 3)]
    frames: usize,
    /// Only every setting whose label contains this text (the default and the baselines always
    /// run).
    #[arg(long, value_name = "TEXT")]
    only: Option<String>,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Also write one CSV row per setting to this file.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Write the Pareto plot as pareto.svg and pareto.png into this folder.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Measure nothing: draw the --plot from an earlier run's --report FILE.
    #[arg(long, value_name = "FILE", requires = "plot")]
    replot: Option<PathBuf>,
}

/// The plot of an earlier run, from its JSON report.
fn replot(report: &Path, dir: &Path) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(report).with_context(|| format!("reading {}", report.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| BadUsage(format!("--replot {}: not JSON ({e})", report.display())))?;
    let field = |p: &serde_json::Value, name: &str| {
        p[name].as_f64().ok_or_else(|| {
            BadUsage(format!(
                "--replot {}: a point without \"{name}\"; give a report of lensmap bench error",
                report.display()
            ))
        })
    };
    let mut points = Vec::new();
    for p in json["points"].as_array().into_iter().flatten() {
        let series = p["series"].as_str().unwrap_or("?").to_owned();
        points.push(crate::pareto::PlotPoint {
            default: series == "default",
            series,
            x_ms: field(p, "frame_ms")?,
            y_db: field(p, "lens_psnr_db")?,
            frontier: p["on_frontier"] == true,
        });
    }
    if points.is_empty() {
        return Err(BadUsage(format!(
            "--replot {}: no points; give a report of lensmap bench error",
            report.display()
        ))
        .into());
    }
    let text = |name: &str| json[name].as_str().unwrap_or("?").to_owned();
    // Reports written before the driver was recorded name the device alone.
    let device = match json["driver"].as_str() {
        Some(driver) => format!("{}, driver {driver}", text("device")),
        None => text("device"),
    };
    let title = plot_title(&text("scene"), json["reference_tree"].as_str());
    crate::pareto::write(dir, &points, &title, &device)
}

/// The plot's title: the scene, and the reference's ray-path model where the report names it
/// (reports written before the model was recorded were judged against the greedy model).
fn plot_title(scene: &str, reference_tree: Option<&str>) -> String {
    format!(
        "{scene}, reference --tree {}",
        reference_tree.unwrap_or("greedy")
    )
}

/// Where a setting's layered EMs come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Ems {
    /// Projected onto the scene's shells (the first `layers` of them).
    Projected,
    /// Inferred by the baker (`--bake`).
    Inferred,
    /// Baseline: one sphere shell far beyond the scene, a classic EM indexed by direction.
    Infinity,
    /// Baseline: one box shell fitted to the room around the EM origin (a parallax-corrected
    /// box probe).
    BoxProbe,
}

impl Ems {
    fn name(self) -> &'static str {
        match self {
            Ems::Projected => "projected",
            Ems::Inferred => "inferred",
            Ems::Infinity => "EM at infinity",
            Ems::BoxProbe => "box probe",
        }
    }
}

/// One point of the sweep: every knob a frame's time and error depend on.
#[derive(Clone, Debug)]
struct Setting {
    /// Which knob the sweep moves here (the plot's series).
    family: &'static str,
    t: f32,
    angle_degrees: f64,
    em_size: u32,
    /// The first this many shells of each lens object; `None`: all of them.
    layers: Option<usize>,
    compositing: Compositing,
    format: TargetFormat,
    supersampling: u32,
    ems: Ems,
    /// The float type of the per-vertex CPU stages.
    precision: VertexPrecision,
    /// The terms each lens vertex traces (the scene file's by default).
    terms: ShadingTerms,
}

impl Setting {
    /// `lensmap render`'s defaults (t = 3, 3°, 128² projected EMs on every shell, single pass,
    /// RGBA16F) at one sample per pixel.
    fn default_setting() -> Setting {
        Setting {
            family: "default",
            t: DEFAULT_T,
            angle_degrees: lensmap::hybrid::DEFAULT_ANGLE_DEGREES,
            em_size: DEFAULT_EM_SIZE,
            layers: None,
            compositing: Compositing::SinglePass,
            format: TargetFormat::Rgba16f,
            supersampling: 1,
            ems: Ems::Projected,
            precision: VertexPrecision::F64,
            terms: ShadingTerms::Scene,
        }
    }

    /// The label names the precision only where it is not the default f64, so `--only f64`
    /// picks the f32 settings (compared with f64) rather than every setting; and the terms only
    /// where they are not the scene file's, so `--only terms` picks the path-class settings.
    fn label(&self) -> String {
        let precision = match self.precision {
            VertexPrecision::F64 => String::new(),
            other => format!(" CPU {} (vs f64)", other.name()),
        };
        let terms = match self.terms {
            ShadingTerms::Scene => String::new(),
            other => format!(" terms={}", other.name()),
        };
        format!(
            "{} t={} angle={}° em={} layers={} {} {} ss={}{terms}{precision}",
            self.ems.name(),
            self.t,
            self.angle_degrees,
            self.em_size,
            self.layers
                .map_or_else(|| "all".to_owned(), |n| n.to_string()),
            self.compositing.variant().name(),
            self.format.name(),
            self.supersampling
        )
    }

    /// This setting with the per-vertex stages in f64: what an f32 setting is compared with.
    fn f64_twin(&self) -> Setting {
        Setting {
            precision: VertexPrecision::F64,
            ..self.clone()
        }
    }

    /// Whether two settings render with the same knobs (the series aside).
    fn same_knobs(&self, other: &Setting) -> bool {
        self.label() == other.label()
    }

    /// The key of the hybrid scene this setting renders (its EMs).
    fn scene_key(&self) -> SceneKey {
        match self.ems {
            Ems::Projected => (self.ems, self.em_size, self.layers),
            Ems::Inferred => (self.ems, 0, None),
            Ems::Infinity | Ems::BoxProbe => (self.ems, self.em_size, None),
        }
    }
}

/// What tells the hybrid scenes of the settings apart: where the EMs come from, their size and
/// how many shells are kept.
type SceneKey = (Ems, u32, Option<usize>);

/// The sweep: the default; each knob moved alone; a t × EM-size grid; supersampling with t; t
/// with the angle threshold (on teapot-room 42 settings besides the default, 45 with a bake);
/// and the two EM baselines.
fn settings(layer_count: usize, inferred: bool) -> Vec<Setting> {
    let base = Setting::default_setting();
    let mut all = vec![base.clone()];
    let mut add = |family: &'static str, change: &dyn Fn(&mut Setting)| {
        let mut setting = Setting {
            family,
            ..base.clone()
        };
        change(&mut setting);
        all.push(setting);
    };
    for t in [0.5, 0.75, 1.0, 1.5, 2.0, 4.0, 6.0, 8.0] {
        add("t", &|s| s.t = t);
    }
    for angle in [1.5, 6.0, 12.0] {
        add("angle threshold", &|s| s.angle_degrees = angle);
    }
    for size in [32, 64, 256] {
        add("EM size", &|s| s.em_size = size);
    }
    for layers in 1..layer_count {
        add("layers", &|s| s.layers = Some(layers));
    }
    add("variant", &|s| {
        s.compositing = Compositing::Multipass(BlendScheme::FrontToBack)
    });
    add("CPU precision", &|s| s.precision = VertexPrecision::F32);
    add("CPU precision", &|s| {
        (s.precision, s.format) = (VertexPrecision::F32, TargetFormat::Rgba32f)
    });
    for format in [TargetFormat::Rgba8, TargetFormat::Rgba32f] {
        add("format", &|s| s.format = format);
    }
    for k in [2, 3] {
        add("supersampling", &|s| s.supersampling = k);
    }
    for t in [1.0, 2.0, 4.0, 8.0] {
        for size in [32, 64, 256] {
            add("t × EM size", &|s| (s.t, s.em_size) = (t, size));
        }
    }
    for t in [2.0, 4.0, 8.0] {
        add("supersampling 2 × t", &|s| (s.supersampling, s.t) = (2, t));
    }
    for angle in [1.5, 6.0] {
        for t in [1.0, 8.0] {
            add("t × angle", &|s| (s.t, s.angle_degrees) = (t, angle));
        }
    }
    if inferred {
        for t in [1.0, 3.0, 8.0] {
            add("inferred EMs", &|s| (s.ems, s.t) = (Ems::Inferred, t));
        }
    }
    // The class set as an axis (composited by the multipass variant, which takes any class set
    // at any layer count, so every row is drawn alike: the single pass carries K·(n + 1) ≤ 16
    // varyings): the first 3, 4 and 6 classes, and 4 classes with t moved.
    let classes = |s: &mut Setting, count: u8| {
        s.terms = ShadingTerms::Classes(ClassSet::First(count));
        s.compositing = Compositing::Multipass(BlendScheme::FrontToBack);
    };
    for count in [3, 4, 6] {
        add("path classes", &|s| classes(s, count));
    }
    for t in [1.0, 8.0] {
        add("path classes × t", &|s| {
            classes(s, 4);
            s.t = t;
        });
    }
    add("baseline: EM at infinity", &|s| s.ems = Ems::Infinity);
    add("baseline: box probe", &|s| s.ems = Ems::BoxProbe);
    all
}

/// The half extents of a box centred on lens `lens`'s EM origin fitted to the environment's
/// bounding box (every object outside the lens objects): per axis the mean of the distances to
/// the two walls, so the box meets the room halfway between its near and far walls (a box shell
/// is centred on the EM origin; a game engine's probe box is the room's own, which a room not
/// centred on the lens object cannot be here).
fn box_probe(scene: &Scene, lens: usize) -> Option<Vec3> {
    let in_lens: Vec<usize> = scene
        .lenses
        .iter()
        .flat_map(|l| l.objects.clone())
        .collect();
    let (low, high) = scene
        .objects
        .iter()
        .enumerate()
        .filter(|(i, _)| !in_lens.contains(i))
        .filter_map(|(_, object)| object.mesh.bounds())
        .reduce(|(a_low, a_high), (b_low, b_high)| (a_low.min(b_low), a_high.max(b_high)))?;
    let origin = em_origin(scene, lens).as_vec3();
    let half = ((origin - low).abs() + (high - origin).abs()) * 0.5;
    (half.min_element() > 0.0).then_some(half)
}

/// The hybrid scene a setting renders: the scene's shells cut to the first `layers`, or the
/// baselines' single shell, with projected EMs of `em_size`; or the bake's inferred EMs.
fn hybrid_scene(
    scene: &Scene,
    setting: &Setting,
    bake: Option<&Path>,
) -> anyhow::Result<HybridScene> {
    if setting.ems == Ems::Inferred {
        let dir = bake.context("inferred EMs need --bake")?;
        let ems = lensmap::hybrid::LayeredEms::Baked(Bake::read(dir)?);
        return Ok(HybridScene::new(scene.clone(), ems.into())?.0);
    }
    let mut scene = scene.clone();
    for lens in 0..scene.lenses.len() {
        let shells = match setting.ems {
            Ems::Infinity => vec![LayerSpec::Sphere(1.0e4)],
            Ems::BoxProbe => vec![LayerSpec::Box(box_probe(&scene, lens).with_context(
                || {
                    format!(
                        "a box probe for lens \"{}\" needs an environment around it",
                        scene.lenses[lens].name
                    )
                },
            )?)],
            _ => {
                let mut shells = scene.lenses[lens].layers.clone();
                if let Some(n) = setting.layers {
                    shells.truncate(n.max(1));
                }
                shells
            }
        };
        scene.lenses[lens].layers = shells;
    }
    let projected = ProjectedOptions::with_size(setting.em_size);
    Ok(load_hybrid_scene(scene, &EmSource::Projected(projected).into())?.0)
}

/// What one setting measured at one camera.
#[derive(Clone, Copy, Debug)]
struct Measured {
    /// Median frame time, ms.
    frame_ms: f64,
    /// Lens PSNR, display sRGB, dB.
    psnr_db: f64,
    /// Lens SSIM ([`lens_ssim`]).
    ssim: f64,
}

/// One measured point: a setting's median frame time, lens PSNR and SSIM, each averaged over the
/// cameras.
#[derive(Clone, Debug)]
struct Point {
    family: &'static str,
    label: String,
    frame_ms: f64,
    psnr_db: f64,
    ssim: f64,
    per_camera: Vec<Measured>,
    /// An f32 setting's frames against their f64 twins over the lens pixels, linear:
    /// `(RMS, largest difference)`, the RMS over the pooled squared differences of the cameras,
    /// the largest over all.
    f32_vs_f64: Option<(f64, f64)>,
}

impl Point {
    /// The point of `values` (one per camera): their means, and the values themselves.
    fn averaged(
        family: &'static str,
        label: String,
        values: &[Measured],
        f32_vs_f64: Option<(f64, f64)>,
    ) -> Point {
        let mean =
            |pick: fn(&Measured) -> f64| values.iter().map(pick).sum::<f64>() / values.len() as f64;
        Point {
            family,
            label,
            frame_ms: mean(|v| v.frame_ms),
            psnr_db: mean(|v| v.psnr_db),
            ssim: mean(|v| v.ssim),
            per_camera: values.to_vec(),
            f32_vs_f64,
        }
    }
}

/// SSIM over the lens pixels: image-compare's SSIM of the two images in display sRGB (8 bits,
/// per channel, over 8×8 windows, its map holding each window's value at its pixels; a negative
/// window counts as 0), averaged over the reference's fully covered lens pixels and the three
/// channels. An empty lens mask is an error.
fn lens_ssim(image: &RenderedImage, reference: &ReferenceImage) -> anyhow::Result<f64> {
    let size = (reference.width, reference.height);
    let to_image = |rgb: Vec<Vec3>| {
        image::RgbImage::from_raw(size.0, size.1, srgb8(&rgb))
            .context("an image of the frame's size")
    };
    let ours = to_image(image.rgb())?;
    let theirs = to_image(reference.radiance.clone())?;
    let similarity = image_compare::rgb_similarity_structure(
        &image_compare::Algorithm::MSSIMSimple,
        &ours,
        &theirs,
    )
    .map_err(|e| anyhow::anyhow!("SSIM: {e}"))?;
    // The crate names its map's type only through this 8-bit rendering of it (values clamped to
    // [0, 1] and truncated to 1/255): the mean below is within 1/255 of the map's.
    let map = similarity.image.to_color_map().to_rgb8();
    let mask = Mask::lens(&reference.lens_pixels, LensSelection::All);
    let (sum, count) = map
        .pixels()
        .enumerate()
        .filter(|(i, _)| mask.contains(*i))
        .fold((0.0f64, 0usize), |(sum, n), (_, p)| {
            let mean = p.0.iter().map(|&c| f64::from(c) / 255.0).sum::<f64>() / 3.0;
            (sum + mean, n + 1)
        });
    anyhow::ensure!(count > 0, "SSIM: the reference shows no lens pixel");
    Ok(sum / count as f64)
}

/// The points no other point beats in both time and error, fastest first.
fn frontier(points: &[Point]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        points[a]
            .frame_ms
            .total_cmp(&points[b].frame_ms)
            .then(points[b].psnr_db.total_cmp(&points[a].psnr_db))
    });
    let mut best = f64::NEG_INFINITY;
    order
        .into_iter()
        .filter(|&i| {
            let better = points[i].psnr_db > best;
            best = best.max(points[i].psnr_db);
            better
        })
        .collect()
}

pub fn run(args: BenchErrorArgs) -> anyhow::Result<()> {
    if let (Some(report), Some(dir)) = (&args.replot, &args.plot) {
        return replot(report, dir);
    }
    let scene = checked_scene(&args)?;
    let sweep = Sweep::new(&scene, &args);
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let device = runner.gpu().device_id().clone();
    let base = scene.camera.with_resolution(args.width, args.height, 1);
    let cameras = crate::bench_bake::cameras(&scene, args.sample, base);

    let mut steps = Steps::new(3);
    let scenes = hybrid_scenes(&scene, &sweep.settings, args.bake.as_deref(), &mut steps)?;
    say!(
        "{}: {}×{}, cameras around sample {} (on it, halfway, 15° above), reference {r}×{r} (--tree {}), {} timed frames per setting and camera, device {device}",
        scene.name,
        args.width,
        args.height,
        args.sample,
        args.reference_tree.name(),
        args.frames,
        r = args.reference_supersampling
    );
    let measured = measure(&mut runner, &args, &sweep, &scenes, &cameras, &mut steps)?;
    let results = Results::new(measured.points(&sweep.settings));
    results.print();
    let half = (args.reference_supersampling / 2).max(1);
    if !measured.convergence.is_empty() {
        let per_camera: Vec<String> = measured
            .convergence
            .iter()
            .map(|db| format!("{db:.2}"))
            .collect();
        say!(
            "the full-tree reference's own convergence ({half}×{half} against {r}×{r}, lens PSNR per camera): {} dB",
            per_camera.join(" / "),
            r = args.reference_supersampling
        );
    }
    let title = plot_title(&scene.name, Some(&args.reference_tree.name()));
    if let Some(path) = &args.csv {
        lensmap::atomic::write_atomically(path, results.csv().as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(dir) = &args.plot {
        crate::pareto::write(
            dir,
            &points_for_plot(&results.points, &results.on_frontier),
            &title,
            &device.to_string(),
        )?;
    }
    report(
        &json!({
            "scene": scene.name, "device": device.device, "driver": device.driver_description(), "width": args.width, "height": args.height,
            "reference_supersampling": args.reference_supersampling, "frames": args.frames,
            "reference_tree": args.reference_tree.name(),
            "reference_convergence": (!measured.convergence.is_empty()).then(|| json!({
                "supersampling": [half, args.reference_supersampling],
                "lens_psnr_db_per_camera": measured.convergence,
            })),
            "cameras": cameras.iter().map(|(name, c)| json!({"camera": name, "position": c.position})).collect::<Vec<_>>(),
            "encoding": "display sRGB, lens pixels of the reference; SSIM: image-compare's 8×8-window SSIM averaged over them",
            "default_gap_to_frontier_db": results.gap_db, "points": results.json_points(),
        }),
        args.report.as_deref(),
    )?;
    Ok(())
}

/// The scene, once the options are checked: a frame of at least 1×1 pixels, at least one frame,
/// a reference of at least 2×2 supersamples, and samples A and A+1 in the scene's view space.
fn checked_scene(args: &BenchErrorArgs) -> anyhow::Result<Scene> {
    if args.width == 0 || args.height == 0 || args.reference_supersampling < 2 || args.frames == 0 {
        return Err(BadUsage(format!(
            "--width {} --height {} --reference-supersampling {} --frames {}: give a frame of at least 1×1 pixels, at least one frame, and a reference of at least 2×2 supersamples (the 1-sample ray tracer is a baseline judged against it)",
            args.width, args.height, args.reference_supersampling, args.frames
        ))
        .into());
    }
    let scene = crate::common::load_scene(&args.scene)?;
    if args.sample >= scene.view_space.len().saturating_sub(1) {
        return Err(BadUsage(format!(
            "--sample {}: the cameras need samples A and A+1; scene \"{}\" has samples 0..{}",
            args.sample,
            scene.name,
            scene.view_space.len()
        ))
        .into());
    }
    Ok(scene)
}

/// Why a count of path classes cannot shade `scene`'s frames, if it cannot: a lens object
/// layered by bounce (its paths stop at the first bounce), or one of glass and mirrors together
/// (a count has no one order).
fn classes_do_not_apply(scene: &Scene) -> Option<String> {
    scene.lenses.iter().find_map(|lens| {
        if lens.layering == lensmap::layers::Layering::Bounce {
            return Some(format!(
                "lens object \"{}\" is layered by bounce",
                lens.name
            ));
        }
        let glass = |&o: &usize| {
            matches!(
                scene.materials[scene.objects[o].material],
                lensmap::scene::Material::Glass { .. }
            )
        };
        (lens.objects.iter().any(glass) && !lens.objects.iter().all(glass))
            .then(|| format!("lens object \"{}\" joins glass and mirrors", lens.name))
    })
}

/// The settings a run measures.
struct Sweep {
    /// The settings `--only` keeps, then the f64 twins of its f32 settings that it left out.
    settings: Vec<Setting>,
    /// Per setting: where its f64 twin stands in `settings`, for an f32 setting.
    twins: Vec<Option<usize>>,
}

impl Sweep {
    /// The sweep of [`settings`] for `scene`, cut by `--only` (the default and the baselines
    /// always stay), with every f32 setting's f64 twin measured too.
    fn new(scene: &Scene, args: &BenchErrorArgs) -> Sweep {
        let layer_count = scene
            .lenses
            .iter()
            .map(|l| l.layers.len())
            .max()
            .unwrap_or(1);
        let mut all = settings(layer_count, args.bake.is_some());
        if let Some(why) = classes_do_not_apply(scene) {
            say!("the path-class settings are left out: {why}");
            all.retain(|s| !matches!(s.terms, ShadingTerms::Classes(_)));
        }
        if let Some(text) = &args.only {
            all.retain(|s| {
                s.family == "default"
                    || s.family.starts_with("baseline")
                    || s.label().contains(text.as_str())
            });
        }
        for twin in all
            .iter()
            .filter(|s| s.precision != VertexPrecision::F64)
            .map(Setting::f64_twin)
            .collect::<Vec<_>>()
        {
            if !all.iter().any(|s| s.same_knobs(&twin)) {
                all.push(Setting {
                    family: "format",
                    ..twin
                });
            }
        }
        let twins = all
            .iter()
            .map(|s| {
                (s.precision != VertexPrecision::F64)
                    .then(|| all.iter().position(|t| t.same_knobs(&s.f64_twin())))
                    .flatten()
            })
            .collect();
        Sweep {
            settings: all,
            twins,
        }
    }
}

/// The hybrid scene of every setting, one per [`SceneKey`] (settings that differ only in how
/// they render share it).
fn hybrid_scenes(
    scene: &Scene,
    settings: &[Setting],
    bake: Option<&Path>,
    steps: &mut Steps,
) -> anyhow::Result<HashMap<SceneKey, HybridScene>> {
    let mut scenes = HashMap::new();
    let step = steps.counted(
        "layered EMs and light maps",
        settings.len() as u64,
        "settings",
    );
    for setting in settings {
        if let Entry::Vacant(slot) = scenes.entry(setting.scene_key()) {
            slot.insert(hybrid_scene(scene, setting, bake)?);
        }
        step.inc(1);
    }
    step.finish_and_clear();
    Ok(scenes)
}

/// What the sweep measured, camera by camera.
struct Measurements {
    /// Per setting, then last the 1-spp ray tracer: one value per camera.
    per_setting: Vec<Vec<Measured>>,
    /// Per f32 setting, one per camera: its frame against its f64 twin's over the lens pixels.
    against_f64: Vec<Vec<ImageError>>,
    /// Per camera, against the full tree: the reference at half its supersampling against it,
    /// lens PSNR (display sRGB), dB.
    convergence: Vec<f64>,
}

impl Measurements {
    /// The points: each setting's values averaged over the cameras, then the ray tracer's.
    fn points(&self, settings: &[Setting]) -> Vec<Point> {
        let mut points: Vec<Point> = settings
            .iter()
            .zip(&self.per_setting)
            .zip(&self.against_f64)
            .map(|((setting, values), errors)| {
                Point::averaged(setting.family, setting.label(), values, pooled(errors))
            })
            .collect();
        points.push(Point::averaged(
            "baseline: ray tracer, 1 spp",
            "reference ray tracer, 1 sample per pixel".into(),
            &self.per_setting[settings.len()],
            None,
        ));
        points
    }
}

/// The linear RMS over the pooled squared differences of `errors` and the largest difference
/// of all; `None` for no errors.
fn pooled(errors: &[ImageError]) -> Option<(f64, f64)> {
    let pixels: usize = errors.iter().map(|e| e.pixels).sum();
    (!errors.is_empty()).then(|| {
        let mse = errors.iter().map(|e| e.mse * e.pixels as f64).sum::<f64>() / pixels as f64;
        let max = errors.iter().map(|e| e.max_abs).fold(0.0, f64::max);
        (mse.sqrt(), max)
    })
}

/// Every setting and the 1-spp ray tracer at every camera, each judged against that camera's
/// reference; and each f32 setting's frame against its f64 twin's.
fn measure(
    runner: &mut FrameRunner,
    args: &BenchErrorArgs,
    sweep: &Sweep,
    scenes: &HashMap<SceneKey, HybridScene>,
    cameras: &[(&str, Camera)],
    steps: &mut Steps,
) -> anyhow::Result<Measurements> {
    let count = sweep.settings.len();
    let trace = &scenes[&Setting::default_setting().scene_key()].trace();
    let bar = steps.counted(
        "references and frames",
        (cameras.len() * (count + 2)) as u64,
        "renders",
    );
    let mut measured = Measurements {
        per_setting: vec![Vec::new(); count + 1],
        against_f64: vec![Vec::new(); count],
        convergence: Vec::new(),
    };
    let options = reference_options(args.reference_tree);
    for (_, camera) in cameras {
        let judge = camera.with_resolution(args.width, args.height, args.reference_supersampling);
        let reference = render_reference(trace, &judge, &options, &|_| {})?;
        if args.reference_tree == PathModel::Full {
            let half = camera.with_resolution(
                args.width,
                args.height,
                (args.reference_supersampling / 2).max(1),
            );
            let coarse = render_reference(trace, &half, &options, &|_| {})?;
            measured.convergence.push(
                lensmap::metrics::compare(
                    &coarse.radiance,
                    &reference.radiance,
                    &Mask::lens(&reference.lens_pixels, LensSelection::All),
                    Encoding::DisplaySrgb,
                    Channels::Rgb,
                )?
                .psnr_db,
            );
        }
        bar.inc(1);
        let mut images = Vec::with_capacity(count);
        for (i, setting) in sweep.settings.iter().enumerate() {
            let (values, image) =
                measure_setting(runner, args, setting, scenes, camera, &reference)?;
            measured.per_setting[i].push(values);
            images.push(image);
            bar.inc(1);
        }
        let lens_pixels = Mask::lens(&reference.lens_pixels, LensSelection::All);
        for (i, twin) in sweep.twins.iter().enumerate() {
            if let Some(twin) = twin {
                measured.against_f64[i].push(lensmap::metrics::compare(
                    &images[i].pixels,
                    &images[*twin].pixels,
                    &lens_pixels,
                    Encoding::Linear,
                    Channels::Rgb,
                )?);
            }
        }
        measured.per_setting[count].push(measure_ray_tracer(trace, args, camera, &reference)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(measured)
}

/// The reference tracer's options for ray-path model `model`.
fn reference_options(model: PathModel) -> TraceOptions {
    TraceOptions {
        model,
        ..TraceOptions::default()
    }
}

/// One setting at one camera: its median frame time over `--frames` timed frames (after one
/// warm-up), and its last frame's lens PSNR and SSIM against `reference`; with that frame.
fn measure_setting(
    runner: &mut FrameRunner,
    args: &BenchErrorArgs,
    setting: &Setting,
    scenes: &HashMap<SceneKey, HybridScene>,
    camera: &Camera,
    reference: &ReferenceImage,
) -> anyhow::Result<(Measured, RenderedImage)> {
    let camera = camera.with_resolution(args.width, args.height, setting.supersampling);
    let options = FrameOptions {
        hybrid: HybridOptions {
            angle_radians: setting.angle_degrees.to_radians(),
            precision: setting.precision,
            terms: setting.terms,
            ..HybridOptions::with_t(setting.t)
        },
        compositing: setting.compositing,
        format: setting.format,
    };
    runner.check_framebuffer(&camera, options.format)?;
    let frames = runner.timed_frames(
        &scenes[&setting.scene_key()],
        &camera,
        &options,
        Repetitions {
            warmup: 1,
            timed: args.frames,
        },
    )?;
    let image = &frames.last().image;
    let error = lens_error(image, reference, Encoding::DisplaySrgb)?;
    let values = Measured {
        frame_ms: frames.median(|f| f.total_ms),
        psnr_db: error.psnr_db,
        ssim: lens_ssim(image, reference)?,
    };
    Ok((values, image.clone()))
}

/// Baseline: the reference ray tracer at one sample per pixel, `--frames` times at `camera`;
/// its median time and its last image's lens PSNR and SSIM against `reference`.
fn measure_ray_tracer(
    trace: &TraceScene,
    args: &BenchErrorArgs,
    camera: &Camera,
    reference: &ReferenceImage,
) -> anyhow::Result<Measured> {
    let mut times = Vec::new();
    let mut image = None;
    for _ in 0..args.frames {
        let one = render_reference(
            trace,
            &camera.with_resolution(args.width, args.height, 1),
            &reference_options(args.reference_tree),
            &|_| {},
        )?;
        times.push(one.stats.seconds * 1e3);
        image = Some(one);
    }
    let as_frame = reference_frame(&image.context("at least one frame")?);
    let error = lens_error(&as_frame, reference, Encoding::DisplaySrgb)?;
    Ok(Measured {
        frame_ms: lensmap::runner::median(&mut times),
        psnr_db: error.psnr_db,
        ssim: lens_ssim(&as_frame, reference)?,
    })
}

/// The points with their Pareto frontier, and how far the default lies below it.
struct Results {
    /// The default first, then the sweep, then the 1-spp ray tracer.
    points: Vec<Point>,
    /// The points on the frontier ([`frontier`]).
    on_frontier: Vec<usize>,
    /// The best PSNR any point reaches in no more time than the default, less the default's,
    /// dB.
    gap_db: f64,
}

impl Results {
    fn new(points: Vec<Point>) -> Results {
        let on_frontier = frontier(&points);
        let default = &points[0];
        let best_in_time = points
            .iter()
            .filter(|p| p.frame_ms <= default.frame_ms)
            .map(|p| p.psnr_db)
            .fold(f64::NEG_INFINITY, f64::max);
        let gap_db = best_in_time - default.psnr_db;
        Results {
            points,
            on_frontier,
            gap_db,
        }
    }

    /// The table: one line per point, `*` on the frontier, then the frontier's summary.
    fn print(&self) {
        say!(
            "{:<28} {:>9} {:>8} {:>7}  {}",
            "series",
            "frame ms",
            "lens dB",
            "SSIM",
            "setting (per camera: ms / dB)"
        );
        for (i, point) in self.points.iter().enumerate() {
            let cameras_text: Vec<String> = point
                .per_camera
                .iter()
                .map(|m| format!("{:.0}/{:.2}", m.frame_ms, m.psnr_db))
                .collect();
            let against_f64 = point.f32_vs_f64.map_or_else(String::new, |(rms, max)| {
                format!("  f32 − f64 frame over the lens: RMS {rms:.3e}, max {max:.3e}")
            });
            say!(
                "{:<28} {:>9.1} {:>8.2}{} {:>6.4}  {}  [{}]{against_f64}",
                point.family,
                point.frame_ms,
                point.psnr_db,
                if self.on_frontier.contains(&i) {
                    "*"
                } else {
                    " "
                },
                point.ssim,
                point.label,
                cameras_text.join(" ")
            );
        }
        say!(
            "* on the Pareto frontier ({} of {} points); the default is {:.2} dB below the best point at no more time",
            self.on_frontier.len(),
            self.points.len(),
            self.gap_db
        );
    }

    /// One CSV row per point, after a header.
    fn csv(&self) -> String {
        let mut csv = String::from(
            "series,setting,frame_ms,lens_psnr_db,lens_ssim,on_frontier,f32_vs_f64_rms,f32_vs_f64_max\n",
        );
        for (i, point) in self.points.iter().enumerate() {
            let (rms, max) = point.f32_vs_f64.map_or_else(
                || (String::new(), String::new()),
                |(rms, max)| (format!("{rms:.6e}"), format!("{max:.6e}")),
            );
            csv.push_str(&format!(
                "{},{},{:.4},{:.4},{:.5},{},{rms},{max}\n",
                csv_text(point.family),
                csv_text(&point.label),
                point.frame_ms,
                point.psnr_db,
                point.ssim,
                self.on_frontier.contains(&i)
            ));
        }
        csv
    }

    /// The points as the JSON report's rows.
    fn json_points(&self) -> Vec<serde_json::Value> {
        self.points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                json!({
                    "series": p.family, "setting": p.label, "frame_ms": p.frame_ms,
                    "lens_psnr_db": p.psnr_db, "lens_ssim": p.ssim, "on_frontier": self.on_frontier.contains(&i),
                    "f32_vs_f64": p.f32_vs_f64.map(|(rms, max)| json!({"linear_rms": rms, "linear_max": max})),
                    "per_camera": p.per_camera.iter().map(|m| json!({"frame_ms": m.frame_ms, "lens_psnr_db": m.psnr_db, "lens_ssim": m.ssim})).collect::<Vec<_>>(),
                })
            })
            .collect()
    }
}

/// A CSV field: quoted, with quotes doubled (RFC 4180), as series names hold commas.
fn csv_text(text: &str) -> String {
    format!("\"{}\"", text.replace('"', "\"\""))
}

/// The plot's view of the points.
fn points_for_plot(points: &[Point], on_frontier: &[usize]) -> Vec<crate::pareto::PlotPoint> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| crate::pareto::PlotPoint {
            series: p.family.to_owned(),
            x_ms: p.frame_ms,
            y_db: p.psnr_db,
            frontier: on_frontier.contains(&i),
            default: i == 0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(frame_ms: f64, psnr_db: f64) -> Point {
        Point {
            family: "t",
            label: String::new(),
            frame_ms,
            psnr_db,
            ssim: 0.5,
            per_camera: Vec::new(),
            f32_vs_f64: None,
        }
    }

    /// The frontier is exactly the points no other point beats in both time and error, fastest
    /// first, checked against the definition by brute force on a fixed set with ties.
    #[test]
    fn the_frontier_is_the_set_of_undominated_points() {
        let points: Vec<Point> = [
            (10.0, 17.0),
            (12.0, 16.0),
            (12.0, 18.0),
            (20.0, 18.0),
            (30.0, 19.5),
            (25.0, 19.0),
            (40.0, 19.5),
            (5.0, 15.0),
        ]
        .into_iter()
        .map(|(ms, db)| point(ms, db))
        .collect();
        let frontier = frontier(&points);
        let dominated = |i: usize| {
            points.iter().enumerate().any(|(j, q)| {
                j != i
                    && q.frame_ms <= points[i].frame_ms
                    && q.psnr_db >= points[i].psnr_db
                    && (q.frame_ms < points[i].frame_ms || q.psnr_db > points[i].psnr_db)
            })
        };
        let mut expected: Vec<usize> = (0..points.len()).filter(|&i| !dominated(i)).collect();
        expected.sort_by(|&a, &b| points[a].frame_ms.total_cmp(&points[b].frame_ms));
        assert_eq!(frontier, expected);
        assert_eq!(frontier, [7, 0, 2, 5, 4]);
    }

    /// CSV text fields are quoted with their quotes doubled, so a comma stays inside its field.
    #[test]
    fn csv_text_quotes_commas_and_quotes() {
        assert_eq!(
            csv_text("baseline: ray tracer, 1 spp"),
            "\"baseline: ray tracer, 1 spp\""
        );
        assert_eq!(csv_text("a \"b\""), "\"a \"\"b\"\"\"");
    }
}
