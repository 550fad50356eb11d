//! `lensmap reference`: render a ray-traced reference image of a scene (the final image, the two
//! term images and the lens mask, as linear EXR and sRGB PNG) with the greedy two-term model or the
//! full ray tree.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::Context;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use lensmap::scene::{Camera, Scene, SceneError};
use lensmap::trace::{
    self, PathModel, ReferenceImage, RenderStats, TraceOptions, TraceScene, image::validate_camera,
};

/// Prints a line on stdout; a closed stdout (`lensmap … | head`) ends the output, not the work.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// Arguments of `lensmap reference`.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Example:\n  lensmap reference --scene teapot-room --view 3 --tree greedy --out out/ref"
)]
pub struct ReferenceArgs {
    /// Built-in scene name (teapot-room, glass-sphere, mirror-teapot) or path to a scene .toml.
    #[arg(long)]
    pub scene: String,
    /// Render from viewpoint sample I of the scene's view space (0-based). Without --view or
    /// --camera-position the scene's camera is used.
    #[arg(long, value_name = "I", conflicts_with = "camera_position")]
    pub view: Option<usize>,
    /// Camera position "x,y,z" in metres (looking at the scene camera's look-at point unless
    /// --look-at is given).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_position: Option<Vec3>,
    /// Point the camera looks at, "x,y,z" in metres.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<Vec3>,
    /// Image width in pixels (default: the scene camera's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene camera's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Supersamples per pixel along each axis, k for k×k (default: the scene camera's).
    #[arg(long, value_name = "K")]
    pub supersampling: Option<u32>,
    /// Ray-path model: the paper's two-term greedy paths, or the full ray tree.
    #[arg(long, value_enum, default_value_t = Tree::Greedy)]
    pub tree: Tree,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Print the statistics as JSON on stdout instead of a summary.
    #[arg(long)]
    pub json: bool,
}

/// The ray-path model named on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tree {
    /// Two-term greedy ray paths (the paper's model).
    Greedy,
    /// Full binary ray tree (both children at every interface).
    Full,
}

impl From<Tree> for PathModel {
    fn from(tree: Tree) -> PathModel {
        match tree {
            Tree::Greedy => PathModel::Greedy,
            Tree::Full => PathModel::Full,
        }
    }
}

/// Parses "x,y,z" into a vector of three finite numbers.
pub fn parse_vec3(text: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected three comma-separated numbers x,y,z, got '{text}'"
        ));
    }
    let mut values = [0.0f32; 3];
    for (value, part) in values.iter_mut().zip(&parts) {
        *value = part
            .parse::<f32>()
            .map_err(|e| format!("'{part}' is not a number ({e})"))?;
        if !value.is_finite() {
            return Err(format!("'{part}' is not a finite number"));
        }
    }
    Ok(Vec3::from_array(values))
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
    lens_pixels: f64,
    files: Vec<PathBuf>,
}

/// Runs `lensmap reference`.
pub fn run(args: ReferenceArgs) -> anyhow::Result<()> {
    let scene = Scene::load_named(&args.scene)?;
    let camera = choose_camera(&scene, &args)?;
    let world = TraceScene::new(&scene).context("preparing the scene for ray tracing")?;
    let options = TraceOptions {
        model: args.tree.into(),
        ..TraceOptions::default()
    };

    let progress = progress_bar(u64::from(camera.height));
    let image = trace::render_reference(&world, &camera, &options, &|rows| {
        progress.set_position(u64::from(rows));
    })
    .context("rendering the reference image")?;
    progress.finish_and_clear();

    let mut files = image
        .write(&args.out)
        .context("writing the reference images")?
        .paths;
    let report = Report {
        scene: &scene.name,
        view: args.view,
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
        lens_pixels: lens_coverage(&image),
        files: Vec::new(),
    };
    let stats_path = args.out.join("stats.json");
    files.push(stats_path.clone());
    let report = Report { files, ..report };
    let json = serde_json::to_string_pretty(&report)?;
    std::fs::write(&stats_path, format!("{json}\n"))
        .with_context(|| format!("writing {}", stats_path.display()))?;

    if args.json {
        say!("{json}");
    } else {
        print_summary(&scene.name, &args.out, options.model, &image.stats, &image);
    }
    Ok(())
}

/// The camera the arguments ask for, validated; bad values are scene (input) errors.
fn choose_camera(scene: &Scene, args: &ReferenceArgs) -> Result<Camera, SceneError> {
    let file = PathBuf::from(&args.scene);
    let mut camera = match (args.view, args.camera_position) {
        (Some(view), _) => scene
            .camera_at_view(view)
            .ok_or_else(|| SceneError::Invalid {
                file: file.clone(),
                field: "--view".to_owned(),
                problem: format!(
                    "view {view} does not exist: the view space has {} viewpoint samples",
                    scene.view_space.len()
                ),
                fix: if scene.view_space.is_empty() {
                    "the scene has no view space; use --camera-position or the scene camera"
                        .to_owned()
                } else {
                    format!("give --view between 0 and {}", scene.view_space.len() - 1)
                },
            })?,
        (None, Some(position)) => scene.camera.with_position(position),
        (None, None) => scene.camera,
    };
    if let Some(look_at) = args.look_at {
        camera.look_at = look_at;
    }
    if let Some(width) = args.width {
        camera.width = width;
    }
    if let Some(height) = args.height {
        camera.height = height;
    }
    if let Some(k) = args.supersampling {
        camera.supersampling = k;
    }
    validate_camera(&camera).map_err(|error| SceneError::Invalid {
        file,
        field: "camera (after --view/--camera-position/--look-at/--width/--height/--supersampling)"
            .to_owned(),
        problem: error.to_string(),
        fix: "give a camera position distinct from the look-at point, an image of at least 1×1 \
              and --supersampling of at least 1"
            .to_owned(),
    })?;
    Ok(camera)
}

/// A row progress bar on stderr, hidden when stderr is not a terminal.
pub fn progress_bar(rows: u64) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(rows);
    if let Ok(style) = ProgressStyle::with_template(
        "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} rows (eta {eta})",
    ) {
        bar.set_style(style);
    }
    bar.set_message("ray tracing");
    bar
}

fn lens_coverage(image: &ReferenceImage) -> f64 {
    image.lens_mask.iter().map(|&m| f64::from(m)).sum()
}

fn print_summary(
    scene: &str,
    out: &Path,
    model: PathModel,
    stats: &RenderStats,
    image: &ReferenceImage,
) {
    say!(
        "{scene}: {}×{} with {k}×{k} supersampling, {model:?} paths, {:.2} s",
        stats.width,
        stats.height,
        stats.seconds,
        k = stats.supersampling,
    );
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
        "  triangle tests: {} ({:.1} per ray); lens objects cover {:.0} pixels",
        stats.counters.triangle_tests,
        stats.counters.triangle_tests_per_ray(),
        lens_coverage(image),
    );
    say!(
        "  wrote {}/{{reference,refraction,reflection,lens_mask}}.{{exr,png}} and stats.json",
        out.display()
    );
}
