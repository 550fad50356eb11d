//! `lensmap reference`: render a ray-traced reference image of a scene (the final image, the two
//! term images and the lens mask, as linear EXR and sRGB PNG) with the greedy two-term model or the
//! full ray tree.

use std::path::{Path, PathBuf};

use anyhow::Context;
use lensmap::metrics::Mask;
use lensmap::trace::{
    self, LensSelection, PathModel, ReferenceImage, RenderStats, TraceOptions, TraceScene,
};

use crate::common::{CameraArgs, Steps, choose_camera, write_json};

/// Arguments of `lensmap reference`.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Example:\n  lensmap reference --scene teapot-room --view 3 --tree greedy --out out/ref"
)]
pub struct ReferenceArgs {
    /// Built-in scene name (teapot-room, glass-sphere, mirror-teapot) or path to a scene .toml.
    #[arg(long)]
    pub scene: String,
    /// The camera.
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Ray-path model: `greedy` (the paper's two greedy terms), `full` (the full ray tree), or
    /// path classes: a count N (the first N of R, TT, TRT, TRRT, … for glass; of R, RR, … for
    /// mirrors) or a list such as `R,TT,TRT,TRRT` (docs/reference.md#path-classes).
    #[arg(long, default_value = "greedy", value_name = "greedy|full|N|CLASSES", value_parser = parse_tree)]
    pub tree: PathModel,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Directions sampled per camera ray that meets a glossy surface.
    /// At least 2, so that the estimate's error can be estimated too.
    /// Range: [2, 1048576].
    #[arg(long, default_value_t = lensmap::trace::shade::DEFAULT_GLOSSY_SAMPLES, value_parser = clap::value_parser!(u32).range(2..))]
    pub glossy_samples: u32,
    /// Seed of the glossy samples: two seeds give independent estimates.
    /// Range: any.
    #[arg(long, default_value_t = 0)]
    pub glossy_seed: u64,
}

/// `--tree`'s value: `greedy`, `full`, or a class set ([`trace::ClassSet::parse`]).
pub fn parse_tree(text: &str) -> Result<PathModel, String> {
    match text {
        "greedy" => Ok(PathModel::Greedy),
        "full" => Ok(PathModel::Full),
        _ => trace::ClassSet::parse(text)
            .map(PathModel::Classes)
            .map_err(|problem| format!("{problem}; or give greedy or full")),
    }
}

/// What `--json` prints and `stats.json` holds.
#[derive(serde::Serialize)]
struct Report<'a> {
    scene: &'a str,
    view: Option<usize>,
    tree: PathModel,
    camera_position: [f32; 3],
    look_at: [f32; 3],
    width: u32,
    height: u32,
    supersampling: u32,
    primary_rays: u64,
    secondary_rays: u64,
    shadow_rays: u64,
    all_rays: u64,
    triangle_tests: u64,
    seconds: f64,
    mrays_per_second: f64,
    rays_per_pixel: f64,
    triangle_tests_per_ray: f64,
    lens_pixels: usize,
    /// Under path classes: the share of the lens objects' throughput (Σ F·G over camera rays)
    /// the classes drop; null under the other models.
    class_dropped: Option<f64>,
    glossy: Glossiness,
    files: Vec<PathBuf>,
}

/// The glossy surfaces' Monte Carlo estimate: its samples, the pixels that show a glossy surface
/// and the root mean square of their standard errors (null without glossy pixels).
#[derive(serde::Serialize)]
struct Glossiness {
    samples: u32,
    seed: u64,
    pixels: usize,
    rms_standard_error: Option<f64>,
}

impl Glossiness {
    fn of(image: &ReferenceImage, options: &TraceOptions) -> Glossiness {
        let errors: Vec<f64> = image
            .glossy_error
            .iter()
            .zip(&image.glossy_mask)
            .filter(|&(_, &mask)| mask > 0.0)
            .map(|(&e, _)| f64::from(e))
            .collect();
        let rms = (!errors.is_empty())
            .then(|| (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt());
        Glossiness {
            samples: options.glossy_samples,
            seed: options.glossy_seed,
            pixels: errors.len(),
            rms_standard_error: rms,
        }
    }
}

/// Runs `lensmap reference`.
pub fn run(args: ReferenceArgs) -> anyhow::Result<()> {
    let mut steps = Steps::new(3);
    let scene = crate::common::load_scene(&args.scene)?;
    let camera = choose_camera(&scene, &args.scene, &args.camera)?;
    if crate::common::validate_only() {
        return Ok(());
    }
    let step = steps.step("preparing the scene for ray tracing");
    let world = TraceScene::new(&scene).context("preparing the scene for ray tracing")?;
    step.finish_and_clear();
    let options = TraceOptions {
        model: args.tree,
        glossy_samples: args.glossy_samples,
        glossy_seed: args.glossy_seed,
        ..TraceOptions::default()
    };

    let progress = steps.counted("ray tracing", u64::from(camera.height), "rows");
    let image = trace::render_reference(&world, &camera, &options, &|rows| {
        progress.set_position(u64::from(rows));
    })
    .context("rendering the reference image")?;
    progress.finish_and_clear();

    let step = steps.step("writing the images");
    let mut files = image
        .write(&args.out)
        .context("writing the reference images")?
        .paths;
    let report = Report {
        scene: &scene.name,
        view: args.camera.view,
        tree: options.model,
        camera_position: camera.position.to_array(),
        look_at: camera.look_at.to_array(),
        width: camera.width,
        height: camera.height,
        supersampling: camera.supersampling,
        primary_rays: image.stats.counters.primary_rays,
        secondary_rays: image.stats.counters.secondary_rays,
        shadow_rays: image.stats.counters.shadow_rays,
        all_rays: image.stats.counters.all_rays(),
        triangle_tests: image.stats.counters.triangle_tests,
        seconds: image.stats.seconds,
        mrays_per_second: image.stats.mrays_per_second(),
        rays_per_pixel: image.stats.rays_per_pixel(),
        triangle_tests_per_ray: image.stats.counters.triangle_tests_per_ray(),
        lens_pixels: lens_pixel_count(&image),
        class_dropped: match options.model {
            PathModel::Classes(_) => image.stats.class_share.dropped(),
            _ => None,
        },
        glossy: Glossiness::of(&image, &options),
        files: Vec::new(),
    };
    let stats_path = args.out.join("stats.json");
    files.push(stats_path.clone());
    let report = Report { files, ..report };
    write_json(&stats_path, &report)?;
    step.finish_and_clear();
    crate::common::report(&report, None)?;
    print_summary(&scene.name, &args.out, options.model, &image.stats, &image);
    if let Some(rms) = report.glossy.rms_standard_error {
        say!(
            "  glossy surfaces: {} pixels, {} samples per camera ray (seed {}), standard error {rms:.2e} (root mean square over those pixels)",
            report.glossy.pixels,
            options.glossy_samples,
            options.glossy_seed
        );
    }
    Ok(())
}

/// The number of lens pixels, by the engine's rule ([`lensmap::trace::lens_pixels`]).
fn lens_pixel_count(image: &ReferenceImage) -> usize {
    Mask::lens(&image.lens_pixels, LensSelection::All).selected()
}

fn print_summary(
    scene: &str,
    out: &Path,
    model: PathModel,
    stats: &RenderStats,
    image: &ReferenceImage,
) {
    say!(
        "{scene}: {}×{} with {k}×{k} supersampling, {} paths, {:.2} s",
        stats.width,
        stats.height,
        model.name(),
        stats.seconds,
        k = stats.supersampling,
    );
    if let (PathModel::Classes(_), Some(dropped)) = (model, stats.class_share.dropped()) {
        say!(
            "  the classes drop {:.2} % of the lens objects' throughput (Σ F·G over camera rays)",
            100.0 * dropped
        );
    }
    say!(
        "  rays: {} primary, {} secondary, {} shadow, {} in all ({:.1} per pixel, {:.2} Mrays/s)",
        stats.counters.primary_rays,
        stats.counters.secondary_rays,
        stats.counters.shadow_rays,
        stats.counters.all_rays(),
        stats.rays_per_pixel(),
        stats.mrays_per_second(),
    );
    say!(
        "  triangle tests: {} ({:.1} per ray); {} lens pixels",
        stats.counters.triangle_tests,
        stats.counters.triangle_tests_per_ray(),
        lens_pixel_count(image),
    );
    say!(
        "  wrote {}/{{reference,refraction,reflection,lens_mask}}.{{exr,png}} and stats.json",
        out.display()
    );
}
