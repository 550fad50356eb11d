//! `lensmap view`: the hybrid frame in a window (winit, ash-window, a swapchain) with live
//! experiments on keys, the camera's place in the view space, the paper's per-frame table and
//! the reference ray tracer on demand; or, with `--record DIR`, a camera path rendered headless.

mod camera;
mod keys;
mod overlay;
mod present;
mod record;
mod reference;
mod script;
mod window;

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use lensmap::{
    hybrid::HybridScene,
    layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions},
    lightmap::LightMapOptions,
    runner::{EmSource, LoadOptions, load_hybrid_scene},
    scene::{Camera, Scene},
};

use crate::common::{CameraArgs, choose_camera, flag_error};
use crate::frame_args::FrameArgs;

#[derive(Args)]
#[command(after_help = after_help())]
pub struct ViewArgs {
    /// Built-in scene name (teapot-room, glass-sphere, mirror-teapot) or path to a scene .toml.
    #[arg(long)]
    pub scene: String,
    /// Read the inferred layered EMs from this bake directory. Without --bake or --projected,
    /// the demo's cache (out/bake) is used when it holds a bake of this scene, else projected
    /// EMs.
    #[arg(long, value_name = "DIR", conflicts_with = "projected")]
    pub bake: Option<PathBuf>,
    /// Use projected layered EMs (layer shells from the scene file), even where a bake exists.
    #[arg(long)]
    pub projected: bool,
    /// Draw the glossy objects by reflection-space IBR from this radiance-map bake
    /// (`lensmap bake --radiance-maps`), instead of light-mapped.
    #[arg(long, value_name = "DIR")]
    pub radiance: Option<PathBuf>,
    /// Render the camera path headless into DIR (no window, no display needed):
    /// frame-NNNN.png and .exr per frame and stats.csv.
    #[arg(long, value_name = "DIR", conflicts_with = "script")]
    pub record: Option<PathBuf>,
    /// With --record: the camera path, `orbit` (a full turn around the camera's look-at point
    /// in --frames frames, starting at the camera) or a path file (TOML `[[poses]]` with
    /// position and look_at; docs/viewer.md).
    #[arg(long, default_value = "orbit", value_name = "orbit|FILE")]
    pub path: String,
    /// With --record: frames of an orbit (a path file gives its own) [default: 60].
    /// Range: [1, 100000].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_ORBIT_FRAMES)))]
    pub frames: Option<u32>,
    /// Replay a script in the window: timed camera moves, key presses, resizes and screenshots,
    /// one step per frame number (docs/viewer.md#scripts); the viewer closes after its last step.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Write every windowed frame's figures (unsmoothed) to this CSV when the viewer closes:
    /// frame and latency times, the CPU stages, GPU, rays, triangle tests, passes.
    #[arg(long, value_name = "FILE", conflicts_with = "record")]
    pub stats: Option<PathBuf>,
    /// How frames reach the screen: fifo (vsync, never tears), mailbox or immediate (fall back
    /// to fifo, saying so, where the surface lacks them).
    #[arg(long, value_enum, default_value = "fifo")]
    pub present: PresentArg,
    /// Where `P` writes screenshots (shot-NNNN.png, .exr, -window.png, .json).
    #[arg(long, value_name = "DIR", default_value = "out/view")]
    pub screenshots: PathBuf,
    /// The starting camera (size, supersampling, position, look-at; the window opens at its
    /// size).
    #[command(flatten)]
    pub camera: CameraArgs,
    /// How the frames are made (the keys change them as the viewer runs: `]` `[` t, `.` `,`
    /// the angle, `v` the variant, `b` the blending scheme, `f` the format).
    #[command(flatten)]
    pub frame: FrameArgs,
    /// Projected EM face size, texels.
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = DEFAULT_EM_SIZE)]
    pub em_size: u32,
}

/// `--present`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PresentArg {
    /// Wait for the display's vertical blank; every device has it.
    Fifo,
    /// Replace the queued frame with the newest one: no tearing, no waiting.
    Mailbox,
    /// Present at once; may tear.
    Immediate,
}

/// `--help`'s text after the options: an example and the keys.
fn after_help() -> String {
    format!(
        "Examples:\n  lensmap view --scene teapot-room\n  lensmap view --scene glass-sphere --projected --record out/orbit --frames 60\n\n{}",
        keys::help_text()
    )
}

/// Where the layered EMs come from, as the user asked or the cache offered.
#[derive(Clone, Debug)]
pub(crate) struct EmChoice {
    /// A bake to read (given, or the demo's cache), if any.
    bake: Option<PathBuf>,
    /// Whether the viewer starts with the bake's inferred EMs (else projected ones).
    inferred_first: bool,
    /// Projected EMs' options.
    projected: ProjectedOptions,
    /// A radiance-map bake the glossy objects are drawn from, if any.
    radiance: Option<PathBuf>,
}

impl EmChoice {
    /// The user's choice, or the demo's cache when it holds a bake this scene can reuse, said
    /// in one line either way.
    fn choose(args: &ViewArgs, scene: &Scene, camera: &Camera) -> anyhow::Result<EmChoice> {
        let projected = ProjectedOptions::with_size(args.em_size);
        projected.validate().map_err(flag_error)?;
        if let Some(dir) = &args.bake {
            return Ok(EmChoice {
                bake: Some(dir.clone()),
                inferred_first: true,
                projected,
                radiance: args.radiance.clone(),
            });
        }
        let cache = Path::new("out").join(crate::demo::BAKE_CACHE);
        let offered = if args.projected {
            None
        } else {
            match lensmap_baker::bake::reuse::check(
                &cache,
                scene,
                &crate::demo::bake_options(camera),
                &[],
            ) {
                Ok(_) => {
                    say!(
                        "inferred layered EMs: the demo's bake in {} (key e: projected ones)",
                        cache.display()
                    );
                    Some(cache)
                }
                Err(why) => {
                    say!(
                        "projected layered EMs: no reusable bake in {} ({why}; `lensmap demo` or `lensmap bake` makes one)",
                        cache.display()
                    );
                    None
                }
            }
        };
        Ok(EmChoice {
            inferred_first: offered.is_some(),
            bake: offered,
            projected,
            radiance: args.radiance.clone(),
        })
    }

    /// ` --radiance DIR` when the glossy objects are drawn from a radiance-map bake, for the
    /// `lensmap render` command a screenshot repeats.
    pub(crate) fn radiance_flag(&self) -> String {
        self.radiance
            .as_ref()
            .map_or_else(String::new, |dir| format!(" --radiance {}", dir.display()))
    }

    /// The hybrid scene with inferred (`true`) or projected EMs.
    fn load(&self, scene: &Scene, inferred: bool) -> anyhow::Result<HybridScene> {
        let ems = match (&self.bake, inferred) {
            (Some(dir), true) => EmSource::Bake(dir.clone()),
            _ => EmSource::Projected(self.projected),
        };
        let (mut hybrid, _) = load_hybrid_scene(
            scene.clone(),
            &LoadOptions {
                ems,
                light_maps: LightMapOptions::default(),
            },
        )?;
        if let Some(dir) = &self.radiance {
            hybrid.use_radiance_bake(dir, lensmap::rsibr::Reconstruction::Warped)?;
        }
        Ok(hybrid)
    }
}

/// The most frames an orbit of `--record` may have (at 60 frames a second, 28 minutes).
pub const MAX_ORBIT_FRAMES: u32 = 100_000;

pub fn run(args: ViewArgs) -> anyhow::Result<()> {
    let scene = crate::common::load_scene(&args.scene)?;
    let camera = choose_camera(&scene, &args.scene, &args.camera)?;
    let options = args.frame.options()?;
    let script = match &args.script {
        Some(file) => Some(script::Script::load(file)?),
        None => None,
    };
    let ems = EmChoice::choose(&args, &scene, &camera)?;
    if args.record.is_none() && crate::common::validate_only() {
        return Ok(());
    }
    match &args.record {
        Some(dir) => record::run(&args, dir, scene, camera, &options, &ems),
        None => window::run(
            &args,
            window::Start {
                scene,
                camera,
                options,
                ems,
                script,
            },
        ),
    }
}
