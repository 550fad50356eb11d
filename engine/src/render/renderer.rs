//! The compositor on the GPU: [`Renderer::upload`] turns a [`FrameInput`] into buffers, images
//! and descriptor sets ([`super::upload`]); [`Renderer::render`] builds the frame's plan
//! ([`super::plan`]), records it into one command buffer ([`super::record`]: dynamic rendering,
//! synchronization2, a debug label around every pass), submits it and reads the colour target
//! back ([`super::image`]).

use std::{sync::Arc, time::Instant};

use ash::vk;

use super::compute::ComputeCommands;
use super::{
    FrameInput, FramePlan, HostImage, RenderError, RenderedImage, TargetFormat,
    image::decode,
    pipelines::Pipelines,
    plan::{Compositing, FrameResources, FrameShape, Output, PlanOptions, frame_graph},
    record::Recorder,
    targets::Targets,
    upload::{UploadCache, UploadedFrame},
};
use crate::gpu::{Gpu, GpuError, Semaphores, Timeline};
use crate::index::LensIndex;

/// Frames that may be recorded and executing at once: the CPU prepares frame N + 1 while the GPU
/// renders frame N.
pub const FRAMES_IN_FLIGHT: usize = 2;

/// Where one frame's time went, in milliseconds of wall time on the host.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTimings {
    /// Compiling the plan and recording the command buffer.
    pub record_ms: f64,
    /// Submission until the fence signals (on lavapipe: the rasterization itself).
    pub execute_ms: f64,
    /// Converting the read-back bytes to f32.
    pub readback_ms: f64,
    /// Passes the frame recorded (the plan's steps: environment, prime, layer passes, alpha
    /// clears or single passes, the readback; not its GPU tessellations' passes).
    pub passes: usize,
    /// Compute commands the frame recorded: the tessellations of its resident lens parts, each
    /// a pass of its plan.
    pub compute: ComputeCommands,
    /// Channel values of an RGBA16F framebuffer that overflowed (±Inf) and were clamped to
    /// ±65504 on readback (0 for other formats, and for frames into a host's image, whose box
    /// filter clamps them on the GPU).
    pub saturated: usize,
}

/// How [`Renderer::render`], [`Renderer::submit`] and [`Renderer::plan`] composite a frame and
/// where its pixels go. The default is the runner's (`runner::FrameOptions`): the single pass
/// into RGBA16F, read back.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions<'a> {
    /// How lens objects are composited: the single pass, or the multipass variant and its
    /// blending scheme.
    pub compositing: Compositing,
    /// The framebuffer's format.
    pub format: TargetFormat,
    /// A host's image to box-filter the frame into on the GPU, or `None` to read the
    /// framebuffer back.
    pub host: Option<&'a HostImage>,
}

impl Default for RenderOptions<'_> {
    fn default() -> Self {
        RenderOptions {
            compositing: Compositing::SinglePass,
            format: TargetFormat::Rgba16f,
            host: None,
        }
    }
}

/// Pipelines, layouts and the sampler shared by every frame, the uploads frames share, the
/// command buffers frames are recorded into (one per frame in flight) and the timeline semaphore
/// that says which submissions completed.
pub struct Renderer {
    pipelines: Pipelines,
    cache: UploadCache,
    /// `(command buffer, timeline value of its last submission)`, used round robin.
    command_buffers: Vec<(vk::CommandBuffer, u64)>,
    timeline: Arc<Timeline>,
    /// The value the last submission signals.
    submitted: u64,
    /// The last frames' plans: a stream of frames of one shape compiles its plan once.
    plans: Plans,
}

/// Compiled plans by what they depend on (a frame's shape and its plan's options), the most
/// recent first: a few, so that frames alternating between two options (a benchmark's, a
/// viewer's toggle) keep both.
#[derive(Default)]
struct Plans {
    recent: std::collections::VecDeque<(FrameShape, PlanOptions, Arc<CompiledPlan>)>,
}

/// A frame's plan and the graph's handles of its images.
struct CompiledPlan {
    plan: FramePlan,
    resources: FrameResources,
}

impl Plans {
    /// Plans kept.
    const KEPT: usize = 4;

    /// The plan of `shape` with `options`, compiled where no recent frame had it.
    fn get(
        &mut self,
        shape: &FrameShape,
        options: &PlanOptions,
    ) -> Result<Arc<CompiledPlan>, RenderError> {
        let at = self
            .recent
            .iter()
            .position(|(s, o, _)| o == options && s.plans_alike(shape));
        if let Some(entry) = at.and_then(|at| self.recent.remove(at)) {
            let plan = entry.2.clone();
            self.recent.push_front(entry);
            return Ok(plan);
        }
        let plan = Arc::new(compile(shape, options)?);
        self.recent.truncate(Self::KEPT - 1);
        self.recent
            .push_front((shape.clone(), *options, plan.clone()));
        Ok(plan)
    }
}

/// Compiles the plan of `shape` with `options`.
fn compile(shape: &FrameShape, options: &PlanOptions) -> Result<CompiledPlan, RenderError> {
    let (graph, resources) = frame_graph(shape, options)?;
    // The frame graph is well-formed by construction (lens names are unique, checked by
    // FrameInput::validate); a failure here is a bug in plan/.
    let plan = graph.compile().expect("frame graphs always compile");
    Ok(CompiledPlan { plan, resources })
}

/// A frame submitted by [`Renderer::submit`] and not yet waited for: hand it to
/// [`Renderer::finish`] with the same uploaded frame.
#[must_use = "a submitted frame is waited for and read back by Renderer::finish"]
#[derive(Debug)]
pub struct Submission {
    value: u64,
    /// False for a frame rendered into a host's image: nothing to read back.
    readback: bool,
    format: TargetFormat,
    passes: usize,
    compute: ComputeCommands,
    record_ms: f64,
    submitted_at: Instant,
}

impl Submission {
    /// Passes the frame recorded.
    pub fn passes(&self) -> usize {
        self.passes
    }

    /// Compiling the plan and recording the command buffer, ms.
    pub fn record_ms(&self) -> f64 {
        self.record_ms
    }

    /// The renderer's timeline value its completion signals ([`Renderer::completed`]).
    pub fn value(&self) -> u64 {
        self.value
    }
}

impl Renderer {
    /// Creates the layouts and sampler; pipelines are created on first use.
    pub fn new(gpu: &Gpu) -> Result<Renderer, GpuError> {
        let command_buffers = (0..FRAMES_IN_FLIGHT)
            .map(|_| gpu.allocate_command_buffer().map(|cb| (cb, 0)))
            .collect::<Result<_, _>>()?;
        Ok(Renderer {
            pipelines: Pipelines::new(gpu)?,
            cache: UploadCache::default(),
            command_buffers,
            timeline: Arc::new(Timeline::new(gpu)?),
            submitted: 0,
            plans: Plans::default(),
        })
    }

    /// Validates and uploads a frame's data. Layered EMs and environment meshes already uploaded
    /// for one of the last two frames (the same `Arc`s) are reused.
    pub fn upload(&mut self, gpu: &Gpu, frame: &FrameInput) -> Result<UploadedFrame, RenderError> {
        self.cache.upload(gpu, &self.pipelines, frame, None)
    }

    /// [`Renderer::upload`] into the buffers, descriptor pool and targets of `previous` (after
    /// waiting for its last submission): what a stream of frames does to allocate nothing.
    pub fn upload_into(
        &mut self,
        gpu: &Gpu,
        frame: &FrameInput,
        previous: UploadedFrame,
    ) -> Result<UploadedFrame, RenderError> {
        self.cache
            .upload(gpu, &self.pipelines, frame, Some(previous))
    }

    /// Replaces the layered EMs of lens `lens` of an uploaded frame (one list per viewpoint, as
    /// many layers and the same face size as before), uploading only the maps.
    pub fn replace_layers(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        lens: LensIndex,
        layers: &[Vec<std::sync::Arc<crate::cubemap::CubeMap>>],
    ) -> Result<(), RenderError> {
        self.cache
            .replace_layers(gpu, &self.pipelines, frame, lens, layers)
    }

    /// The plan [`Renderer::submit`] records for `frame` with `options`; an error where a lens
    /// object needs a program that does not exist (more layers than the single pass supports).
    pub fn plan(frame: &UploadedFrame, options: &RenderOptions) -> Result<FramePlan, RenderError> {
        Ok(compile(frame.shape(), &Self::plan_options(frame, options)?)?.plan)
    }

    /// The options of `frame`'s plan with `options`.
    fn plan_options(
        frame: &UploadedFrame,
        options: &RenderOptions,
    ) -> Result<PlanOptions, RenderError> {
        let (width, height) = (frame.shape().width, frame.shape().height);
        let output = match options.host {
            Some(image) => image.output(width, height)?,
            None => Output::Readback,
        };
        Ok(PlanOptions {
            compositing: options.compositing,
            format: options.format,
            output,
            single_pass: frame.single_pass,
        })
    }

    /// Renders the frame and reads it back: [`Renderer::submit`], then [`Renderer::finish`].
    pub fn render(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        options: &RenderOptions,
    ) -> Result<(RenderedImage, FrameTimings), RenderError> {
        let submission = self.submit(gpu, frame, options)?;
        self.finish(frame, submission)
    }

    /// The timeline its submissions signal (a [`Submission::value`] on it).
    pub fn timeline(&self) -> Arc<Timeline> {
        self.timeline.clone()
    }

    /// Whether the submission whose [`Submission::value`] is `value` completed, without
    /// waiting (an error reading the timeline counts as not completed).
    pub fn completed(&self, value: u64) -> bool {
        self.timeline.reached(value).unwrap_or(false)
    }

    /// Records the frame's plan and submits it without waiting. Without a host image the plan
    /// ends in the readback copy; with one (on this device, its size the frame's divided by the
    /// supersampling factor) the frame is box-filtered into it on the GPU, with the host's
    /// semaphores on the submission and no readback, and is complete when its `signal`
    /// semaphores are (or [`Renderer::finish`] returns, which also waits). At most
    /// [`FRAMES_IN_FLIGHT`] frames execute at once: a command buffer is reused only after its
    /// previous submission completed.
    pub fn submit(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        options: &RenderOptions,
    ) -> Result<Submission, RenderError> {
        let start = Instant::now();
        let RenderOptions { format, host, .. } = *options;
        let (width, height) = (frame.shape().width, frame.shape().height);
        let compiled = self
            .plans
            .get(frame.shape(), &Self::plan_options(frame, options)?)?;
        let CompiledPlan { plan, resources } = &*compiled;
        if let std::collections::hash_map::Entry::Vacant(slot) = frame.targets.entry(format) {
            slot.insert(Targets::new(gpu, &self.pipelines, format, width, height)?);
        }
        // One pipeline per step (None for a readback), derived from the step's declaration.
        let mut pipelines = Vec::with_capacity(plan.steps.len());
        for step in &plan.steps {
            if let Some(key) = step.pass.pipeline_key(&plan.images) {
                pipelines.push(Some(self.pipelines.get(gpu, key)?));
            } else {
                pipelines.push(None);
            }
        }
        // The frame's own previous submission wrote its targets: wait for it (a no-op when the
        // caller alternates frames, as a stream with frames in flight does).
        if let Some((timeline, value)) = &frame.last_submission {
            timeline.wait(*value)?;
        }
        if let Some(targets) = frame.targets.get_mut(&format) {
            let needed = resources.scratch.len();
            if needed > 0 {
                super::budget::check_scratch_budget(gpu, width, height, format, needed)?;
            }
            targets.ensure_scratch(gpu, &self.pipelines, needed)?;
        }
        let slot = (self.submitted as usize) % self.command_buffers.len();
        let (command_buffer, last) = self.command_buffers[slot];
        self.timeline.wait(last)?;
        let value = self.submitted + 1;
        let recorder = Recorder {
            gpu,
            pipelines: &self.pipelines,
            frame,
            host,
        };
        let mut record_ms = 0.0;
        let mut compute = ComputeCommands::default();
        let (waits, signals) = host.map_or((&[][..], &[][..]), |h| (&h.wait[..], &h.signal[..]));
        gpu.record_submit(
            command_buffer,
            |cb| {
                compute = recorder.record(cb, plan, resources, format, &pipelines);
                record_ms = start.elapsed().as_secs_f64() * 1e3;
                Ok(())
            },
            Semaphores {
                timeline: &self.timeline,
                value,
                waits,
                signals,
            },
        )?;
        self.submitted = value;
        self.command_buffers[slot].1 = value;
        frame.last_submission = Some((self.timeline.clone(), value));
        // The compute work that makes resident lens parts runs once: a frame drawn again draws
        // what it made.
        for part in frame.shape.lenses.iter_mut().flat_map(|l| &mut l.parts) {
            part.work = None;
        }
        for work in frame.lenses.iter().flat_map(|lens| &lens.works) {
            work.submitted();
        }
        Ok(Submission {
            value,
            readback: host.is_none(),
            format,
            // The GPU tessellations' passes are counted as their commands (`compute`).
            passes: plan
                .steps
                .iter()
                .filter(|s| {
                    !matches!(
                        s.pass.kind,
                        crate::graph::PassKind::Compute { .. }
                            | crate::graph::PassKind::HostRead { .. }
                    )
                })
                .count(),
            compute,
            record_ms,
            submitted_at: Instant::now(),
        })
    }

    /// Waits for a submitted frame and reads its colour target back (a frame rendered into a
    /// host's image has nothing to read: its image here is empty, 0×0).
    pub fn finish(
        &self,
        frame: &UploadedFrame,
        submission: Submission,
    ) -> Result<(RenderedImage, FrameTimings), RenderError> {
        // Only the frame's latest submission's readback is there to read: a later one reuses
        // the same buffer.
        if frame.last_submission.as_ref().map(|(_, v)| *v) != Some(submission.value) {
            return Err(RenderError::BadInput(
                "finish() was given a submission this frame has since been submitted again over; finish each submission before submitting the frame again".into(),
            ));
        }
        self.timeline.wait(submission.value)?;
        let execute_ms = submission.submitted_at.elapsed().as_secs_f64() * 1e3;
        if !submission.readback {
            return Ok((
                RenderedImage {
                    width: 0,
                    height: 0,
                    pixels: Vec::new(),
                },
                FrameTimings {
                    record_ms: submission.record_ms,
                    execute_ms,
                    readback_ms: 0.0,
                    passes: submission.passes,
                    compute: submission.compute,
                    saturated: 0,
                },
            ));
        }
        let decode_start = Instant::now();
        let (width, height) = (frame.shape().width, frame.shape().height);
        let Some(targets) = frame.targets.get(&submission.format) else {
            return Err(RenderError::BadInput(
                "finish() was given another frame than the one submitted".into(),
            ));
        };
        let (pixels, saturated) = decode(
            targets.readback.read(),
            submission.format,
            (width * height) as usize,
        );
        let readback_ms = decode_start.elapsed().as_secs_f64() * 1e3;
        Ok((
            RenderedImage {
                width,
                height,
                pixels,
            },
            FrameTimings {
                record_ms: submission.record_ms,
                execute_ms,
                readback_ms,
                passes: submission.passes,
                compute: submission.compute,
                saturated,
            },
        ))
    }
}
