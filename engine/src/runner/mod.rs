//! The frame runner: what the command line, the tests and embedding hosts call to turn a scene
//! and its layered EMs into timed frames. It loads a [`HybridScene`](crate::hybrid::HybridScene) with baked or projected EMs
//! ([`load_hybrid_scene`]), runs hybrid frames (per-vertex tracing and tessellation on the CPU,
//! upload, compositing, read-back, the supersampled framebuffer box-filtered to pixels) with the
//! paper's per-stage statistics ([`FrameRunner::frame`]), repeats them after warm-up frames for
//! medians ([`FrameRunner::timed_frames`]), and times the compositor alone on an uploaded frame
//! ([`FrameRunner::timed_renders`]). The room sits on top of `hybrid/` and `render/`; nothing
//! here parses arguments or prints.
//!
//! ```no_run
//! use lensmap::gpu::{Gpu, GpuOptions};
//! use lensmap::layers::projected::ProjectedOptions;
//! use lensmap::metrics::Encoding;
//! use lensmap::runner::{EmSource, FrameOptions, FrameRunner, LoadOptions, Repetitions};
//! use lensmap::runner::{lens_error, load_hybrid_scene, novel_camera};
//! use lensmap::scene::Scene;
//! use lensmap::trace::{TraceOptions, render_reference};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = Scene::load_named("teapot-room")?;
//! let camera = novel_camera(&scene);
//! let load = LoadOptions {
//!     ems: EmSource::Projected(ProjectedOptions::default()),
//!     ..LoadOptions::default()
//! };
//! let (hybrid, _) = load_hybrid_scene(scene, &load)?;
//! let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
//! let repetitions = Repetitions { warmup: 1, timed: 3 };
//! let frames = runner.timed_frames(&hybrid, &camera, &FrameOptions::default(), repetitions)?;
//! println!("median frame {:.1} ms", frames.median(|f| f.total_ms));
//! let reference = render_reference(hybrid.trace(), &camera, &TraceOptions::default(), &|_| {})?;
//! let error = lens_error(&frames.last().image, &reference, Encoding::Linear)?;
//! println!("lens PSNR {:.2} dB ({})", error.psnr_db, error.encoding.name());
//! frames.last().image.write_png_and_exr("out/frame.png".as_ref())?;
//! # Ok(())
//! # }
//! ```

mod camera;
mod frame_runner;
mod lens_pixels;
mod load;
mod timing;

pub use camera::{camera_between, novel_camera};
pub use frame_runner::{FrameOptions, FrameRunner};
pub use lens_pixels::{lens_error, non_lens_error};
pub use load::{EmSource, LoadOptions, load_hybrid_scene};
pub use timing::{HostFrame, HybridFrame, Repetitions, TimedFrames, TimedRenders, median};

use crate::{
    hybrid::{HybridError, tessellate::TessellationError},
    layers::BakeError,
    options::{OptionError, OptionWords, Worded},
    render::RenderError,
};

/// Why a frame or a scene could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// An option is out of range (exit code 2 on the command line).
    #[error(transparent)]
    Option(#[from] OptionError),
    /// The bake could not be read.
    #[error(transparent)]
    Bake(#[from] BakeError),
    /// The scene and its EMs do not fit together, or the tracer refused the scene.
    #[error(transparent)]
    Hybrid(#[from] HybridError),
    /// Tessellation refused a lens mesh.
    #[error(transparent)]
    Tessellation(#[from] TessellationError),
    /// Uploading or rendering failed.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The device could not take the scene's geometry for the GPU tracer (kept, and raised
    /// again by every frame that asks for the GPU tracer).
    #[error("upload to the GPU tracer's geometry: {0}")]
    Tracer(std::sync::Arc<crate::gpu::GpuError>),
}

impl Worded for RunError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            RunError::Option(error) => error.worded(words),
            RunError::Hybrid(error) => error.worded(words),
            RunError::Render(error) => error.worded(words),
            RunError::Bake(_) | RunError::Tessellation(_) | RunError::Tracer(_) => self.to_string(),
        }
    }
}
