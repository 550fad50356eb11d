//! `lensmap bench trace`: speed of the reference ray tracer on teapot-room (both ray-path models,
//! 1 and 2 threads, median of repeated runs), and the full ray tree against the greedy two-term
//! model on glass-sphere and teapot-room (image RMSE and PSNR, ray-count ratio).

use std::path::PathBuf;

use anyhow::Context;
use indicatif::ProgressBar;

use lensmap::metrics::{self, Channels, Encoding, Mask, MetricsError};
use lensmap::runner::median;
use lensmap::scene::Camera;
use lensmap::trace::{
    self, LensSelection, PathModel, RayTreeOptions, ReferenceImage, TraceCounters, TraceOptions,
    TraceScene,
};

/// Arguments of `lensmap bench trace`.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Example:\n  lensmap bench trace --width 320 --height 240 --supersampling 2 --report trace.json"
)]
pub struct BenchTraceArgs {
    /// Image width in pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height in pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Supersamples per pixel along each axis (k for k×k).
    /// Range: [1, 16384].
    #[arg(long, value_name = "K", default_value_t = 3)]
    pub supersampling: u32,
    /// Timed renders per configuration; the median is reported.
    /// Range: [1, 100000].
    #[arg(long, default_value_t = 3)]
    pub runs: u32,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

/// One timed configuration.
#[derive(serde::Serialize, Debug, Clone)]
struct SpeedRow {
    scene: String,
    tree: PathModel,
    threads: usize,
    median_seconds: f64,
    seconds: Vec<f64>,
    mrays_per_second: f64,
    rays_per_pixel: f64,
    triangle_tests_per_ray: f64,
    counters: TraceCounters,
}

/// Full ray tree against greedy paths on one scene.
#[derive(serde::Serialize, Debug, Clone)]
struct ComparisonRow {
    scene: String,
    /// The full tree's limits.
    full_tree: String,
    /// RMSE of the final images in display sRGB (clamped to [0, 1], then encoded), over all
    /// pixels and channels.
    rmse_srgb: f64,
    /// PSNR in dB for that RMSE with peak 1.
    psnr_db: f64,
    /// RMSE of linear radiance (unclamped) over pixels that see a lens object in either image;
    /// `None` when no pixel does.
    rmse_linear_lens_pixels: Option<f64>,
    /// Rays along light paths (primary + secondary), full tree / greedy.
    path_ray_ratio: f64,
    /// All rays including shadow rays, full tree / greedy.
    all_ray_ratio: f64,
    /// Secondary rays only (those spent on the lens objects and beyond), full tree / greedy.
    secondary_ray_ratio: f64,
}

#[derive(serde::Serialize)]
struct BenchReport {
    width: u32,
    height: u32,
    supersampling: u32,
    runs: u32,
    cpu_threads_available: usize,
    speed: Vec<SpeedRow>,
    full_vs_greedy: Vec<ComparisonRow>,
}

/// Runs `lensmap bench trace`.
pub fn run(args: BenchTraceArgs) -> anyhow::Result<()> {
    let runs = args.runs.max(1);
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut speed = Vec::new();
    let mut comparisons = Vec::new();
    say!(
        "reference ray tracer, {}×{} with {k}×{k} supersampling, median of {runs} runs \
         ({} CPU threads available)",
        args.width,
        args.height,
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        k = args.supersampling,
    );
    say!(
        "{:<14} {:<7} {:>7} {:>9} {:>9} {:>11} {:>11}",
        "scene",
        "tree",
        "threads",
        "median s",
        "Mrays/s",
        "rays/pixel",
        "tests/ray"
    );

    // Teapot-room: both models at 1 and 2 threads, `runs` each, and the uncut tree; glass-sphere:
    // both models and the uncut tree once.
    let bar =
        crate::common::Steps::new(1).counted("reference images", 4 * u64::from(runs) + 4, "images");
    for scene_name in ["teapot-room", "glass-sphere"] {
        let scene = crate::common::load_scene(scene_name)?;
        let bench = SceneBench {
            name: scene_name,
            world: TraceScene::new(&scene).context("preparing the scene for ray tracing")?,
            camera: Camera {
                width: args.width,
                height: args.height,
                supersampling: args.supersampling,
                ..scene.camera
            },
            bar: &bar,
        };
        // Speed on teapot-room; glass-sphere only joins the full-vs-greedy comparison.
        let (thread_counts, timed_runs): (&[usize], u32) = if scene_name == "teapot-room" {
            (&[1, 2], runs)
        } else {
            (&[2], 1)
        };
        let mut images: Vec<(PathModel, ReferenceImage)> = Vec::new();
        for model in [PathModel::Greedy, PathModel::Full] {
            for &threads in thread_counts {
                let (row, image) = bench.speed(model, threads, timed_runs)?;
                speed.push(row);
                if threads == *thread_counts.last().unwrap_or(&threads) {
                    images.push((model, image));
                }
            }
        }
        if let [(PathModel::Greedy, greedy), (PathModel::Full, full)] = images.as_slice() {
            comparisons.extend(bench.full_vs_greedy(greedy, full)?);
        }
    }

    bar.finish_and_clear();
    say_comparisons(&comparisons);

    let report = BenchReport {
        width: args.width,
        height: args.height,
        supersampling: args.supersampling,
        runs,
        cpu_threads_available: std::thread::available_parallelism().map_or(1, |n| n.get()),
        speed,
        full_vs_greedy: comparisons,
    };
    crate::common::report(&report, args.report.as_deref())
}

/// The reference ray tracer on one scene, at the benchmark's image size and sampling.
struct SceneBench<'a> {
    name: &'static str,
    world: TraceScene,
    camera: Camera,
    /// Counts every image rendered.
    bar: &'a ProgressBar,
}

impl SceneBench<'_> {
    /// `runs` timed renders with `model` on `threads` threads: the row (printed) and the last
    /// image.
    fn speed(
        &self,
        model: PathModel,
        threads: usize,
        runs: u32,
    ) -> anyhow::Result<(SpeedRow, ReferenceImage)> {
        let options = TraceOptions {
            model,
            ..TraceOptions::default()
        };
        let pool = thread_pool(threads)?;
        let mut seconds = Vec::new();
        let mut last = None;
        for _ in 0..runs {
            let image = pool.install(|| {
                trace::render_reference(&self.world, &self.camera, &options, &|_| {})
            })?;
            self.bar.inc(1);
            seconds.push(image.stats.seconds);
            last = Some(image);
        }
        let image = last.context("at least one run")?;
        let median = median(&mut seconds.clone());
        let counters = image.stats.counters;
        let row = SpeedRow {
            scene: self.name.to_owned(),
            tree: model,
            threads,
            median_seconds: median,
            seconds,
            mrays_per_second: counters.all_rays() as f64 / median.max(1e-12) / 1e6,
            rays_per_pixel: image.stats.rays_per_pixel(),
            triangle_tests_per_ray: counters.triangle_tests_per_ray(),
            counters,
        };
        say!(
            "{:<14} {:<7} {:>7} {:>9.3} {:>9.2} {:>11.1} {:>11.1}",
            row.scene,
            format!("{model:?}").to_lowercase(),
            threads,
            row.median_seconds,
            row.mrays_per_second,
            row.rays_per_pixel,
            row.triangle_tests_per_ray
        );
        Ok((row, image))
    }

    /// The full tree with its default limits, and one without a contribution cutoff to depth 6,
    /// each against the greedy paths. The uncut tree is closer to a complete binary tree, the
    /// shape whose cost the paper compares against.
    fn full_vs_greedy(
        &self,
        greedy: &ReferenceImage,
        full: &ReferenceImage,
    ) -> anyhow::Result<[ComparisonRow; 2]> {
        let defaults = RayTreeOptions::default();
        let label = format!("depth {}, cutoff {}", defaults.max_depth, defaults.cutoff);
        let with_defaults = compare(self.name, &label, greedy, full)?;
        let uncut = TraceOptions {
            model: PathModel::Full,
            tree: RayTreeOptions {
                max_depth: 6,
                cutoff: 0.0,
            },
            ..TraceOptions::default()
        };
        let image = thread_pool(2)?
            .install(|| trace::render_reference(&self.world, &self.camera, &uncut, &|_| {}))?;
        self.bar.inc(1);
        let uncut = compare(self.name, "depth 6, no cutoff", greedy, &image)?;
        Ok([with_defaults, uncut])
    }
}

/// A rayon pool of `threads` threads.
fn thread_pool(threads: usize) -> anyhow::Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("creating the rayon thread pool")
}

/// The full-vs-greedy table.
fn say_comparisons(comparisons: &[ComparisonRow]) {
    say!();
    say!("full ray tree vs greedy two-term paths (same image size and sampling):");
    say!(
        "{:<14} {:<20} {:>10} {:>9} {:>14} {:>15} {:>14} {:>14}",
        "scene",
        "full tree",
        "RMSE sRGB",
        "PSNR dB",
        "RMSE lens lin",
        "path-ray ratio",
        "all-ray ratio",
        "2nd-ray ratio"
    );
    for c in comparisons {
        say!(
            "{:<14} {:<20} {:>10.4} {:>9.2} {:>14} {:>15.2} {:>14.2} {:>14.2}",
            c.scene,
            c.full_tree,
            c.rmse_srgb,
            c.psnr_db,
            c.rmse_linear_lens_pixels
                .map_or_else(|| "-".to_owned(), |rmse| format!("{rmse:.4}")),
            c.path_ray_ratio,
            c.all_ray_ratio,
            c.secondary_ray_ratio
        );
    }
    say!("(the paper reports about 5× more ray queries for the full tree)");
}

/// The full tree's image against the greedy one: display-sRGB error over every pixel, linear
/// error over the pixels either image sees any lens in, and the ray-count ratios.
fn compare(
    scene: &str,
    full_tree: &str,
    greedy: &ReferenceImage,
    full: &ReferenceImage,
) -> anyhow::Result<ComparisonRow> {
    let all = Mask::all(greedy.radiance.len());
    let display = metrics::compare(
        &full.radiance,
        &greedy.radiance,
        &all,
        Encoding::DisplaySrgb,
        Channels::Rgb,
    )?;
    // Both images see the same first hits, so their lens pixels are one set.
    let lens = Mask::lens(&greedy.lens_pixels, LensSelection::All);
    // No lens pixel at all (a tiny image): no figure, never a zero.
    let linear = match metrics::compare(
        &full.radiance,
        &greedy.radiance,
        &lens,
        Encoding::Linear,
        Channels::Rgb,
    ) {
        Ok(error) => Some(error.rmse),
        Err(MetricsError::EmptyMask) => None,
        Err(error) => return Err(error.into()),
    };
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let (g, f) = (greedy.stats.counters, full.stats.counters);
    Ok(ComparisonRow {
        scene: scene.to_owned(),
        full_tree: full_tree.to_owned(),
        rmse_srgb: display.rmse,
        psnr_db: display.psnr_db,
        rmse_linear_lens_pixels: linear,
        path_ray_ratio: ratio(f.path_rays(), g.path_rays()),
        all_ray_ratio: ratio(f.all_rays(), g.all_rays()),
        secondary_ray_ratio: ratio(f.secondary_rays, g.secondary_rays),
    })
}
