//! The frame runner: what the command line, the tests and embedding hosts call to turn a scene
//! and its layered EMs into timed frames. It loads a [`HybridScene`] with baked or projected EMs
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
//! use lensmap::runner::{EmSource, FrameOptions, FrameRunner, Repetitions, lens_error};
//! use lensmap::runner::{load_hybrid_scene, novel_camera};
//! use lensmap::scene::Scene;
//! use lensmap::trace::{TraceOptions, render_reference};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = Scene::load_named("teapot-room")?;
//! let camera = novel_camera(&scene);
//! let ems = EmSource::Projected(ProjectedOptions::default());
//! let (hybrid, _) = load_hybrid_scene(scene, &ems)?;
//! let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
//! let repetitions = Repetitions { warmup: 1, timed: 3 };
//! let frames = runner.timed_frames(&hybrid, &camera, &FrameOptions::default(), repetitions)?;
//! println!("median frame {:.1} ms", frames.median(|f| f.total_ms));
//! let reference = render_reference(&hybrid.trace, &camera, &TraceOptions::default(), &|_| {})?;
//! let error = lens_error(&frames.last().image, &reference, Encoding::Linear)?;
//! println!("lens PSNR {:.2} dB ({})", error.psnr_db, error.encoding.name());
//! frames.last().image.write_png_and_exr("out/frame.png".as_ref())?;
//! # Ok(())
//! # }
//! ```

use std::{path::PathBuf, time::Instant};

use crate::{
    gpu::{Gpu, GpuError},
    hybrid::{
        HybridError, HybridOptions, HybridScene, HybridStats, frame::BuiltFrame,
        tessellate::TessellationError,
    },
    layers::{Bake, BakeError, projected::ProjectedOptions},
    lightmap::LightMapOptions,
    metrics::{self, Channels, Coverage, Encoding, ImageError, Mask, MetricsError},
    options::OptionError,
    render::{
        BlendScheme, FRAMES_IN_FLIGHT, FrameTimings, RenderError, RenderOptions, RenderedImage,
        Renderer, Submission, TargetFormat, UploadedFrame, Variant,
    },
    scene::{Camera, Scene},
    trace::ReferenceImage,
};

/// Where a hybrid scene's layered EMs come from.
#[derive(Clone, Debug, PartialEq)]
pub enum EmSource {
    /// A bake directory written by the baker (or `lensmap render --write-bake`) for this very
    /// scene: its manifest's provenance must name the scene's content hash.
    Bake(PathBuf),
    /// A bake directory used whatever scene it was made for (`render --accept-any-bake`): for
    /// deliberate reuse, e.g. a hand-made bake or one made before the scene was edited. Lens
    /// objects are still matched by name and every map is still validated.
    AnyBake(PathBuf),
    /// Projected from the scene onto the layer shells its file names.
    Projected(ProjectedOptions),
}

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
}

/// A bake as [`EmSource`] asks: one that says nothing of the scene it was made for is refused
/// unless any bake is accepted, and an accepted one loses its provenance, so that no scene check
/// applies to it.
fn checked_identity(mut bake: Bake, accept_any: bool) -> Result<Bake, HybridError> {
    if accept_any {
        bake.provenance = None;
    } else if bake.provenance.is_none() {
        return Err(HybridError::BakeMismatch(
            "manifest.json: provenance: the bake does not say which scene it was made from; bake this scene (lensmap bake --scene S --out DIR), or pass --accept-any-bake to use it anyway"
                .into(),
        ));
    }
    Ok(bake)
}

/// Loads `scene` with its layered EMs and light maps of the default options; returns the hybrid
/// scene and the rays cast to project EMs (0 for a bake).
pub fn load_hybrid_scene(scene: Scene, ems: &EmSource) -> Result<(HybridScene, u64), RunError> {
    load_hybrid_scene_with_light_maps(scene, ems, &LightMapOptions::default())
}

/// [`load_hybrid_scene`] with the environment's light maps made with `light_maps`.
pub fn load_hybrid_scene_with_light_maps(
    scene: Scene,
    ems: &EmSource,
    light_maps: &LightMapOptions,
) -> Result<(HybridScene, u64), RunError> {
    light_maps.validate()?;
    Ok(match ems {
        EmSource::Bake(dir) | EmSource::AnyBake(dir) => (
            // The mismatch names `manifest.json`; say which directory's.
            HybridScene::from_bake_with_light_maps(
                scene,
                checked_identity(Bake::read(dir)?, matches!(ems, EmSource::AnyBake(_)))?,
                light_maps,
            )
            .map_err(|error| match error {
                HybridError::BakeMismatch(message) => {
                    HybridError::BakeMismatch(format!("{}/{message}", dir.display()))
                }
                other => other,
            })?,
            0,
        ),
        EmSource::Projected(options) => {
            options.validate()?;
            HybridScene::projected_with_light_maps(scene, options, light_maps)?
        }
    })
}

/// What a hybrid frame is rendered with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Tessellation and the angle threshold.
    pub hybrid: HybridOptions,
    /// Compositor variant.
    pub variant: Variant,
    /// How the multipass variant combines layers and groups (the single pass takes only
    /// [`BlendScheme::FrontToBack`]).
    pub blend: BlendScheme,
    /// Framebuffer format.
    pub format: TargetFormat,
}

impl FrameOptions {
    /// Checks the options a frame cannot use before any work: the hybrid options, and a blending
    /// scheme other than front-to-back asked of the single pass (which does not blend).
    pub fn validate(&self) -> Result<(), OptionError> {
        self.hybrid.validate()?;
        OptionError::require(
            self.variant == Variant::Multipass || self.blend == BlendScheme::FrontToBack,
            "blend",
            self.blend.name(),
            "the single pass composites in registers and does not blend; give variant multipass, or blend front-to-back",
        )
    }
}

impl Default for FrameOptions {
    fn default() -> Self {
        FrameOptions {
            hybrid: HybridOptions::default(),
            variant: Variant::SinglePass,
            blend: BlendScheme::FrontToBack,
            format: TargetFormat::Rgba16f,
        }
    }
}

/// How many frames to render before timing (the first pays for pipeline creation and shader
/// compilation) and how many to time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repetitions {
    /// Untimed frames first.
    pub warmup: usize,
    /// Timed frames (at least one is rendered).
    pub timed: usize,
}

/// One hybrid frame's image and costs.
#[derive(Clone, Debug)]
pub struct HybridFrame {
    /// The frame at the camera's resolution (box-filtered from the supersampled framebuffer).
    pub image: RenderedImage,
    /// CPU stages.
    pub stats: HybridStats,
    /// GPU upload, rendering and readback, ms.
    pub gpu_ms: f64,
    /// Of which: uploading the frame's data (lens geometry; EMs only when new), ms.
    pub upload_ms: f64,
    /// Of which: recording, executing and reading back the frame.
    pub render: FrameTimings,
    /// Of which: box-filtering the supersampled framebuffer to pixels, ms.
    pub downsample_ms: f64,
    /// Whole frame, ms.
    pub total_ms: f64,
}

impl HybridFrame {
    /// "Other" in the paper's table: everything but vertex tracing, texture coordinates and
    /// tessellation, ms.
    pub fn other_ms(&self) -> f64 {
        (self.total_ms - self.stats.trace_ms - self.stats.texgen_ms - self.stats.tessellation_ms)
            .max(0.0)
    }

    /// What no stage accounts for (waiting, scheduling): the total minus every measured stage,
    /// ms. Near zero for a frame rendered alone; in a stream it includes waiting for the GPU.
    pub fn unaccounted_ms(&self) -> f64 {
        (self.total_ms
            - self.stats.trace_ms
            - self.stats.texgen_ms
            - self.stats.tessellation_ms
            - self.stats.assemble_ms
            - self.upload_ms
            - self.render.record_ms
            - self.render.execute_ms
            - self.render.readback_ms
            - self.downsample_ms)
            .max(0.0)
    }
}

/// A hybrid frame submitted into a host's image ([`FrameRunner::frame_into`]): its costs up to
/// the submission (the GPU's part is the host's to time).
#[derive(Clone, Debug)]
pub struct HostFrame {
    /// CPU stages.
    pub stats: HybridStats,
    /// Uploading the frame's data, ms.
    pub upload_ms: f64,
    /// Compiling the plan and recording the command buffer, ms.
    pub record_ms: f64,
    /// Passes recorded (the box filter and the hand-back included).
    pub passes: usize,
    /// From the start of the CPU stages to the submission, ms.
    pub total_ms: f64,
}

impl HostFrame {
    /// "Other" in the paper's table: everything but vertex tracing, texture coordinates and
    /// tessellation, ms (here: assembly, upload, recording and submission).
    pub fn other_ms(&self) -> f64 {
        (self.total_ms - self.stats.trace_ms - self.stats.texgen_ms - self.stats.tessellation_ms)
            .max(0.0)
    }
}

/// Timed hybrid frames of one setting: at least one (made only by
/// [`FrameRunner::timed_frames`]).
#[derive(Clone, Debug)]
pub struct TimedFrames {
    frames: Vec<HybridFrame>,
}

impl TimedFrames {
    /// The timed frames in order.
    pub fn frames(&self) -> &[HybridFrame] {
        &self.frames
    }

    /// Median over the frames of one stage's time.
    pub fn median(&self, stage: impl Fn(&HybridFrame) -> f64) -> f64 {
        median(&mut self.frames.iter().map(stage).collect::<Vec<_>>())
    }

    /// The last frame (its image and counters; counters are the same for every frame).
    pub fn last(&self) -> &HybridFrame {
        // `FrameRunner::timed_frames` renders at least one frame.
        &self.frames[self.frames.len() - 1]
    }
}

/// Compositor-only renders of one uploaded frame.
#[derive(Clone, Debug)]
pub struct TimedRenders {
    /// The image of the first (warm-up) render.
    pub image: RenderedImage,
    /// Timings of the timed renders (at least one).
    pub timings: Vec<FrameTimings>,
}

impl TimedRenders {
    /// Median over the timed renders of `stage`.
    pub fn median(&self, stage: impl Fn(&FrameTimings) -> f64) -> f64 {
        median(&mut self.timings.iter().map(stage).collect::<Vec<_>>())
    }
}

/// Median of a sample (0 for none).
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

/// A device and the compositor on it: runs frames of any hybrid scene.
///
/// Frames are uploaded into [`FRAMES_IN_FLIGHT`] reusable slots in turn (buffers, descriptor
/// pool and targets kept from frame to frame), and a frame equal to the one the last slot holds
/// (a still camera: [`HybridScene::frame_unless`]) is only rendered again, with no CPU stage and
/// no upload.
pub struct FrameRunner {
    // Declared before `gpu` so that they are dropped first (their objects belong to that device).
    slots: Vec<Slot>,
    /// The slot the last frame went to.
    last_slot: usize,
    renderer: Renderer,
    gpu: Gpu,
}

/// One reusable upload and the identity of the hybrid frame it holds (0: none).
#[derive(Default)]
struct Slot {
    uploaded: Option<UploadedFrame>,
    identity: u64,
}

/// A frame whose CPU stages and upload are done, in its slot.
struct Staged {
    slot: usize,
    stats: HybridStats,
    upload_ms: f64,
    /// When its CPU stages began.
    start: Instant,
    /// When its upload began.
    gpu_start: Instant,
}

/// A frame whose CPU stages and upload are done and whose GPU work was submitted.
struct Pending {
    slot: usize,
    submission: Submission,
    stats: HybridStats,
    supersampling: u32,
    upload_ms: f64,
    start: Instant,
    gpu_start: Instant,
}

impl FrameRunner {
    /// A runner on `gpu`.
    pub fn new(gpu: Gpu) -> Result<FrameRunner, GpuError> {
        let renderer = Renderer::new(&gpu)?;
        Ok(FrameRunner {
            slots: (0..FRAMES_IN_FLIGHT).map(|_| Slot::default()).collect(),
            last_slot: 0,
            renderer,
            gpu,
        })
    }

    /// The device (its name, the validation report).
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Checks that frames of `camera` (its subpixels) in `format` fit this device, before any
    /// work: [`crate::render::check_framebuffer`].
    pub fn check_framebuffer(
        &self,
        camera: &crate::scene::Camera,
        format: TargetFormat,
    ) -> Result<(), RenderError> {
        let side = |pixels: u32| pixels.saturating_mul(camera.supersampling);
        crate::render::check_framebuffer(&self.gpu, side(camera.width), side(camera.height), format)
    }

    /// Uploads a compositor frame (for compositor-only work such as [`Self::timed_renders`]).
    pub fn upload(
        &mut self,
        frame: &crate::render::FrameInput,
    ) -> Result<UploadedFrame, RenderError> {
        self.renderer.upload(&self.gpu, frame)
    }

    /// Uploads and renders one compositor frame at its framebuffer resolution (no box filter):
    /// the baker's test renderings go through here, so they use exactly the runtime's shaders,
    /// passes, sampler and target format.
    pub fn render(
        &mut self,
        frame: &crate::render::FrameInput,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<RenderedImage, RenderError> {
        let mut uploaded = self.renderer.upload(&self.gpu, frame)?;
        Ok(self
            .renderer
            .render(
                &self.gpu,
                &mut uploaded,
                &RenderOptions {
                    variant,
                    format,
                    ..RenderOptions::default()
                },
            )?
            .0)
    }

    /// Renders an uploaded frame at its framebuffer resolution (no box filter).
    pub fn render_uploaded(
        &mut self,
        uploaded: &mut UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<RenderedImage, RenderError> {
        Ok(self
            .renderer
            .render(
                &self.gpu,
                uploaded,
                &RenderOptions {
                    variant,
                    format,
                    ..RenderOptions::default()
                },
            )?
            .0)
    }

    /// Which pixels of `frame` show a lens object, from its geometry, not from a frame's
    /// colours: the frame rendered twice in the multipass variant with every layered EM replaced
    /// by a uniform map, once of (0, 0, 0, 0) texels and once of opaque black (0, 0, 0, 1). A lens
    /// pixel (its prime passed the depth test) ends with α = 0 in the first render (the prime and
    /// the alpha clears write 0, and no layer adds any) and α = 1 in the second (each group's
    /// first layer blends 1 over 0); the environment writes α = 1 in both and the background
    /// keeps the clear's 0 in both. In RGBA8 these alphas are exact on any driver. The pixels are
    /// the framebuffer's (its subpixels, before any box filter).
    pub fn lens_coverage(
        &mut self,
        frame: &crate::render::FrameInput,
    ) -> Result<Mask, RenderError> {
        let mut alpha = |texel: [f32; 4]| -> Result<Vec<f32>, RenderError> {
            let mut uniform = frame.clone();
            for lens in &mut uniform.lenses {
                for maps in &mut lens.layers {
                    for map in maps.iter_mut() {
                        *map =
                            std::sync::Arc::new(crate::cubemap::CubeMap::uniform(map.size, texel));
                    }
                }
            }
            let image = self.render(&uniform, Variant::Multipass, TargetFormat::Rgba8)?;
            Ok(image.pixels.iter().map(|p| p[3]).collect())
        };
        let transparent = alpha([0.0; 4])?;
        let opaque = alpha([0.0, 0.0, 0.0, 1.0])?;
        Ok(Mask::from_flags(
            transparent
                .iter()
                .zip(&opaque)
                .map(|(&t, &o)| t == 0.0 && o == 1.0)
                .collect(),
        ))
    }

    /// Replaces the layered EMs of lens `lens` of an uploaded frame (see
    /// [`Renderer::replace_layers`]): the baker's test renderings change only the maps.
    pub fn replace_layers(
        &mut self,
        uploaded: &mut UploadedFrame,
        lens: usize,
        layers: &[Vec<std::sync::Arc<crate::cubemap::CubeMap>>],
    ) -> Result<(), RenderError> {
        self.renderer
            .replace_layers(&self.gpu, uploaded, lens, layers)
    }

    /// Renders one hybrid frame of `hybrid` seen by `camera`, and reads it back.
    pub fn frame(
        &mut self,
        hybrid: &HybridScene,
        camera: &Camera,
        options: &FrameOptions,
    ) -> Result<HybridFrame, RunError> {
        let (frames, _) = self.frames_in_flight(hybrid, std::slice::from_ref(camera), options)?;
        frames
            .into_iter()
            .next()
            .ok_or_else(|| RenderError::BadInput("no frame was rendered".into()).into())
    }

    /// Renders `cameras` in order with up to [`FRAMES_IN_FLIGHT`] frames in flight: the CPU
    /// stages of frame N + 1 run while the GPU renders frame N, and a frame is read back only
    /// when its slot is needed again or at the end. Each frame's `total_ms` is its latency, from
    /// the start of its CPU stages to its image on the host; the second value is the wall time
    /// of the whole run, ms (throughput = frames / wall time).
    pub fn frames_in_flight(
        &mut self,
        hybrid: &HybridScene,
        cameras: &[Camera],
        options: &FrameOptions,
    ) -> Result<(Vec<HybridFrame>, f64), RunError> {
        options.validate()?;
        let start = Instant::now();
        let mut frames = Vec::with_capacity(cameras.len());
        let mut in_flight = std::collections::VecDeque::new();
        for camera in cameras {
            let staged = self.stage(hybrid, camera, options, |runner, slot| {
                // The slot's previous frame is read back before the slot is written again.
                while in_flight.iter().any(|p: &Pending| p.slot == slot) {
                    if let Some(oldest) = in_flight.pop_front() {
                        frames.push(runner.finish(oldest)?);
                    }
                }
                Ok(())
            })?;
            let Some(uploaded) = self.slots[staged.slot].uploaded.as_mut() else {
                // A held identity is only ever that of an uploaded slot.
                return Err(RenderError::BadInput("a still frame has no upload".into()).into());
            };
            let submission = self.renderer.submit(
                &self.gpu,
                uploaded,
                &RenderOptions {
                    variant: options.variant,
                    blend: options.blend,
                    format: options.format,
                    host: None,
                },
            )?;
            in_flight.push_back(Pending {
                slot: staged.slot,
                submission,
                stats: staged.stats,
                supersampling: camera.supersampling,
                upload_ms: staged.upload_ms,
                start: staged.start,
                gpu_start: staged.gpu_start,
            });
        }
        while let Some(pending) = in_flight.pop_front() {
            frames.push(self.finish(pending)?);
        }
        Ok((frames, start.elapsed().as_secs_f64() * 1e3))
    }

    /// Renders one hybrid frame of `hybrid` seen by `camera` into a host's image on this
    /// runner's device (a runner made on the host's device: [`Gpu::from_host`]) and returns once
    /// it is submitted, with no readback: the CPU stages and upload as for [`Self::frame`], the
    /// frame's plan ending in the GPU box filter into `host` (whose size is the camera's width ×
    /// height), submitted with the host's wait and signal semaphores. The host learns that the
    /// frame is done from its signal semaphores (or from later work on the same queue).
    pub fn frame_into(
        &mut self,
        hybrid: &HybridScene,
        camera: &Camera,
        options: &FrameOptions,
        host: &crate::render::HostImage,
    ) -> Result<HostFrame, RunError> {
        options.validate()?;
        if (host.width, host.height) != (camera.width, camera.height) {
            return Err(RenderError::BadInput(format!(
                "host image is {}×{}; the camera's frame is {}×{}: give an image of the camera's size",
                host.width, host.height, camera.width, camera.height
            ))
            .into());
        }
        // Everything else about the image is checked before any CPU stage runs.
        let k = camera.supersampling.max(1);
        host.output(
            camera.width.saturating_mul(k),
            camera.height.saturating_mul(k),
        )?;
        let staged = self.stage(hybrid, camera, options, |_, _| Ok(()))?;
        let Some(uploaded) = self.slots[staged.slot].uploaded.as_mut() else {
            return Err(RenderError::BadInput("a still frame has no upload".into()).into());
        };
        let submission = self.renderer.submit(
            &self.gpu,
            uploaded,
            &RenderOptions {
                variant: options.variant,
                blend: options.blend,
                format: options.format,
                host: Some(host),
            },
        )?;
        Ok(HostFrame {
            stats: staged.stats,
            upload_ms: staged.upload_ms,
            record_ms: submission.record_ms(),
            passes: submission.passes(),
            total_ms: staged.start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// A frame's CPU stages (unless the last slot holds it already: a still camera) and its
    /// upload into the next slot, after `free_slot` made sure nothing pending still reads it.
    fn stage(
        &mut self,
        hybrid: &HybridScene,
        camera: &Camera,
        options: &FrameOptions,
        mut free_slot: impl FnMut(&mut Self, usize) -> Result<(), RunError>,
    ) -> Result<Staged, RunError> {
        let start = Instant::now();
        let held = self.slots[self.last_slot].identity;
        let built = hybrid.frame_unless(camera, &options.hybrid, held)?;
        let slot = match built {
            BuiltFrame::Unchanged(_) => self.last_slot,
            BuiltFrame::New(..) => (self.last_slot + 1) % self.slots.len(),
        };
        free_slot(self, slot)?;
        let gpu_start = Instant::now();
        let stats = match built {
            BuiltFrame::Unchanged(stats) => stats,
            BuiltFrame::New(frame, stats, identity) => {
                let uploaded = match self.slots[slot].uploaded.take() {
                    Some(previous) => self.renderer.upload_into(&self.gpu, &frame, previous)?,
                    None => self.renderer.upload(&self.gpu, &frame)?,
                };
                self.slots[slot] = Slot {
                    uploaded: Some(uploaded),
                    identity,
                };
                stats
            }
        };
        self.last_slot = slot;
        Ok(Staged {
            slot,
            stats,
            upload_ms: gpu_start.elapsed().as_secs_f64() * 1e3,
            start,
            gpu_start,
        })
    }

    /// Waits for a submitted frame, reads it back and box-filters it to pixels.
    fn finish(&mut self, pending: Pending) -> Result<HybridFrame, RunError> {
        let Some(uploaded) = self.slots[pending.slot].uploaded.as_ref() else {
            return Err(RenderError::BadInput("a pending frame lost its upload".into()).into());
        };
        let (image, render) = self.renderer.finish(uploaded, pending.submission)?;
        let downsample_start = Instant::now();
        let image = image.box_downsample(pending.supersampling);
        let downsample_ms = downsample_start.elapsed().as_secs_f64() * 1e3;
        Ok(HybridFrame {
            image,
            stats: pending.stats,
            gpu_ms: pending.gpu_start.elapsed().as_secs_f64() * 1e3,
            upload_ms: pending.upload_ms,
            render,
            downsample_ms,
            total_ms: pending.start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// `repetitions.warmup` untimed frames, then `repetitions.timed` timed ones (at least one),
    /// each built from scratch (the scene's frame cache is cleared first: a repeated camera is
    /// timed as a moving one would be; [`FrameRunner::frame`] twice times a still one).
    pub fn timed_frames(
        &mut self,
        hybrid: &HybridScene,
        camera: &Camera,
        options: &FrameOptions,
        repetitions: Repetitions,
    ) -> Result<TimedFrames, RunError> {
        let full_frame = |runner: &mut Self| {
            hybrid.forget_frame();
            runner.frame(hybrid, camera, options)
        };
        for _ in 0..repetitions.warmup {
            full_frame(self)?;
        }
        let frames = (0..repetitions.timed.max(1))
            .map(|_| full_frame(self))
            .collect::<Result<_, _>>()?;
        Ok(TimedFrames { frames })
    }

    /// The compositor alone on an uploaded frame: one warm-up render (its image is returned),
    /// then `timed` timed renders (at least one).
    pub fn timed_renders(
        &mut self,
        uploaded: &mut UploadedFrame,
        variant: Variant,
        format: TargetFormat,
        timed: usize,
    ) -> Result<TimedRenders, RenderError> {
        self.timed_renders_blended(uploaded, (variant, BlendScheme::FrontToBack), format, timed)
    }

    /// [`Self::timed_renders`] with the multipass variant's layers combined by `blend`.
    pub fn timed_renders_blended(
        &mut self,
        uploaded: &mut UploadedFrame,
        compositing: (Variant, BlendScheme),
        format: TargetFormat,
        timed: usize,
    ) -> Result<TimedRenders, RenderError> {
        let options = RenderOptions {
            variant: compositing.0,
            blend: compositing.1,
            format,
            host: None,
        };
        let (image, _) = self.renderer.render(&self.gpu, uploaded, &options)?;
        let timings = (0..timed.max(1))
            .map(|_| {
                self.renderer
                    .render(&self.gpu, uploaded, &options)
                    .map(|(_, timings)| timings)
            })
            .collect::<Result<_, _>>()?;
        Ok(TimedRenders { image, timings })
    }
}

/// The demo's and the hybrid benchmark's novel viewpoint: halfway (in angle) between viewpoint
/// samples 2 and 3 of the scene's view space, at their mean distance from the look-at point, so
/// two samples are blended; the scene camera when the view space has fewer than four samples.
pub fn novel_camera(scene: &Scene) -> Camera {
    camera_between(scene, 2, 3).unwrap_or(scene.camera)
}

/// The scene camera halfway (in angle about the look-at point) between viewpoint samples `a`
/// and `b`, at their mean distance from it; `None` when the view space lacks either sample.
pub fn camera_between(scene: &Scene, a: usize, b: usize) -> Option<Camera> {
    let samples = scene.view_space.samples();
    let look_at = scene.camera.look_at;
    let (da, db) = (*samples.get(a)? - look_at, *samples.get(b)? - look_at);
    let direction = (da.normalize() + db.normalize()).normalize_or(da.normalize());
    Some(
        scene
            .camera
            .with_position(look_at + direction * 0.5 * (da.length() + db.length())),
    )
}

/// The error of a hybrid frame against the reference ray tracer over the lens pixels: those the
/// reference sees as entirely lens (coverage 1, no background mixed in), RGB, in `encoding`.
/// [`Encoding::DisplaySrgb`] is the figure lensmap has always printed as "lens PSNR";
/// [`Encoding::Linear`] also counts errors in highlights above 1. An error when no pixel is all
/// lens.
pub fn lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    metrics::compare(
        &image.pixels,
        &reference.radiance,
        &Mask::from_coverage(&reference.lens_mask, Coverage::Full),
        encoding,
        Channels::Rgb,
    )
}

/// The error of a hybrid frame against the reference ray tracer over the non-lens pixels: those
/// in which no reference sub-sample saw a lens object (coverage 0), so the opaque environment,
/// light-mapped on the GPU, and the background are all they show; RGB, in `encoding`. An error
/// when every pixel sees some lens.
pub fn non_lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    metrics::compare(
        &image.pixels,
        &reference.radiance,
        &Mask::from_coverage(&reference.lens_mask, Coverage::None),
        encoding,
        Channels::Rgb,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_empty_samples() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut []), 0.0);
    }

    #[test]
    fn the_novel_camera_bisects_samples_2_and_3() {
        let scene = Scene::load_named("teapot-room").unwrap();
        let samples = scene.view_space.samples();
        let look_at = scene.camera.look_at;
        let camera = novel_camera(&scene);
        let (a, b, c) = (
            (samples[2] - look_at).normalize(),
            (samples[3] - look_at).normalize(),
            (camera.position - look_at).normalize(),
        );
        // Equal angles to both samples, in their plane, between them.
        assert!((c.dot(a) - c.dot(b)).abs() < 1e-6, "{c} {a} {b}");
        assert!(c.dot(a) > a.dot(b));
        let distance = 0.5 * ((samples[2] - look_at).length() + (samples[3] - look_at).length());
        assert!(((camera.position - look_at).length() - distance).abs() < 1e-4);
    }

    #[test]
    fn other_is_what_the_papers_three_cpu_stages_leave() {
        let frame = HybridFrame {
            image: RenderedImage {
                width: 1,
                height: 1,
                pixels: vec![[0.0; 4]],
            },
            stats: HybridStats {
                trace_ms: 4.0,
                texgen_ms: 1.0,
                tessellation_ms: 2.0,
                ..HybridStats::default()
            },
            gpu_ms: 2.5,
            upload_ms: 0.5,
            render: FrameTimings {
                record_ms: 0.25,
                execute_ms: 1.0,
                readback_ms: 0.5,
                passes: 3,
                saturated: 0,
            },
            downsample_ms: 0.25,
            total_ms: 10.0,
        };
        assert_eq!(frame.other_ms(), 3.0);
        // Of the other 3 ms, 2.5 are measured stages.
        assert_eq!(frame.unaccounted_ms(), 0.5);
    }
}
