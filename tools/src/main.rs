//! `lensmap`: the command line. Each command lives in its own module; this file parses arguments
//! and maps errors to exit codes (0 success, 1 failure of the work, 2 bad usage or bad input, with
//! one line naming what and where).

#[macro_use]
mod common;
mod bake;
mod bake_radiance;
mod bench_bake;
mod bench_classes;
mod bench_error;
mod bench_fresnel;
mod bench_glossy;
mod bench_hybrid;
mod bench_infer;
mod bench_passes;
mod bench_trace;
mod demo;
mod frame_args;
mod interrupt;
mod modes;
mod pareto;
mod passes;
mod ranges;
mod reference;
mod render;
mod view;
mod words;

use std::process::ExitCode;

use lensmap::error::ErrorKind;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// Hybrid rendering of shiny and glass objects with layered environment maps.
#[derive(Parser)]
#[command(
    name = "lensmap",
    version,
    about = "Hybrid rendering of shiny and glass objects with layered environment maps",
    propagate_version = true,
    after_help = "Examples:
  lensmap demo                                   the main job on the built-in teapot-room
  lensmap render --scene glass-sphere --projected --compare --out out/frame.png
  lensmap passes --layers 3 --json | jq .counts"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print the result as one JSON document on stdout (nothing else there) and an error as
    /// one JSON line on stderr; the same on every command.
    #[arg(long, global = true)]
    json: bool,
    /// No progress and no human-readable report (errors, warnings and --json still print).
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Check the command line, the scene and the files it names as the command would, then exit
    /// 0 before any work: no device, no large allocation, nothing written.
    #[arg(long, global = true)]
    validate_only: bool,
}

/// What every `--help` ends with: the exit codes and the environment variables.
const HELP_FOOTER: &str = "Exit codes:
  0    success
  1    the work failed (a disk error, a GPU failure, a result the work could not reach), or
       lensmap broke an invariant of its own (a second line asks for a bug report)
  2    bad usage or bad input (an option, a scene, an asset or a bake), said in one line
  130  bake: interrupted by SIGINT (Ctrl-C); finished samples kept, --resume finishes
  141  stdout was closed before the end (e.g. piped into head); the work and files finished
  143  bake: interrupted by SIGTERM (a scheduler's preemption); finished samples kept, --resume finishes

Environment:
  LENSMAP_VALIDATION=1   enable the Khronos validation layer (fails on any message)
  LENSMAP_DEVICE=NAME    use the Vulkan device whose name contains NAME (default: the best)
  RAYON_NUM_THREADS=N    CPU threads for ray tracing, tessellation and the baker";

/// The command tree with [`HELP_FOOTER`] after every command's own help (its example first).
fn command_with_footer(command: clap::Command) -> clap::Command {
    let after = match command.get_after_help() {
        Some(own) => format!("{own}\n\n{HELP_FOOTER}"),
        None => HELP_FOOTER.to_owned(),
    };
    command
        .after_help(after)
        .mut_subcommands(command_with_footer)
}

#[derive(Subcommand)]
enum Command {
    /// The main job: hybrid frames of teapot-room (both variants, t = 3 and 5) beside the
    /// reference ray tracer, with the paper's table and PSNR, into out/.
    ///
    /// Example: lensmap demo --out out   (or --synthetic for the compositor alone)
    Demo(demo::DemoArgs),
    /// Print the compositor's pass plan for a pass-count or blending-mode experiment.
    ///
    /// Example: lensmap passes --layers 3 --viewpoints 2 --terms greedy --variant multipass --format rgba8
    Passes(passes::PassesArgs),
    /// Render reference images with the CPU ray tracer.
    ///
    /// Example: lensmap reference --scene glass-sphere --view 0 --tree greedy --out out/reference
    Reference(reference::ReferenceArgs),
    /// Render a hybrid frame (vertex ray paths, adaptive tessellation, layered EMs on the GPU).
    ///
    /// Example: lensmap render --scene teapot-room --projected --view 2 --compare --out out/hybrid.png
    Render(render::RenderArgs),
    /// Bake inferred layered EMs over a scene's view space into a bake directory (resumable,
    /// shardable; --merge joins shards).
    ///
    /// Example: lensmap bake --scene teapot-room --samples 0,1 --out out/bake
    Bake(bake::BakeArgs),
    /// The hybrid frame along a camera path; --record DIR renders it headless into frames and a
    /// stats CSV.
    ///
    /// Example: lensmap view --scene glass-sphere --projected --record out/orbit --frames 60
    View(view::ViewArgs),
    /// Benchmarks (medians of repeated runs, ratios measured in the same run).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Every option of every command as JSON lines (command, option, value type, help), for
    /// the tests that walk them.
    #[command(hide = true)]
    OptionTree,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Compositor frame time for n = 1…4 layers, multipass vs single pass, every format, and the
    /// error of RGBA8/RGBA16F against RGBA32F.
    ///
    /// Example: lensmap bench passes --width 640 --height 480
    Passes(bench_passes::BenchPassesArgs),
    /// Hybrid frame time per stage (medians), single pass vs multipass.
    ///
    /// Example: lensmap bench hybrid --width 640 --height 480
    Hybrid(bench_hybrid::BenchHybridArgs),
    /// Ray tracer throughput on teapot-room, greedy vs full tree, 1 and 2 threads.
    ///
    /// Example: lensmap bench trace --width 640 --height 480 --supersampling 3
    Trace(bench_trace::BenchTraceArgs),
    /// The baker's core at one viewpoint sample: inferred vs projected EMs (lens PSNR against a
    /// better-converged reference) and the inference's cost per stage (median of runs).
    ///
    /// Example: lensmap bench infer --scene glass-sphere --width 320 --height 240
    Infer(bench_infer::BenchInferArgs),
    /// Baked EMs away from where they were fitted: on a sample, halfway to the next, 15° above
    /// (lens and non-lens PSNR against a better-converged reference, projected EMs beside).
    ///
    /// Example: lensmap bench bake --scene teapot-room --bake out/bake --sample 0
    Bake(bench_bake::BenchBakeArgs),
    /// Run time against error: a sweep of t, the angle threshold, layers, EM size, variant,
    /// format, supersampling (and inferred EMs) with three baselines, and a Pareto plot.
    ///
    /// Example: lensmap bench error --scene teapot-room --plot out/pareto
    Error(bench_error::BenchErrorArgs),
    /// Schlick's (1 − cos θ)⁵ through a 1D table (--fresnel table:N): its largest error over
    /// 0–90° per size, against Schlick evaluated exactly and, for glass, exact Fresnel.
    ///
    /// Example: lensmap bench fresnel --scene mirror-teapot --scene glass-sphere --texels 16,64,256
    Fresnel(bench_fresnel::BenchFresnelArgs),
    /// Glossy objects by reflection-space IBR against the reference: warped, nearest and
    /// blended maps on a sample, in a triangle and on an edge; 12, 42 and 162 view samples.
    Glossy(bench_glossy::BenchGlossyArgs),
    /// Ray-path models against the full ray tree with no EM between: the greedy terms and the
    /// first N path classes (R, TT, TRT, …), their lens PSNR, light kept per ring and rays.
    ///
    /// Example: lensmap bench classes --scenes glass-sphere --tree greedy --tree 4
    Classes(bench_classes::BenchClassesArgs),
}

/// The kind of failure `error` is: that of the first error in its chain the library or the
/// baker classifies ([`lensmap::error::ErrorKind`]); the command line's own usage errors are
/// input, and anything else is the work's failure.
fn error_kind(error: &anyhow::Error) -> ErrorKind {
    use lensmap::error::Classified;
    for cause in error.chain() {
        if cause.is::<common::BadUsage>() {
            return ErrorKind::Input;
        }
        if let Some(failure) = cause.downcast_ref::<lensmap_baker::bake::BakeFailure>() {
            return failure.kind();
        }
        if let Some(kind) = lensmap::error::kind_of(cause) {
            return kind;
        }
    }
    ErrorKind::Failed
}

/// The exit status of a failure of kind `kind`: 2 for the user's input, 1 for the work's
/// failure and for lensmap's own.
fn exit_code(kind: ErrorKind) -> u8 {
    if kind.is_input() { 2 } else { 1 }
}

fn main() -> ExitCode {
    // Before parsing: a usage error is said as JSON too when --json was asked for.
    let json_asked = std::env::args_os().any(|a| a == "--json");
    // Usage errors in one line (clap's own message, without the usage block), exit code 2;
    // --help and --version print as clap prints them.
    // An option given in a mode that ignores it is a usage error too (modes::check), as is a
    // number outside the range its help states (ranges::check).
    let command = command_with_footer(Cli::command());
    let parsed = command.clone().try_get_matches().and_then(|matches| {
        modes::check(&command, &matches)?;
        ranges::check(&command, &matches)?;
        Cli::from_arg_matches(&matches)
    });
    let cli = match parsed {
        Ok(cli) => cli,
        // --help, --version, and a bare `lensmap` or `lensmap bench` (help on stderr, exit 2).
        Err(error)
            if !error.use_stderr()
                || error.kind()
                    == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            error.exit()
        }
        Err(error) => {
            // clap's message without its usage block, its lines (the missing arguments, the
            // possible values, a suggestion) joined into one.
            let rendered = error.to_string();
            let parts: Vec<&str> = rendered
                .lines()
                .take_while(|line| !line.starts_with("Usage:"))
                .map(str::trim)
                .filter(|line| !line.is_empty() && !line.starts_with("For more information"))
                .collect();
            return fail(
                &format!("{} (see --help)", parts.join(" ")),
                2,
                None,
                json_asked,
            );
        }
    };
    common::set_voice(common::Voice {
        json: cli.json,
        quiet: cli.quiet,
        validate_only: cli.validate_only,
    });
    common::warn_of_file_size_limit();
    let result = match cli.command {
        Command::Demo(args) => demo::run(args),
        Command::Passes(args) => passes::run(args),
        Command::Reference(args) => reference::run(args),
        Command::Render(args) => render::run(args),
        Command::Bake(args) => bake::run(args),
        Command::View(args) => view::run(args),
        Command::Bench(BenchCommand::Passes(args)) => bench_passes::run(args),
        Command::Bench(BenchCommand::Trace(args)) => bench_trace::run(args),
        Command::Bench(BenchCommand::Hybrid(args)) => bench_hybrid::run(args),
        Command::Bench(BenchCommand::Infer(args)) => bench_infer::run(args),
        Command::Bench(BenchCommand::Bake(args)) => bench_bake::run(args),
        Command::Bench(BenchCommand::Error(args)) => bench_error::run(args),
        Command::Bench(BenchCommand::Fresnel(args)) => bench_fresnel::run(args),
        Command::Bench(BenchCommand::Glossy(args)) => bench_glossy::run(args),
        Command::Bench(BenchCommand::Classes(args)) => bench_classes::run(args),
        Command::OptionTree => {
            modes::print_tree(&Cli::command());
            Ok(())
        }
    };
    match result {
        Ok(()) => common::exit_status(),
        Err(error) => {
            // One line: the outermost context and its causes, each said once.
            let line = words::error_line(&error);
            let kind = error_kind(&error);
            let code = exit_code(kind);
            let bug = (kind == ErrorKind::Internal).then_some(BUG_REPORT);
            fail(&format!("error: {line}"), code, bug, cli.json)
        }
    }
}

/// The line after the error of a broken invariant.
const BUG_REPORT: &str = "this is a bug in lensmap: please report it with the command line and the lines above (lensmap --version)";

/// Says a failure on stderr, one line (one JSON object under `--json`), and `bug`'s request for
/// a bug report on a line of its own (a field of the object), and gives its exit code.
fn fail(line: &str, code: u8, bug: Option<&str>, json: bool) -> ExitCode {
    if json {
        let message = line.strip_prefix("error: ").unwrap_or(line);
        let mut said = serde_json::json!({ "error": message, "exit_code": code });
        if let Some(bug) = bug {
            said["bug_report"] = bug.into();
        }
        common::tell(format_args!("{said}"));
    } else {
        common::tell(format_args!("{line}"));
        if let Some(bug) = bug {
            common::tell(format_args!("{bug}"));
        }
    }
    ExitCode::from(code)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::gpu::GpuError;
    use lensmap::render::RenderError;
    use lensmap::runner::RunError;

    /// The exit status follows the library's kind through the runner's and the baker's
    /// wrappers and anyhow's context; a broken invariant is exit 1, as is a failure of the work.
    #[test]
    fn exit_codes_come_from_the_librarys_kinds() {
        let internal = anyhow::Error::from(RunError::from(RenderError::Internal("x".into())))
            .context("rendering");
        assert_eq!(error_kind(&internal), ErrorKind::Internal);
        assert_eq!(exit_code(ErrorKind::Internal), 1);
        let input = anyhow::Error::from(RunError::from(RenderError::BadInput("x".into())));
        assert_eq!(exit_code(error_kind(&input)), 2);
        let no_driver = anyhow::Error::from(RenderError::from(GpuError::NoDriver("x".into())));
        assert_eq!(
            (error_kind(&no_driver), exit_code(ErrorKind::NoDriver)),
            (ErrorKind::NoDriver, 2)
        );
        let lost = anyhow::Error::from(GpuError::Vulkan {
            call: "vkQueueSubmit2",
            result: lensmap::gpu::vk::Result::ERROR_DEVICE_LOST,
        });
        assert_eq!(exit_code(error_kind(&lost)), 1);
        let usage = anyhow::Error::from(common::BadUsage("--width 0".into()));
        assert_eq!(exit_code(error_kind(&usage)), 2);
        assert_eq!(exit_code(error_kind(&anyhow::anyhow!("anything else"))), 1);
        let bake = anyhow::Error::from(lensmap_baker::bake::BakeFailure::Run(RunError::from(
            RenderError::Internal("x".into()),
        )));
        assert_eq!(error_kind(&bake), ErrorKind::Internal);
    }
}
