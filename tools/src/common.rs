//! What several commands share: how a command talks (`--json`, `--quiet`, results on stdout that
//! survive a closed pipe, status and progress on stderr), usage errors and the option enums,
//! camera arguments and their validation, progress and JSON reports.

use lensmap::{hybrid::ShadingTerms, trace::PathModel};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::ValueEnum;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lensmap::hybrid::FresnelModel;
use lensmap::options::{OptionError, Worded};
use lensmap::render::{BlendScheme, RenderedImage, TargetFormat, Variant};
use lensmap::scene::{Camera, Scene, SceneError};
use lensmap::trace::ReferenceImage;
use lensmap::trace::image::validate_camera;

/// Prints a line of the human-readable result on stdout: nothing under `--json` (the JSON
/// document is the result then) or `--quiet`. Once stdout is closed (`lensmap … | head -1`)
/// nothing more is printed, the work and the files it was asked to write are finished, and the
/// program then ends quietly with [`CLOSED_PIPE_EXIT`] ([`exit_status`]).
macro_rules! say {
    () => {{
        $crate::common::say_line(format_args!(""));
    }};
    ($($arg:tt)*) => {{
        $crate::common::say_line(format_args!($($arg)*));
    }};
}

/// Prints a warning on stderr, whatever `--quiet` says: an adjusted value or a spent budget is
/// never silent.
macro_rules! warn {
    ($($arg:tt)*) => {{
        $crate::common::tell(format_args!("warning: {}", format_args!($($arg)*)));
    }};
}

/// Writes one line to stderr, ignoring a closed or full stderr (where `eprintln!` panics): the
/// exit code still says what happened.
pub fn tell(line: std::fmt::Arguments) {
    use std::io::Write as _;
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}

/// How every command talks, from the global flags: the same on every command.
#[derive(Clone, Copy, Debug, Default)]
pub struct Voice {
    /// `--json`: the result is one JSON document on stdout and nothing else is printed there;
    /// an error is one JSON line on stderr.
    pub json: bool,
    /// `--quiet`: no progress and no human-readable report (errors, warnings and the `--json`
    /// document still print).
    pub quiet: bool,
    /// `--validate-only`: every check, then exit 0 before any work ([`validate_only`]).
    pub validate_only: bool,
}

static VOICE: OnceLock<Voice> = OnceLock::new();

/// Sets how the commands talk, once, before any command runs.
pub fn set_voice(voice: Voice) {
    let _ = VOICE.set(voice);
}

/// How the commands talk (the default before [`set_voice`]: human, not quiet).
pub fn voice() -> Voice {
    VOICE.get().copied().unwrap_or_default()
}

/// Whether the command stops here, its checks done (`--validate-only`): each command asks once,
/// after its last check of the command line and the files it names and before it makes a device
/// or allocates for the work.
pub fn validate_only() -> bool {
    voice().validate_only
}

/// The exit status after stdout was closed: 128 + SIGPIPE, what a shell reports for a program
/// that SIGPIPE ended.
pub const CLOSED_PIPE_EXIT: u8 = 128 + 13;

/// Set once a write to stdout found the reader gone.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes one line of the human report to stdout (see `say!`).
pub fn say_line(line: std::fmt::Arguments) {
    let voice = voice();
    if voice.json || voice.quiet {
        return;
    }
    write_stdout(line);
}

/// Writes one line to stdout; remembers a closed stdout and prints nothing more. Other write
/// errors are ignored (a full disk behind a redirect does not stop the work).
pub fn write_stdout(line: std::fmt::Arguments) {
    use std::io::Write as _;
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return;
    }
    if let Err(error) = writeln!(std::io::stdout().lock(), "{line}")
        && error.kind() == std::io::ErrorKind::BrokenPipe
    {
        STDOUT_CLOSED.store(true, Ordering::Relaxed);
    }
}

/// The exit status for a run that succeeded: [`CLOSED_PIPE_EXIT`] when stdout was closed
/// under it, else success.
pub fn exit_status() -> std::process::ExitCode {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        std::process::ExitCode::from(CLOSED_PIPE_EXIT)
    } else {
        std::process::ExitCode::SUCCESS
    }
}

/// A command's machine-readable result: printed on stdout under `--json` (pretty, the only
/// thing there), and written atomically to `file` when one was asked for (`--report FILE`),
/// which the human report then names.
pub fn report(value: &impl serde::Serialize, file: Option<&Path>) -> anyhow::Result<()> {
    if let Some(path) = file {
        write_json(path, value)?;
    }
    if voice().json {
        write_stdout(format_args!("{}", serde_json::to_string_pretty(value)?));
    } else if let Some(path) = file {
        say!("wrote {}", path.display());
    }
    Ok(())
}

/// A usage error the parser cannot catch (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadUsage(pub String);

/// A library option error as the command line says it: the flag (the option's name with `_`
/// written `-`), the value and the fix.
pub fn flag_error(error: OptionError) -> BadUsage {
    BadUsage(error.worded(&crate::words::Flags))
}

/// `--variant`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VariantArg {
    /// The paper's 4n-pass scheme.
    Multipass,
    /// One draw per lens object.
    SinglePass,
}

impl From<VariantArg> for Variant {
    fn from(v: VariantArg) -> Variant {
        match v {
            VariantArg::Multipass => Variant::Multipass,
            VariantArg::SinglePass => Variant::SinglePass,
        }
    }
}

/// `--blend`: how the multipass variant combines layers and (viewpoint, term) groups.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum BlendArg {
    /// The paper's: layers nearest first with src·(1 − dstα) + dst, alpha clears between groups.
    FrontToBack,
    /// Layers farthest first with src + dst·(1 − srcα) into a scratch image, added per group.
    BackToFront,
    /// Each group into its own image, one resolve summing them.
    GroupTargets,
    /// The blend in the fragment shader, reading the previous pass's image.
    Programmable,
}

impl From<BlendArg> for BlendScheme {
    fn from(b: BlendArg) -> BlendScheme {
        match b {
            BlendArg::FrontToBack => BlendScheme::FrontToBack,
            BlendArg::BackToFront => BlendScheme::BackToFront,
            BlendArg::GroupTargets => BlendScheme::GroupTargets,
            BlendArg::Programmable => BlendScheme::Programmable,
        }
    }
}

/// `--format`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FormatArg {
    /// 8-bit unorm.
    Rgba8,
    /// 16-bit float.
    Rgba16f,
    /// 32-bit float.
    Rgba32f,
}

impl From<FormatArg> for TargetFormat {
    fn from(f: FormatArg) -> TargetFormat {
        match f {
            FormatArg::Rgba8 => TargetFormat::Rgba8,
            FormatArg::Rgba16f => TargetFormat::Rgba16f,
            FormatArg::Rgba32f => TargetFormat::Rgba32f,
        }
    }
}

/// Writes a JSON report (pretty, ending in a newline) atomically, creating its folder.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let mut json = serde_json::to_string_pretty(value)?;
    json.push('\n');
    lensmap::atomic::write_atomically(path, json.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// The reference ray tracer's image as a frame (its radiance, alpha 1), to be judged or shown
/// like one.
pub fn reference_frame(reference: &ReferenceImage) -> RenderedImage {
    RenderedImage {
        width: reference.width,
        height: reference.height,
        pixels: reference
            .radiance
            .iter()
            .map(|p| [p.x, p.y, p.z, 1.0])
            .collect(),
    }
}

/// The frames a benchmark judges and the independent reference it judges them against (`bench
/// infer`, `bench bake`).
#[derive(clap::Args)]
pub struct JudgeArgs {
    /// Image width.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Supersampling k×k of the hybrid framebuffer (and of the targets, where there are any).
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 3)]
    pub supersampling: u32,
    /// Supersampling of the independent reference the frames are judged against.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 6)]
    pub reference_supersampling: u32,
}

impl JudgeArgs {
    /// `camera` at the judged frames' size and supersampling.
    pub fn frame_camera(&self, camera: &Camera) -> Camera {
        camera.with_resolution(self.width, self.height, self.supersampling)
    }

    /// `camera` at the reference's size and supersampling.
    pub fn reference_camera(&self, camera: &Camera) -> Camera {
        camera.with_resolution(self.width, self.height, self.reference_supersampling)
    }

    /// Every size and supersampling at least 1.
    pub fn validate(&self) -> Result<(), BadUsage> {
        if self.width == 0
            || self.height == 0
            || self.supersampling == 0
            || self.reference_supersampling == 0
        {
            return Err(BadUsage(format!(
                "--width {} --height {} --supersampling {} --reference-supersampling {}: give values ≥ 1",
                self.width, self.height, self.supersampling, self.reference_supersampling
            )));
        }
        Ok(())
    }
}

/// Which camera to render from (default: the scene's camera).
#[derive(clap::Args, Debug, Clone)]
pub struct CameraArgs {
    /// Render from viewpoint sample I of the scene's view space (0-based). Without --view or
    /// --camera-position the scene's camera is used.
    /// Range: [0, ∞) (a sample of the scene's view space).
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
    /// Range: [1, 16384].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene camera's).
    /// Range: [1, 16384].
    #[arg(long)]
    pub height: Option<u32>,
    /// Supersamples per pixel along each axis, k for k×k (default: the scene camera's).
    /// Range: [1, 16384].
    #[arg(long, value_name = "K")]
    pub supersampling: Option<u32>,
}

/// `on` or `off`.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

impl OnOff {
    /// Whether it is `on`.
    pub fn is_on(self) -> bool {
        self == OnOff::On
    }
}

/// `--tracer`: where the lens vertices are ray traced.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TracerArg {
    /// On the CPU, in f64 (the paper's reference implementation).
    Cpu,
    /// On the GPU, in f32, by a compute pass over the scene's resident BVHs.
    Gpu,
    /// The GPU on a hardware device, the CPU on a CPU device such as lavapipe (where the CPU
    /// path is measured faster).
    Auto,
}

impl TracerArg {
    /// The name `--tracer` takes.
    pub fn name(self) -> &'static str {
        lensmap::hybrid::VertexTracer::from(self).name()
    }
}

impl From<TracerArg> for lensmap::hybrid::VertexTracer {
    fn from(arg: TracerArg) -> Self {
        match arg {
            TracerArg::Cpu => lensmap::hybrid::VertexTracer::Cpu,
            TracerArg::Gpu => lensmap::hybrid::VertexTracer::Gpu,
            TracerArg::Auto => lensmap::hybrid::VertexTracer::Auto,
        }
    }
}

/// `--traversal`: how the GPU tracer finds a ray's hits.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraversalArg {
    /// The walk measured faster on the device (docs/results.md#gpu-traversal).
    Auto,
    /// The tracer's own BVH, walked with a stack in a compute shader: every device.
    Bvh,
    /// The driver's acceleration structures, walked with ray queries: devices with
    /// VK_KHR_acceleration_structure and VK_KHR_ray_query (Mesa 25's lavapipe, most GPUs).
    Driver,
}

impl From<TraversalArg> for lensmap::hybrid::gpu::Traversal {
    fn from(arg: TraversalArg) -> Self {
        match arg {
            TraversalArg::Auto => lensmap::hybrid::gpu::Traversal::Auto,
            TraversalArg::Bvh => lensmap::hybrid::gpu::Traversal::Bvh,
            TraversalArg::Driver => lensmap::hybrid::gpu::Traversal::Driver,
        }
    }
}

/// `--gpu-precision`: what the GPU tracer computes in.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuPrecisionArg {
    /// Single precision: every device, the fastest.
    F32,
    /// Double precision, the CPU oracle's: the same paths as the CPU path; devices with
    /// shaderFloat64.
    F64,
}

impl From<GpuPrecisionArg> for lensmap::hybrid::paths::VertexPrecision {
    fn from(arg: GpuPrecisionArg) -> Self {
        match arg {
            GpuPrecisionArg::F32 => lensmap::hybrid::paths::VertexPrecision::F32,
            GpuPrecisionArg::F64 => lensmap::hybrid::paths::VertexPrecision::F64,
        }
    }
}

/// The command-line flags that give `options`' vertex tracer: `--tracer`, `--traversal` and
/// `--gpu-precision` (what a screenshot's render command repeats).
pub fn tracer_flags(options: &lensmap::hybrid::HybridOptions) -> String {
    format!(
        "--tracer {} --traversal {} --gpu-precision {}",
        options.tracer.name(),
        options.traversal.name(),
        options.gpu_precision.name()
    )
}

/// The walk the GPU tracer takes on `gpu` with these options (`bvh`, `driver`), or `None` where
/// the vertices are traced on the CPU or the walk or the precision cannot be had there (with
/// `--tracer gpu` the frame then fails saying why; `auto` traces on the CPU).
pub fn gpu_walk(
    gpu: &lensmap::gpu::Gpu,
    options: &lensmap::hybrid::HybridOptions,
) -> Option<&'static str> {
    let f64_missing = options.gpu_precision == lensmap::hybrid::paths::VertexPrecision::F64
        && !gpu.shader_float64();
    if !options.tracer.on_gpu(gpu) || f64_missing {
        return None;
    }
    options.traversal.resolve(gpu).ok().map(|walk| walk.name())
}

/// The help of `--hull-split`, the same on every command that takes it.
pub const HULL_SPLIT_HELP: &str = "The convex-hull split (PEM paper §4): a lens object layered by bounce draws its triangles on the convex hull of the lens geometry with the distant layer only, as they cannot show self-reflections; no effect on lens objects layered by distance";

/// The help of `--fresnel`, the same on every command that takes it.
pub const FRESNEL_HELP: &str = "How each lens vertex evaluates Fresnel: exact (Schlick for mirrors, exact dielectric Fresnel for glass), or table:N, Schlick with its (1 − cos θ)⁵ looked up in a 1D table of N texels (2 to 4096), linearly filtered like a texture (the PEM paper's 1D Fresnel texture)";

/// Parses a frame's `--terms`: `scene`, `greedy`, or a path-class set
/// ([`lensmap::trace::classes::ClassSet::parse`]: a count, a list or `greedy:D`).
pub fn parse_terms(text: &str) -> Result<ShadingTerms, String> {
    match text.trim() {
        "scene" => Ok(ShadingTerms::Scene),
        "greedy" => Ok(ShadingTerms::Greedy),
        _ => lensmap::trace::classes::ClassSet::parse(text)
            .map(ShadingTerms::Classes)
            .map_err(|problem| {
                format!(
                    "{problem}; or give scene (the scene file's) or greedy (the papers' two terms)"
                )
            }),
    }
}

/// The reference tracer's model of frames shaded with `terms` in `scene`: greedy or the path
/// classes every lens object shares; an error naming the fix where the scene file gives its
/// lens objects different ones (the reference takes one model).
pub fn frame_model(
    terms: ShadingTerms,
    scene: &lensmap::scene::Scene,
) -> anyhow::Result<PathModel> {
    let mut models = scene.lenses.iter().map(|lens| terms.of(lens.terms));
    let first = models.next().flatten();
    if models.any(|m| m != first) {
        return Err(BadUsage(format!(
            "scene \"{}\" gives its lens objects different terms, and the reference takes one model: give --terms or --reference-tree",
            scene.name
        ))
        .into());
    }
    Ok(first.map_or(PathModel::Greedy, PathModel::Classes))
}

/// Parses `--fresnel`: `exact` or `table:N` (the table's size is checked with the other frame
/// options).
pub fn parse_fresnel(text: &str) -> Result<FresnelModel, String> {
    let text = text.trim();
    if text == "exact" {
        return Ok(FresnelModel::Exact);
    }
    text.strip_prefix("table:")
        .and_then(|texels| texels.trim().parse::<u32>().ok())
        .map(|texels| FresnelModel::Table { texels })
        .ok_or_else(|| {
            format!("'{text}': give exact or table:N, N texels of the 1D Schlick table (2 to 4096), e.g. table:64")
        })
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

/// The camera the arguments ask for, validated; bad values are scene (input) errors.
pub fn choose_camera(
    scene: &Scene,
    scene_arg: &str,
    args: &CameraArgs,
) -> Result<Camera, SceneError> {
    let file = PathBuf::from(scene_arg);
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
        fix: "give an image of at least 1×1 within the subpixel limits, --supersampling of at \
              least 1, and a camera position distinct from the look-at point within 1e6 m of the \
              origin"
            .to_owned(),
    })?;
    Ok(camera)
}

/// Whether progress may be drawn: stderr is a terminal and `--quiet` was not given.
pub fn progress_shown() -> bool {
    !voice().quiet && std::io::stderr().is_terminal()
}

/// A command's stages as it goes, on stderr: "step i of n: what" with a spinner and the elapsed
/// time, or a bar where the stage counts its work (rows, frames). Hidden when stderr is not a
/// terminal or under `--quiet`.
pub struct Steps {
    total: usize,
    started: usize,
}

impl Steps {
    /// A command of `total` stages.
    pub fn new(total: usize) -> Steps {
        Steps { total, started: 0 }
    }

    /// Starts the next stage with a spinner; `finish_and_clear` it when the stage ends.
    pub fn step(&mut self, what: &str) -> ProgressBar {
        let bar = self.bar(None);
        bar.set_message(self.next(what));
        bar.enable_steady_tick(Duration::from_millis(120));
        bar
    }

    /// Starts the next stage as a bar over `length` `unit`s.
    pub fn counted(&mut self, what: &str, length: u64, unit: &str) -> ProgressBar {
        let bar = self.bar(Some((length, unit)));
        bar.set_message(self.next(what));
        bar
    }

    fn next(&mut self, what: &str) -> String {
        self.started += 1;
        format!(
            "step {} of {}: {what}",
            self.started,
            self.total.max(self.started)
        )
    }

    fn bar(&self, counted: Option<(u64, &str)>) -> ProgressBar {
        let (bar, template) = match counted {
            Some((length, unit)) => (
                ProgressBar::new(length),
                format!(
                    "{{msg}} [{{elapsed_precise}}] {{wide_bar}} {{pos}}/{{len}} {unit} (eta {{eta}})"
                ),
            ),
            None => (
                ProgressBar::new_spinner(),
                "{spinner} {msg} [{elapsed_precise}]".to_owned(),
            ),
        };
        if !progress_shown() {
            bar.set_draw_target(ProgressDrawTarget::hidden());
            return bar;
        }
        if let Ok(style) = ProgressStyle::with_template(&template) {
            bar.set_style(style);
        }
        bar
    }
}

/// Where an image command writes: a PNG (sRGB) and an EXR (linear) of the same stem.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageOut {
    /// The PNG.
    pub png: PathBuf,
    /// The EXR beside it.
    pub exr: PathBuf,
}

impl ImageOut {
    /// Reads `--out PATH`: a `.png` or `.exr` path names both files (the other extension beside
    /// it); an existing folder, or a path without an extension (a folder, created), gets
    /// `DEFAULT_STEM.png` and `.exr` inside. Any other extension is a usage error: the command
    /// writes only those two formats, and says so before doing any work.
    pub fn parse(path: &Path, default_stem: &str) -> Result<ImageOut, BadUsage> {
        // A file where a folder must be (`--out notes.txt/frame.png`) is refused before any work.
        if let Some(blocking) = path
            .ancestors()
            .skip(1)
            .find(|ancestor| ancestor.exists())
            .filter(|ancestor| !ancestor.is_dir())
        {
            return Err(BadUsage(format!(
                "--out {}: {} is a file, not a folder; give a path in a folder",
                path.display(),
                blocking.display()
            )));
        }
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match extension.as_deref() {
            _ if path.is_dir() => Ok(Self::in_folder(path, default_stem)),
            None => Ok(Self::in_folder(path, default_stem)),
            // The path given is kept as written (`Shot.PNG` stays `Shot.PNG`).
            Some("png") => Ok(ImageOut {
                png: path.to_path_buf(),
                exr: path.with_extension("exr"),
            }),
            Some("exr") => Ok(ImageOut {
                png: path.with_extension("png"),
                exr: path.to_path_buf(),
            }),
            Some(other) => Err(BadUsage(format!(
                "--out {}: .{other} is not written; give a .png or .exr path (both are written) or a folder",
                path.display()
            ))),
        }
    }

    fn in_folder(folder: &Path, stem: &str) -> ImageOut {
        let stem = folder.join(stem);
        ImageOut {
            png: stem.with_extension("png"),
            exr: stem.with_extension("exr"),
        }
    }
}

/// Warns when the process runs under a file-size limit (`ulimit -f`), read from
/// `/proc/self/limits` (nothing is said where that file does not exist). lensmap's own writes
/// past the limit fail with an error and leave earlier outputs intact, but a driver that backs
/// device memory with files is capped too and cannot be warned: Mesa 25.0's lavapipe allocates
/// memory past the limit without an error and the process dies by SIGBUS at its first use
/// (docs/testing.md#full-disk).
pub fn warn_of_file_size_limit() {
    let Ok(limits) = std::fs::read_to_string("/proc/self/limits") else {
        return;
    };
    // "Max file size   <soft>   <hard>   bytes"
    let soft = limits
        .lines()
        .find_map(|line| line.strip_prefix("Max file size"))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|soft| soft.parse::<u64>().ok());
    if let Some(bytes) = soft {
        warn!(
            "a file-size limit of {} KiB is set (ulimit -f): a driver that backs GPU memory with \
             files (Mesa 24 and later's lavapipe) dies by SIGBUS past it; raise or remove the limit",
            bytes / 1024
        );
    }
}

/// The scene `name` (a built-in name or a TOML file), its loading's warnings said once each (an
/// OBJ's empty `usemtl`): every command loads its scenes here.
pub fn load_scene(name: &str) -> Result<lensmap::scene::Scene, lensmap::scene::SceneError> {
    let scene = lensmap::scene::Scene::load_named(name)?;
    for warning in &scene.warnings {
        warn!("{warning}");
    }
    Ok(scene)
}

/// How the glossy pass reconstructs a view's radiance map (`--glossy-reconstruction`).
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ReconstructionArg {
    /// Three samples, each warped into the view's reflection space, blended (the paper's).
    Warped,
    /// The nearest sample alone, unwarped.
    NearestUnwarped,
    /// Three samples blended, unwarped.
    BlendedUnwarped,
}

impl From<ReconstructionArg> for lensmap::rsibr::Reconstruction {
    fn from(arg: ReconstructionArg) -> Self {
        match arg {
            ReconstructionArg::Warped => lensmap::rsibr::Reconstruction::Warped,
            ReconstructionArg::NearestUnwarped => lensmap::rsibr::Reconstruction::NearestUnwarped,
            ReconstructionArg::BlendedUnwarped => lensmap::rsibr::Reconstruction::BlendedUnwarped,
        }
    }
}

/// Images of one size side by side, left to right.
pub fn beside(images: &[RenderedImage]) -> anyhow::Result<RenderedImage> {
    let Some(first) = images.first() else {
        anyhow::bail!("no images to put side by side");
    };
    let (w, h) = (first.width as usize, first.height as usize);
    if images.iter().any(|i| i.pixels.len() != w * h) {
        anyhow::bail!("side by side: the images differ in size");
    }
    let mut pixels = Vec::with_capacity(images.len() * w * h);
    for y in 0..h {
        for image in images {
            pixels.extend_from_slice(&image.pixels[y * w..(y + 1) * w]);
        }
    }
    Ok(RenderedImage {
        width: first.width * images.len() as u32,
        height: first.height,
        pixels,
    })
}

/// The absolute difference of two images of one size, times `gain`, α 1: what a side-by-side
/// shows beside a frame and its reference.
pub fn difference(a: &RenderedImage, b: &RenderedImage, gain: f32) -> RenderedImage {
    RenderedImage {
        width: a.width,
        height: a.height,
        pixels: a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| {
                let d = |c: usize| (p[c] - q[c]).abs() * gain;
                [d(0), d(1), d(2), 1.0]
            })
            .collect(),
    }
}

/// `image`'s mean radiance over `mask` (linear, the channels' sum) over `reference`'s; `None`
/// over no pixel or a black reference.
pub fn mean_ratio(
    image: &lensmap::render::RenderedImage,
    reference: &lensmap::trace::ReferenceImage,
    mask: &lensmap::metrics::Mask,
) -> Option<f64> {
    let (mut ours, mut theirs) = (0.0f64, 0.0f64);
    for i in (0..reference.radiance.len()).filter(|&i| mask.contains(i)) {
        let p = image.pixels[i];
        ours += f64::from(p[0] + p[1] + p[2]);
        theirs += f64::from(reference.radiance[i].element_sum());
    }
    (theirs > 0.0).then(|| ours / theirs)
}
