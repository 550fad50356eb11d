//! `lensmap bake`: inferred layered EMs over a scene's view space, written as a bake directory
//! (`lensmap_baker::bake`), resumable and shardable; and `lensmap bake --merge`, which joins
//! shards.

use std::path::PathBuf;

use clap::Args;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::HybridOptions,
};
use lensmap_baker::{
    bake::{
        BakeJob, BakeOptions, LayerCount, Progress, bake, merge, parse_samples, parse_shard,
        shard_samples,
    },
    infer::{DEFAULT_MAX_EM_SIZE, EmSize, InferOptions},
};
use serde_json::json;

use crate::common::{BadUsage, OnOff, progress_shown, report};

/// The modes that do not bake layered EMs, and so take none of the layered bake's options.
const LAYERED_ONLY: [&str; 3] = ["compress", "merge", "radiance_maps"];

#[derive(Args)]
#[command(after_help = "Examples:
  lensmap bake --scene teapot-room --samples 0,1 --out out/bake
  lensmap bake --scene teapot-room --shard 2/8 --out out/shard-2     (one job of an array)
  lensmap bake --merge out/shard-1 out/shard-2 --out out/bake
  lensmap bake --radiance-maps --scene glossy-studio --out out/radiance  (glossy objects)
  lensmap bake --compress out/bake                                   (in place, lossless)
  lensmap bake --compress out/bake --drop-mantissa-bits 12 --out out/bake-small")]
pub struct BakeArgs {
    /// Built-in scene name or path (not with --merge or --compress).
    #[arg(long, required_unless_present_any = ["merge", "compress"])]
    pub(crate) scene: Option<String>,
    /// The bake directory to write (replaced atomically when the bake is complete); with
    /// --compress, where to write the compressed bake (default: the bake itself).
    #[arg(long, required_unless_present = "compress")]
    pub(crate) out: Option<PathBuf>,
    /// Viewpoint samples: all, I,J,K, A..B (B excluded) or A..=B.
    #[arg(long, default_value = "all")]
    pub(crate) samples: String,
    /// Layers per lens object, placed by clustering with fitted shells: auto (as many as the
    /// scene names, else as many as help) or a count; or scene (the scene's named shells as
    /// they are); or bounce (reflectors: a local ellipsoid over a distant box, the PEM paper's).
    #[arg(long, default_value = "auto", conflicts_with_all = LAYERED_ONLY)]
    layers: String,
    /// EM face size: auto (the finest level read at sample 0, up to 128) or a power of two.
    #[arg(long, default_value = "auto", conflicts_with_all = LAYERED_ONLY)]
    em_size: String,
    /// Views per sample, spread over its share of the view space (1: the sample alone).
    /// Range: [1, 9].
    #[arg(long, default_value_t = lensmap_baker::bake::DEFAULT_MULTI_VIEW, conflicts_with_all = LAYERED_ONLY)]
    multi_view: usize,
    /// One more view per sample, raised this many degrees above it, for cameras that leave the
    /// view space's circle (0: none).
    /// Range: [0, 90).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, conflicts_with_all = LAYERED_ONLY)]
    view_elevation_degrees: f64,
    /// Target views' width in pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 640, conflicts_with_all = LAYERED_ONLY)]
    width: u32,
    /// Target views' height in pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 480, conflicts_with_all = LAYERED_ONLY)]
    height: u32,
    /// Target views' k×k supersampling.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 3, conflicts_with_all = LAYERED_ONLY)]
    supersampling: u32,
    /// Tessellation threshold t of the frames the EMs are fitted through, subpixels.
    /// Range: (0, ∞).
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true, conflicts_with_all = LAYERED_ONLY)]
    t: f32,
    /// The terms whose equations the EMs are solved over: `greedy` (the papers' two terms, Eq. 1),
    /// a count N of path classes (the first N of R, TT, TRT, … for glass; of R, RR, … for
    /// mirrors), a list such as `R,TT,TRT,TRRT`, or `greedy:D`. One EM per layer over every
    /// class's equations, the targets traced per class; a scene file's `terms` do not apply
    /// to bakes. In the bake's identity.
    #[arg(long, default_value = "greedy", value_name = "greedy|N|CLASSES", value_parser = parse_bake_terms, conflicts_with_all = LAYERED_ONLY)]
    terms: lensmap::hybrid::ShadingTerms,
    /// Confidence threshold θc, degrees.
    /// Range: (0, 180).
    #[arg(long, default_value_t = lensmap_baker::targets::DEFAULT_CONFIDENCE_DEGREES, allow_negative_numbers = true, conflicts_with_all = LAYERED_ONLY)]
    confidence_degrees: f64,
    /// The solver stops at this relative residual of the normal equations.
    /// Range: (0, 1).
    #[arg(long, default_value_t = lensmap_baker::solve::SolveOptions::default().tolerance, allow_negative_numbers = true, conflicts_with_all = LAYERED_ONLY)]
    tolerance: f64,
    /// Share the farthest layer between lens objects that see the same scene objects there:
    /// one map on one shell, solved on every sharing lens object's equations (fewer maps to
    /// store; measured less accurate on teapot-room, so off by default).
    #[arg(long, value_enum, default_value = "off", conflicts_with_all = LAYERED_ONLY)]
    share_layers: OnOff,
    /// Direct images from the EM origin for the texels no lens view constrains.
    #[arg(long, value_enum, default_value = "off", conflicts_with_all = LAYERED_ONLY)]
    direct_images: OnOff,
    #[arg(long, value_enum, default_value = "on", help = crate::common::HULL_SPLIT_HELP, conflicts_with_all = LAYERED_ONLY)]
    hull_split: OnOff,
    /// Bake only shard I of N: every N-th requested sample, starting at the I-th.
    #[arg(long, value_name = "I/N")]
    pub(crate) shard: Option<String>,
    /// Keep samples already complete (staged, or in the bake at --out made with the same scene
    /// and options) and bake only the rest; the bake then holds every complete sample, asked
    /// for or not.
    #[arg(long)]
    pub(crate) resume: bool,
    /// Skip measuring each sample's lens PSNR against a reference (saves a reference trace per
    /// sample; the maps are the same).
    #[arg(long, conflicts_with_all = LAYERED_ONLY)]
    no_judge: bool,
    /// Bake the glossy objects' radiance environment maps (reflection-space IBR) instead of
    /// layered EMs: one map per lobe per view sample of --views; --samples, --shard, --resume
    /// and --merge work on those view samples.
    #[arg(long, conflicts_with = "compress")]
    pub(crate) radiance_maps: bool,
    /// With --radiance-maps: view samples, an icosahedron (12) or its subdivisions (42, 162).
    /// Range: one of 12, 42, 162.
    #[arg(long, default_value_t = lensmap::rsibr::views::DEFAULT_VIEW_COUNT)]
    pub(crate) views: usize,
    /// With --radiance-maps: face size of the maps, texels (rounded up to a power of two).
    /// Range: [1, 1024].
    #[arg(long, default_value_t = lensmap::rsibr::maps::DEFAULT_MAP_SIZE)]
    pub(crate) map_size: u32,
    /// With --radiance-maps: directions sampled per texel.
    /// Range: [2, 65536].
    #[arg(long, default_value_t = lensmap::rsibr::maps::DEFAULT_MAP_SAMPLES)]
    pub(crate) map_samples: u32,
    /// With --radiance-maps: seed of the samples.
    /// Range: any.
    #[arg(long, default_value_t = 0)]
    pub(crate) map_seed: u64,
    /// Join these shard directories into --out instead of baking.
    #[arg(long, num_args = 1.., value_name = "DIR", conflicts_with_all = ["scene", "shard", "resume"])]
    pub(crate) merge: Vec<PathBuf>,
    /// Compress this complete (or merged) bake instead of baking: MIP levels as residuals from
    /// the finest level, each sample coded against the one before, zstd; lossless unless
    /// --drop-mantissa-bits. Everything that reads bakes reads it unchanged.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["scene", "shard", "resume", "merge"])]
    compress: Option<PathBuf>,
    /// With --compress: a keyframe every this many samples of a layer (1: no coding across
    /// samples); one sample decodes from at most this many files.
    /// Range: [1, 1024].
    #[arg(long, default_value_t = lensmap::layers::bake::compress::DEFAULT_KEYFRAME_INTERVAL,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(lensmap::layers::bake::compress::MAX_KEYFRAME_INTERVAL)))]
    keyframe_interval: u32,
    /// With --compress: round away this many of the 23 low mantissa bits of every value
    /// first (lossy; relative error at most 2^(bits − 24)); 0 is lossless.
    /// Range: [0, 20].
    #[arg(long, default_value_t = 0,
          value_parser = clap::value_parser!(u32).range(0..=i64::from(lensmap::layers::bake::compress::codec::MAX_DROPPED_MANTISSA_BITS)))]
    drop_mantissa_bits: u32,
}

/// Runs `lensmap bake`.
pub fn run(args: BakeArgs) -> anyhow::Result<()> {
    if let Some(source) = &args.compress {
        return run_compress(&args, source);
    }
    let Some(out) = &args.out else {
        return Err(BadUsage(
            "--out: name the bake directory to write, e.g. --out out/bake".into(),
        )
        .into());
    };
    if args.radiance_maps {
        return crate::bake_radiance::run(&args, out);
    }
    if !args.merge.is_empty() {
        return run_merge(&args, out);
    }
    let Some(scene_name) = &args.scene else {
        return Err(
            BadUsage("--scene: name the scene to bake, e.g. --scene teapot-room".into()).into(),
        );
    };
    let options = options(&args)?;
    let scene = crate::common::load_scene(scene_name)?;
    let mut samples = parse_samples(&args.samples, scene.view_space.len(), &scene.name)?;
    if let Some(spec) = &args.shard {
        samples = shard_samples(&samples, parse_shard(spec)?);
    }
    options.validate()?;
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = lensmap::runner::FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    // The baker's test renderings and judged frames are RGBA32F at the targets' size.
    runner.check_framebuffer(
        &scene
            .camera
            .with_resolution(args.width, args.height, args.supersampling),
        lensmap::render::TargetFormat::Rgba32f,
    )?;
    let device = runner.gpu().device_id().clone();
    if let Some(staging) = lensmap::layers::Staging::path_of(out) {
        crate::interrupt::stop_on_signals(crate::interrupt::Interruptible {
            out: out.clone(),
            staging,
        })?;
    }
    let bars = BakeBars::new(samples.len());
    let job = BakeJob {
        dir: out,
        samples: &samples,
        options: &options,
        resume: args.resume,
    };
    let summary = bake(&mut runner, &scene, &job, &mut |progress| {
        bars.show(progress)
    })?;
    bars.finish();
    let validation = runner.gpu().validation_report();
    if let Some(first) = validation.messages.first() {
        anyhow::bail!(
            "the Vulkan validation layer reported {} message(s) during the bake; the first: {first}",
            validation.messages.len()
        );
    }
    report(
        &json!({
            "scene": scene.name,
            "out": out,
            "device": device.device,
            "driver": device.driver_description(),
            "summary": summary,
        }),
        None,
    )?;
    say!(
        "{}: {} sample(s) in {} ({} baked now, {} resumed), EM {}², plan {:.1} s, device {device}",
        scene.name,
        summary.samples.len(),
        out.display(),
        summary.baked.len(),
        summary.resumed.len(),
        summary.plan.em_size,
        summary.plan_seconds,
    );
    for lens in &summary.plan.lenses {
        let shells: Vec<String> = lens
            .shells
            .iter()
            .map(|s| format!("{} ~{:.2} m", s.kind(), shell_size(s)))
            .collect();
        say!(
            "  lens \"{}\": {} layers from {} [{}]{}",
            lens.name,
            lens.shells.len(),
            lens.source,
            shells.join(", "),
            if lens.objects.is_empty() {
                String::new()
            } else {
                format!(" objects {:?}", lens.objects)
            }
        );
    }
    for report in summary
        .reports
        .iter()
        .filter(|r| summary.baked.contains(&r.sample))
    {
        let s = &report.seconds;
        say!(
            "  sample {}: {:.1} s (tracing {:.1}, frames {:.1}, matrices {:.1}, targets {:.1}, solve {:.1}, judge {:.1}, write {:.1}){}",
            report.sample,
            s.total,
            s.tracing,
            s.frames,
            s.matrices,
            s.targets,
            s.solve,
            s.judge,
            s.write,
            match (report.psnr_db, report.projected_psnr_db) {
                (Some(inferred), Some(projected)) => format!(
                    "; lens PSNR at the sample {inferred:.2} dB (projected {projected:.2} dB)"
                ),
                _ => String::new(),
            }
        );
    }
    Ok(())
}

/// `lensmap bake --merge DIR… --out OUT`: joins shards into `out` and reports the samples.
fn run_merge(args: &BakeArgs, out: &std::path::Path) -> anyhow::Result<()> {
    if crate::common::validate_only() {
        return Ok(());
    }
    let manifest = merge(&args.merge, out)?;
    let samples = manifest
        .provenance
        .as_ref()
        .map(|p| p.samples.clone())
        .unwrap_or_default();
    let baked_on = manifest
        .provenance
        .as_ref()
        .map(|p| p.baked_on.clone())
        .unwrap_or_default();
    if baked_on.len() > 1 {
        let each: Vec<String> = baked_on
            .iter()
            .map(|g| format!("{} (samples {:?})", g.device, g.samples))
            .collect();
        warn!(
            "the shards were baked on {} devices or drivers: {}; the merged bake holds maps \
             from each (how far two drivers' maps of one sample differ: \
             docs/results.md#bake-drivers)",
            baked_on.len(),
            each.join("; ")
        );
    }
    report(
        &json!({
            "out": out,
            "merged": args.merge,
            "samples": samples,
            "baked_on": baked_on,
        }),
        None,
    )?;
    say_merged(args, out, &samples);
    Ok(())
}

/// The line a merge ends with: how many shards went into `out`, and its samples.
pub(crate) fn say_merged(args: &BakeArgs, out: &std::path::Path, samples: &[usize]) {
    say!(
        "merged {} shards into {}: samples {samples:?}",
        args.merge.len(),
        out.display()
    );
}

/// `lensmap bake --compress DIR`: compresses the bake at `source` into `--out` (default: in
/// place), atomically, and reports the sizes.
fn run_compress(args: &BakeArgs, source: &std::path::Path) -> anyhow::Result<()> {
    let out = args.out.as_deref().unwrap_or(source);
    let options = lensmap::layers::bake::CompressOptions {
        keyframe_interval: args.keyframe_interval,
        dropped_mantissa_bits: args.drop_mantissa_bits,
    };
    if crate::common::validate_only() {
        return Ok(());
    }
    let summary = lensmap::layers::bake::compress(source, out, &options)?;
    let mut decode = summary.decode_seconds.clone();
    decode.sort_by(f64::total_cmp);
    let median_ms = decode.get(decode.len() / 2).map_or(0.0, |s| s * 1e3);
    let ratio = summary.bytes_before as f64 / summary.bytes_after.max(1) as f64;
    report(
        &json!({
            "source": source,
            "out": out,
            "keyframe_interval": options.keyframe_interval,
            "dropped_mantissa_bits": options.dropped_mantissa_bits,
            "summary": summary,
            "ratio": ratio,
            "median_decode_ms": median_ms,
        }),
        None,
    )?;
    say!(
        "compressed {} maps ({} keyframes) of {} into {}: {} → {} bytes ({ratio:.2}×), {}; decoding {median_ms:.1} ms per map (median)",
        summary.files,
        summary.keyframes,
        source.display(),
        out.display(),
        summary.bytes_before,
        summary.bytes_after,
        match summary.map_psnr_db {
            None => "lossless (bit-exact)".to_owned(),
            Some(psnr) => format!(
                "lossy: map PSNR {psnr:.1} dB, largest error {:.2e}",
                summary.max_abs_error
            ),
        }
    );
    Ok(())
}

/// A bake's progress on stderr, hidden when stderr is not a terminal: one bar over the samples,
/// one over the stage of the sample in flight (views traced, layers measured or solved).
pub struct BakeBars {
    _multi: MultiProgress,
    samples: ProgressBar,
    stage: ProgressBar,
}

impl BakeBars {
    /// Bars for a bake of `samples` samples.
    pub fn new(samples: usize) -> BakeBars {
        let multi = if progress_shown() {
            MultiProgress::new()
        } else {
            MultiProgress::with_draw_target(ProgressDrawTarget::hidden())
        };
        let style = |template: &str| {
            ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar())
        };
        let samples_bar = multi.add(ProgressBar::new(samples as u64));
        samples_bar.set_style(style(
            "{msg:<24} [{elapsed_precise}] {wide_bar} {pos}/{len} samples (eta {eta})",
        ));
        let stage = multi.add(ProgressBar::new(1));
        stage.set_style(style("{msg:<24} {wide_bar} {pos}/{len}"));
        BakeBars {
            _multi: multi,
            samples: samples_bar,
            stage,
        }
    }

    /// Shows `progress`.
    pub fn show(&self, progress: Progress<'_>) {
        match progress {
            Progress::Plan(stage) => {
                self.samples.set_message("plan");
                self.stage.set_message(stage.to_owned());
            }
            Progress::Sample {
                sample, done, step, ..
            } => {
                self.samples.set_position(done as u64);
                self.samples.set_message(format!("sample {sample}"));
                self.stage.set_length(step.of as u64);
                self.stage.set_position(step.position as u64);
                self.stage.set_message(step.stage.to_owned());
            }
        }
    }

    /// Removes the bars.
    pub fn finish(&self) {
        self.stage.finish_and_clear();
        self.samples.finish_and_clear();
    }
}

/// A shell's characteristic size for the report: radius, or the largest half extent.
fn shell_size(shell: &lensmap::layers::LayerShell) -> f64 {
    use lensmap::layers::LayerShell;
    match *shell {
        LayerShell::Sphere { radius, .. } | LayerShell::Cylinder { radius, .. } => radius,
        LayerShell::Box { half_extents, .. } => half_extents.max_element(),
        LayerShell::Ellipsoid { radii, .. } => radii.max_element(),
        LayerShell::Quad { half_extents, .. } => half_extents.max_element(),
    }
}

/// The bake options the flags give.
fn options(args: &BakeArgs) -> Result<BakeOptions, BadUsage> {
    let em_size = match args.em_size.as_str() {
        "auto" => EmSize::Auto {
            cap: DEFAULT_MAX_EM_SIZE,
        },
        text => EmSize::Fixed(text.parse().map_err(|_| {
            BadUsage(format!(
                "--em-size {text}: give auto or a power of two such as 128"
            ))
        })?),
    };
    let layers = match args.layers.as_str() {
        "auto" => LayerCount::Auto,
        "scene" => LayerCount::Scene,
        "bounce" => LayerCount::Bounce,
        text => LayerCount::Count(text.parse().map_err(|_| {
            BadUsage(format!(
                "--layers {text}: give auto, scene, bounce or a count such as 3"
            ))
        })?),
    };
    Ok(BakeOptions {
        width: args.width,
        height: args.height,
        supersampling: args.supersampling,
        em_size,
        layers,
        multi_view: args.multi_view,
        view_elevation_degrees: args.view_elevation_degrees,
        share_layers: args.share_layers.is_on(),
        infer: InferOptions {
            hybrid: HybridOptions {
                hull_split: args.hull_split.is_on(),
                terms: args.terms,
                ..HybridOptions::with_t(args.t)
            },
            theta_c: args.confidence_degrees.to_radians(),
            direct_images: args.direct_images.is_on(),
            solve: lensmap_baker::solve::SolveOptions {
                tolerance: args.tolerance,
                ..lensmap_baker::solve::SolveOptions::default()
            },
            ..InferOptions::default()
        },
        judge: !args.no_judge,
    })
}

/// Parses `bake --terms`: the frames' terms, but not `scene` (a bake's equations are of one set
/// of terms, named on the command line).
fn parse_bake_terms(text: &str) -> Result<lensmap::hybrid::ShadingTerms, String> {
    match crate::common::parse_terms(text)? {
        lensmap::hybrid::ShadingTerms::Scene => Err(
            "a bake's terms are named on the command line; give greedy, a count such as 4, or a list such as R,TT,TRT".into(),
        ),
        terms => Ok(terms),
    }
}
