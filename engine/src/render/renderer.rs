//! The compositor on the GPU: [`Renderer::upload`] turns a [`FrameInput`] into buffers, images
//! and descriptor sets ([`super::upload`]); [`Renderer::render`] builds the frame's plan
//! ([`super::plan`]), records it into one command buffer ([`super::record`]: dynamic rendering,
//! synchronization2, a debug label around every pass), submits it and reads the colour target
//! back ([`super::image`]).

use std::time::Instant;

use ash::vk;

use super::{
    FrameInput, FramePlan, RenderError, RenderedImage, TargetFormat, Variant,
    image::decode,
    pipelines::Pipelines,
    plan::{FrameResources, frame_graph},
    record::Recorder,
    upload::{Targets, UploadCache, UploadedFrame},
};
use crate::gpu::{Gpu, GpuError};

/// Where one frame's time went, in milliseconds of wall time on the host.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTimings {
    /// Compiling the plan and recording the command buffer.
    pub record_ms: f64,
    /// Submission until the fence signals (on lavapipe: the rasterization itself).
    pub execute_ms: f64,
    /// Converting the read-back bytes to f32.
    pub readback_ms: f64,
}

/// Pipelines, layouts and the sampler shared by every frame, the uploads frames share, and the
/// command buffer frames are recorded into.
pub struct Renderer {
    pipelines: Pipelines,
    cache: UploadCache,
    command_buffer: vk::CommandBuffer,
}

impl Renderer {
    /// Creates the layouts and sampler; pipelines are created on first use.
    pub fn new(gpu: &Gpu) -> Result<Renderer, GpuError> {
        Ok(Renderer {
            pipelines: Pipelines::new(gpu)?,
            cache: UploadCache::default(),
            command_buffer: gpu.allocate_command_buffer()?,
        })
    }

    /// Validates and uploads a frame's data. Layered EMs and environment meshes already uploaded
    /// for one of the last two frames (the same `Arc`s) are reused.
    pub fn upload(&mut self, gpu: &Gpu, frame: &FrameInput) -> Result<UploadedFrame, RenderError> {
        self.cache.upload(gpu, &self.pipelines, frame)
    }

    /// Replaces the layered EMs of lens `lens` of an uploaded frame (one list per viewpoint, as
    /// many layers and the same face size as before), uploading only the maps.
    pub fn replace_layers(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        lens: usize,
        layers: &[Vec<std::sync::Arc<crate::cubemap::CubeMap>>],
    ) -> Result<(), RenderError> {
        self.cache
            .replace_layers(gpu, &self.pipelines, frame, lens, layers)
    }

    /// The plan a frame would record; an error where a lens object needs a program that does
    /// not exist (more layers than the single pass supports).
    pub fn plan(
        frame: &UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<FramePlan, RenderError> {
        Ok(Self::plan_with_resources(frame, variant, format)?.0)
    }

    /// The plan and the graph's handles of the frame's images.
    fn plan_with_resources(
        frame: &UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<(FramePlan, FrameResources), RenderError> {
        let (graph, resources) = frame_graph(frame.shape(), variant, format)?;
        // The frame graph is well-formed by construction (lens names are unique, checked by
        // FrameInput::validate); a failure here is a bug in plan.rs.
        let plan = graph.compile().expect("frame graphs always compile");
        Ok((plan, resources))
    }

    /// Renders the frame and reads it back.
    pub fn render(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<(RenderedImage, FrameTimings), RenderError> {
        let start = Instant::now();
        let (plan, resources) = Self::plan_with_resources(frame, variant, format)?;
        let (width, height) = (frame.shape().width, frame.shape().height);
        if let std::collections::hash_map::Entry::Vacant(slot) = frame.targets.entry(format) {
            slot.insert(Targets::new(gpu, format, width, height)?);
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
        let recorder = Recorder {
            gpu,
            pipelines: &self.pipelines,
            frame,
        };
        let mut record_ms = 0.0;
        let execute_start = std::cell::Cell::new(Instant::now());
        gpu.record_submit_wait(self.command_buffer, |cb| {
            recorder.record(cb, (&plan, &resources), format, &pipelines);
            record_ms = start.elapsed().as_secs_f64() * 1e3;
            execute_start.set(Instant::now());
            Ok(())
        })?;
        let execute_ms = execute_start.get().elapsed().as_secs_f64() * 1e3;
        let decode_start = Instant::now();
        let targets = &frame.targets[&format];
        let pixels = decode(targets.readback.read(), format, (width * height) as usize);
        let readback_ms = decode_start.elapsed().as_secs_f64() * 1e3;
        Ok((
            RenderedImage {
                width,
                height,
                pixels,
            },
            FrameTimings {
                record_ms,
                execute_ms,
                readback_ms,
            },
        ))
    }
}
