//! The frame runner: a device and the compositor on it, running hybrid frames of any hybrid
//! scene. Frames are uploaded into reusable slots with up to [`FRAMES_IN_FLIGHT`] in flight,
//! read back and box-filtered to pixels, or rendered into a host's image; compositor-only
//! renders of an uploaded frame are timed for the benchmarks and the baker.

use std::{sync::Arc, time::Instant};

use super::{
    RunError,
    timing::{HostFrame, HybridFrame, Repetitions, TimedFrames, TimedRenders},
};
use crate::{
    gpu::{Gpu, GpuError},
    hybrid::{
        BuiltFrame, CpuStage, FrameBuilder, FrameId, FresnelModel, GpuReadBack, GpuResident,
        HybridOptions, HybridScene, HybridStats, VertexStage, VertexTracer, Wireframe,
        gpu::{GpuPaths, GpuTracer, TracerWalk, read_counts},
    },
    index::LensIndex,
    options::OptionError,
    render::{
        Compositing, DeviceLensPart, FRAMES_IN_FLIGHT, FrameInput, HostImage, RenderError,
        RenderOptions, RenderedImage, Renderer, SinglePassLimits, Submission, TargetFormat,
        UploadedFrame,
    },
    scene::Camera,
};

/// What a hybrid frame is rendered with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Tessellation and the angle threshold.
    pub hybrid: HybridOptions,
    /// How lens objects are composited: the single pass, or the multipass variant and its
    /// blending scheme.
    pub compositing: Compositing,
    /// Framebuffer format.
    pub format: TargetFormat,
}

impl FrameOptions {
    /// The compositor's part of these options, for a frame read back.
    pub fn compositing(&self) -> RenderOptions<'static> {
        RenderOptions {
            compositing: self.compositing,
            format: self.format,
            host: None,
        }
    }

    /// The compositing a frame with `stats` runs with on a device of single-pass limits
    /// `limits`: these options' own, but the multipass variant front-to-back (the same
    /// composite) in place of the single pass for a frame of path classes whose varyings the
    /// single pass cannot carry (K·(n + 1) past [`SinglePassLimits::max_class_slots`]).
    pub fn compositing_for(&self, stats: &HybridStats, limits: &SinglePassLimits) -> Compositing {
        match self.compositing {
            Compositing::SinglePass if stats.class_slots > limits.max_class_slots => {
                Compositing::Multipass(crate::render::BlendScheme::FrontToBack)
            }
            compositing => compositing,
        }
    }

    /// Checks the options a frame cannot use before any work (the hybrid options).
    pub fn validate(&self) -> Result<(), OptionError> {
        self.hybrid.validate()
    }
}

impl Default for FrameOptions {
    fn default() -> Self {
        FrameOptions {
            hybrid: HybridOptions::default(),
            compositing: Compositing::SinglePass,
            format: TargetFormat::Rgba16f,
        }
    }
}

/// A device and the compositor on it: runs frames of any hybrid scene.
///
/// Frames are uploaded into [`FRAMES_IN_FLIGHT`] reusable slots in turn (buffers, descriptor
/// pool and targets kept from frame to frame), and a frame equal to the one the last slot holds
/// (a still camera: [`FrameBuilder::frame_unless`]) is only rendered again, with no CPU stage
/// and no upload. Its [`FrameBuilder`] keeps the last frame; the vertex stage of each frame is
/// chosen here, where the device is.
pub struct FrameRunner {
    /// Builds the frames and keeps the last one.
    builder: FrameBuilder,
    // Declared before `gpu` so that they are dropped first (their objects belong to that device).
    slots: Vec<Slot>,
    /// The last scene's geometry resident on the device, for frames traced on the GPU.
    tracer: Option<ResidentTracer>,
    /// The same scene's for another walk or precision, when frames switched: kept, so that
    /// frames that alternate them (a benchmark, the viewer) do not upload and build every time.
    spare: Option<ResidentTracer>,
    /// Whether GPU-traced frames time their stages ([`FrameRunner::time_gpu_stages`]).
    time_gpu_stages: bool,
    /// Whether GPU-traced frames read their meshes back ([`FrameRunner::read_back_gpu_meshes`]).
    read_back_gpu_meshes: bool,
    /// The frames into a host's image drawn from the device's buffers whose counts are not
    /// read yet, oldest first: each one's submission value, parts and stats
    /// ([`HostFrame::previous`]).
    host_counts: std::collections::VecDeque<(u64, Vec<Arc<DeviceLensPart>>, HybridStats)>,
    /// Whether a finished frame's counts said the GPU tessellation's buffers stopped splits and
    /// the tracer grew them (a single frame is then made again).
    grew: bool,
    /// The slot the last frame went to.
    last_slot: usize,
    renderer: Renderer,
    gpu: Gpu,
}

/// A scene's geometry and BVHs resident on the runner's device, with the Schlick table of the
/// Fresnel model it was made for, or why the device could not take them (kept, so that `auto`
/// does not try again every frame).
struct ResidentTracer {
    scene: u64,
    fresnel: FresnelModel,
    walk: TracerWalk,
    tracer: Result<GpuTracer, Arc<GpuError>>,
}

/// One reusable upload and the identity of the hybrid frame it holds.
#[derive(Default)]
struct Slot {
    uploaded: Option<UploadedFrame>,
    identity: Option<FrameId>,
    /// The frame's lens parts drawn from the device's buffers (their counts).
    parts: Vec<Arc<DeviceLensPart>>,
}

/// A frame whose CPU stages and upload are done, in its slot.
struct Staged {
    slot: usize,
    stats: HybridStats,
    /// Its lens parts drawn from the device's buffers, whose counts are read once it is done.
    parts: Vec<Arc<DeviceLensPart>>,
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
    parts: Vec<Arc<DeviceLensPart>>,
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
            builder: FrameBuilder::new(),
            slots: (0..FRAMES_IN_FLIGHT).map(|_| Slot::default()).collect(),
            tracer: None,
            spare: None,
            time_gpu_stages: false,
            read_back_gpu_meshes: false,
            host_counts: std::collections::VecDeque::new(),
            grew: false,
            last_slot: 0,
            renderer,
            gpu,
        })
    }

    /// The device (its name, the validation report).
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// What the single pass composites on this device.
    pub fn single_pass_limits(&self) -> SinglePassLimits {
        SinglePassLimits::of_device(&self.gpu.properties().limits)
    }

    /// The compositing a frame with `stats` runs with under `options` on this device
    /// ([`FrameOptions::compositing_for`]).
    pub fn compositing_for(&self, options: &FrameOptions, stats: &HybridStats) -> Compositing {
        options.compositing_for(stats, &self.single_pass_limits())
    }

    /// Forgets the last frame, so that the next one is built from scratch even for the same
    /// camera: what timing a full frame needs.
    pub fn forget_frame(&mut self) {
        self.builder.forget();
    }

    /// The tessellation wireframe of the last frame built or reused
    /// ([`FrameBuilder::last_wireframe`]); frames drawn where the GPU left them have none (their
    /// meshes are not read back: [`FrameRunner::read_back_gpu_meshes`]).
    pub fn last_wireframe(&self) -> Option<Wireframe> {
        self.builder.last_wireframe()
    }

    /// Checks that frames of `camera` (its subpixels) in `format` fit this device, before any
    /// work: [`crate::render::check_framebuffer`].
    pub fn check_framebuffer(
        &self,
        camera: &Camera,
        format: TargetFormat,
    ) -> Result<(), RenderError> {
        let side = |pixels: u32| pixels.saturating_mul(camera.supersampling);
        crate::render::check_framebuffer(&self.gpu, side(camera.width), side(camera.height), format)
    }

    /// Uploads a compositor frame (for compositor-only work such as [`Self::timed_renders`]).
    pub fn upload(&mut self, frame: &FrameInput) -> Result<UploadedFrame, RenderError> {
        self.renderer.upload(&self.gpu, frame)
    }

    /// Uploads and renders one compositor frame at its framebuffer resolution (no box filter):
    /// the baker's test renderings go through here, so they use exactly the runtime's shaders,
    /// passes, sampler and target format.
    pub fn render(
        &mut self,
        frame: &FrameInput,
        compositing: Compositing,
        format: TargetFormat,
    ) -> Result<RenderedImage, RenderError> {
        let mut uploaded = self.renderer.upload(&self.gpu, frame)?;
        self.render_uploaded(&mut uploaded, compositing, format)
    }

    /// Renders an uploaded frame at its framebuffer resolution (no box filter).
    pub fn render_uploaded(
        &mut self,
        uploaded: &mut UploadedFrame,
        compositing: Compositing,
        format: TargetFormat,
    ) -> Result<RenderedImage, RenderError> {
        let options = RenderOptions {
            compositing,
            format,
            host: None,
        };
        Ok(self.renderer.render(&self.gpu, uploaded, &options)?.0)
    }

    /// Replaces the layered EMs of lens `lens` of an uploaded frame (see
    /// [`Renderer::replace_layers`]): the baker's test renderings change only the maps.
    pub fn replace_layers(
        &mut self,
        uploaded: &mut UploadedFrame,
        lens: LensIndex,
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
        let mut discarded = 0;
        loop {
            self.grew = false;
            let (frames, _) =
                self.frames_in_flight(hybrid, std::slice::from_ref(camera), options)?;
            // A frame whose buffers stopped splits before the budget is made again with the
            // larger ones (they grow fourfold each time, up to what the device holds).
            if self.grew {
                self.builder.forget();
                discarded += 1;
                continue;
            }
            let mut frame = frames
                .into_iter()
                .next()
                .ok_or_else(|| RenderError::Internal("no frame was rendered".into()))?;
            frame.stats.builds_discarded = discarded;
            return Ok(frame);
        }
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
            let submission = self.submit(staged.slot, options, &staged.stats, None)?;
            in_flight.push_back(Pending {
                slot: staged.slot,
                submission,
                stats: staged.stats,
                parts: staged.parts,
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
        host: &HostImage,
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
        let submission = self.submit(staged.slot, options, &staged.stats, Some(host))?;
        // The counts of the frames before that are done by now (never waited for here); the
        // latest of them is reported. Frames complete in order, and no more than the slots are
        // ever pending.
        let mut previous = None;
        while let Some((value, ..)) = self.host_counts.front()
            && self.renderer.completed(*value)
        {
            if let Some((_, parts, mut stats)) = self.host_counts.pop_front() {
                self.grew |= self.add_device_counts(&mut stats, &parts)?;
                previous = Some(stats);
            }
        }
        if !staged.parts.is_empty() {
            let held = (submission.value(), staged.parts, staged.stats);
            self.host_counts.push_back(held);
        }
        // Only a device that stopped completing work leaves more pending: their counts go.
        while self.host_counts.len() > FRAMES_IN_FLIGHT + 1 {
            self.host_counts.pop_front();
        }
        Ok(HostFrame {
            stats: staged.stats,
            previous,
            upload_ms: staged.upload_ms,
            record_ms: submission.record_ms(),
            passes: submission.passes(),
            total_ms: staged.start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// Adds the device's counts of a finished frame's resident lens parts to its `stats`;
    /// where they say the tessellation's buffers stopped splits before the vertex budget, the
    /// tracer grows them for the next frame. Returns whether it did.
    fn add_device_counts(
        &self,
        stats: &mut HybridStats,
        parts: &[Arc<DeviceLensPart>],
    ) -> Result<bool, RunError> {
        let mut capped = Vec::new();
        for part in parts {
            let counts = read_counts(part);
            stats.triangles_out += counts.triangles as usize;
            stats.hull_triangles += counts.hull_triangles as usize;
            // A frame reused whole traced nothing: only what it draws counts.
            if !stats.reused {
                stats.stopped_by_budget += counts.stopped_by_budget as usize;
                stats.vertices_traced += counts.counters.primary_rays as usize;
                stats.counters += counts.counters;
                if counts.capped_by_buffers {
                    capped.push(part);
                }
            }
        }
        // The tracer that made the parts grows: the frame may have come from the spare one.
        let mut grew = false;
        for resident in [&self.tracer, &self.spare].into_iter().flatten() {
            if let Ok(tracer) = &resident.tracer
                && capped.iter().any(|part| tracer.made(part))
            {
                grew |= tracer.grow();
            }
        }
        Ok(grew)
    }

    /// Whether frames traced on the GPU read their meshes back to the host (the tessellation
    /// wireframe and the per-triangle depths need them), instead of being drawn where the GPU
    /// left them with no per-vertex data read back (the default).
    pub fn read_back_gpu_meshes(&mut self, on: bool) {
        self.read_back_gpu_meshes = on;
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
        let tracer = options.hybrid.tracer;
        let on_gpu = tracer.on_gpu(&self.gpu)
            && match self.make_resident(hybrid, &options.hybrid) {
                Ok(()) => true,
                // `auto` traces on the CPU where the device cannot hold the scene's geometry.
                Err(_) if tracer == VertexTracer::Auto => false,
                Err(error) => return Err(error),
            };
        let built = match &self.tracer {
            Some(ResidentTracer {
                tracer: Ok(tracer), ..
            }) if on_gpu => {
                let paths = GpuPaths {
                    gpu: &self.gpu,
                    tracer,
                };
                // Drawn where the GPU leaves it, unless the meshes are to be read back.
                let stage: &dyn VertexStage = if self.read_back_gpu_meshes {
                    &GpuReadBack { paths }
                } else {
                    &GpuResident { paths }
                };
                self.builder
                    .frame_unless(hybrid, camera, &options.hybrid, stage, held)?
            }
            _ => self
                .builder
                .frame_unless(hybrid, camera, &options.hybrid, &CpuStage, held)?,
        };
        let slot = match built {
            BuiltFrame::Unchanged(_) => self.last_slot,
            BuiltFrame::New(..) => (self.last_slot + 1) % self.slots.len(),
        };
        free_slot(self, slot)?;
        let gpu_start = Instant::now();
        let mut parts = Vec::new();
        let stats = match built {
            BuiltFrame::Unchanged(stats) => {
                parts.clone_from(&self.slots[slot].parts);
                stats
            }
            BuiltFrame::New(frame, stats, identity) => {
                parts = frame
                    .lenses
                    .iter()
                    .filter_map(|lens| lens.resident.as_ref())
                    .flat_map(|resident| resident.parts.iter().cloned())
                    .collect();
                let uploaded = match self.slots[slot].uploaded.take() {
                    Some(previous) => self.renderer.upload_into(&self.gpu, &frame, previous)?,
                    None => self.renderer.upload(&self.gpu, &frame)?,
                };
                self.slots[slot] = Slot {
                    uploaded: Some(uploaded),
                    identity: Some(identity),
                    parts: parts.clone(),
                };
                stats
            }
        };
        self.last_slot = slot;
        Ok(Staged {
            slot,
            stats,
            parts,
            upload_ms: gpu_start.elapsed().as_secs_f64() * 1e3,
            start,
            gpu_start,
        })
    }

    /// Whether the frames traced on the GPU time their stages by the device's timestamps
    /// ([`HybridStats::gpu_split_ms`](crate::hybrid::HybridStats::gpu_split_ms)); off by
    /// default, since the timestamps slow lavapipe's frames down.
    pub fn time_gpu_stages(&mut self, on: bool) {
        self.time_gpu_stages = on;
    }

    /// Makes `hybrid`'s geometry resident on the device for `options`' Fresnel model, GPU walk
    /// and precision: the copy kept from an earlier frame (the last one's, or the spare) when it
    /// is the same scene and settings, else uploaded now. An error when the device cannot take
    /// it (now or on an earlier try) or lacks what the walk or the precision needs.
    fn make_resident(
        &mut self,
        hybrid: &HybridScene,
        options: &HybridOptions,
    ) -> Result<(), RunError> {
        let fresnel = options.fresnel;
        let walk = options
            .traversal
            .resolve(&self.gpu)
            .map_err(|error| RunError::from(RenderError::from(error)))?;
        let walk = TracerWalk {
            traversal: walk,
            precision: options.gpu_precision,
        };
        let scene = hybrid.identity();
        let same = |t: &ResidentTracer| t.scene == scene && t.fresnel == fresnel;
        let matches =
            |t: &Option<ResidentTracer>| t.as_ref().is_some_and(|t| same(t) && t.walk == walk);
        if !matches(&self.tracer) && matches(&self.spare) {
            std::mem::swap(&mut self.tracer, &mut self.spare);
        }
        if !matches(&self.tracer) {
            // The old one's buffers go before the new ones are made, but for the same scene's,
            // kept as the spare.
            self.spare = self.tracer.take().filter(|t| same(t));
            let table = fresnel.table()?;
            let make = || GpuTracer::new(&self.gpu, hybrid.trace(), table.as_ref(), walk);
            let tracer = match make() {
                // Once more without the spare, should it hold the memory the new one needs.
                Err(_) if self.spare.take().is_some() => make(),
                made => made,
            }
            .map_err(Arc::new);
            self.tracer = Some(ResidentTracer {
                scene,
                fresnel,
                walk,
                tracer,
            });
        }
        if let Some(Ok(tracer)) = self.tracer.as_ref().map(|t| &t.tracer) {
            tracer.time_stages(self.time_gpu_stages);
        }
        match self.tracer.as_ref().map(|t| &t.tracer) {
            Some(Err(error)) => Err(RunError::Tracer(Arc::clone(error))),
            _ => Ok(()),
        }
    }

    /// Submits the frame that [`Self::stage`] put in `slot` (its stats `stats`): into `host`,
    /// or rendered for readback, composited as [`FrameOptions::compositing_for`] says.
    fn submit(
        &mut self,
        slot: usize,
        options: &FrameOptions,
        stats: &HybridStats,
        host: Option<&HostImage>,
    ) -> Result<Submission, RunError> {
        let compositing = self.compositing_for(options, stats);
        let Some(uploaded) = self.slots[slot].uploaded.as_mut() else {
            // A held identity is only ever that of an uploaded slot.
            return Err(RenderError::Internal("a still frame has no upload".into()).into());
        };
        let compositing = RenderOptions {
            host,
            compositing,
            ..options.compositing()
        };
        let submission = self.renderer.submit(&self.gpu, uploaded, &compositing)?;
        // A frame drawn where the GPU tessellation leaves it recorded the tracer's work: the
        // tracer keeps what that names until the frame is done.
        if !self.slots[slot].parts.is_empty()
            && let Some(ResidentTracer {
                tracer: Ok(tracer), ..
            }) = &self.tracer
        {
            tracer.used_until(self.renderer.timeline(), submission.value());
        }
        Ok(submission)
    }

    /// Waits for a submitted frame, reads it back and box-filters it to pixels.
    fn finish(&mut self, pending: Pending) -> Result<HybridFrame, RunError> {
        let Some(uploaded) = self.slots[pending.slot].uploaded.as_ref() else {
            return Err(RenderError::Internal("a pending frame lost its upload".into()).into());
        };
        let (image, render) = self.renderer.finish(uploaded, pending.submission)?;
        let mut stats = pending.stats;
        self.grew |= self.add_device_counts(&mut stats, &pending.parts)?;
        let downsample_start = Instant::now();
        let image = image.box_downsample(pending.supersampling);
        let downsample_ms = downsample_start.elapsed().as_secs_f64() * 1e3;
        Ok(HybridFrame {
            image,
            stats,
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
            runner.builder.forget();
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

    /// The compositor alone on an uploaded frame, drawn as `compositing` says: one warm-up
    /// render (its image is returned), then `timed` timed renders (at least one).
    pub fn timed_renders(
        &mut self,
        uploaded: &mut UploadedFrame,
        compositing: &RenderOptions,
        timed: usize,
    ) -> Result<TimedRenders, RenderError> {
        let (image, _) = self.renderer.render(&self.gpu, uploaded, compositing)?;
        let timings = (0..timed.max(1))
            .map(|_| {
                self.renderer
                    .render(&self.gpu, uploaded, compositing)
                    .map(|(_, timings)| timings)
            })
            .collect::<Result<_, _>>()?;
        Ok(TimedRenders { image, timings })
    }
}
