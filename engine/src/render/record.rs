//! Recording a compiled frame plan into a command buffer: barriers from the plan, dynamic
//! rendering instances, a debug label around every pass, draws with their push constants
//! (the structs `shaders/build.rs` generated from the WGSL), and the readback copy or the box
//! filter into a host's image.

use ash::vk;
use bytemuck::Zeroable;
use lensmap_shaders::{EnvironmentConstants, GroupSumConstants, LensConstants, ResolveConstants};

use super::compute::ComputeCommands;
use super::{
    HostImage, INDIRECT_ALL, INDIRECT_HULL, INDIRECT_REST, TargetFormat,
    pipelines::Pipelines,
    plan::{Draw, FramePlan, FrameResources},
    targets::Targets,
    upload::{GpuLens, LensPart, PartBuffers, UploadedFrame},
    vulkan::{vk_access, vk_layout},
};
use crate::gpu::copies;
use crate::{
    gpu::Gpu,
    graph::{self, Barrier, Layout, LoadOp, PassKind, RenderingInstance, StoreOp},
    index::{LayerIndex, LensIndex},
    trace::Term,
};

/// How many indices a lens part's draw takes: (non-hull, hull) from the host, or the GPU's
/// indirect arguments.
enum DrawCounts<'a> {
    Direct(u32, u32),
    Indirect(&'a crate::gpu::Buffer),
}

/// What recording one frame reads.
pub(super) struct Recorder<'a> {
    /// The device (labels, commands).
    pub(super) gpu: &'a Gpu,
    /// Layouts the draws bind against.
    pub(super) pipelines: &'a Pipelines,
    /// The uploaded frame.
    pub(super) frame: &'a UploadedFrame,
    /// The host's image, for a plan with an external image.
    pub(super) host: Option<&'a HostImage>,
}

/// The frame's Vulkan images behind the plan's image handles.
struct FrameImages<'a> {
    frame: &'a UploadedFrame,
    resources: &'a FrameResources,
    targets: &'a Targets,
    /// The host's image, when the plan has an external image.
    host: Option<&'a HostImage>,
}

impl FrameImages<'_> {
    /// The Vulkan image of `id` and the subresources its barriers cover: every level and layer
    /// of lensmap's own images (one layer of the scratch array for a scratch image), the one
    /// level and layer of a host image that its view shows. Imported cube arrays never need
    /// barriers within a frame (uploads leave them SHADER_READ_ONLY), but are mapped all the
    /// same.
    fn image(&self, id: graph::ImageId) -> (vk::Image, vk::ImageSubresourceRange) {
        let all = |aspect_mask, layer_count| vk::ImageSubresourceRange {
            aspect_mask,
            base_mip_level: 0,
            level_count: vk::REMAINING_MIP_LEVELS,
            base_array_layer: 0,
            layer_count,
        };
        if let (Some(host), true) = (self.host, Some(id) == self.resources.external) {
            let range = vk::ImageSubresourceRange {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                base_mip_level: host.mip_level,
                level_count: 1,
                base_array_layer: host.array_layer,
                layer_count: 1,
            };
            return (host.image, range);
        }
        if id == self.resources.colour {
            return (
                self.targets.colour.handle,
                all(vk::ImageAspectFlags::COLOR, 1),
            );
        }
        if id == self.resources.depth {
            return (
                self.targets.depth.handle,
                all(vk::ImageAspectFlags::DEPTH, 1),
            );
        }
        if let (Some(k), Some(scratch)) = (self.scratch_index(id), self.targets.scratch.as_ref()) {
            let range = vk::ImageSubresourceRange {
                base_array_layer: k as u32,
                ..all(vk::ImageAspectFlags::COLOR, 1)
            };
            return (scratch.image.handle, range);
        }
        self.resources
            .layers
            .iter()
            .zip(&self.frame.lenses)
            .flat_map(|(ids, lens)| ids.iter().zip(&lens.layers))
            .find(|(layer_id, _)| **layer_id == id)
            .map_or(
                (vk::Image::null(), all(vk::ImageAspectFlags::COLOR, 1)),
                |(_, image)| {
                    (
                        image.handle,
                        all(vk::ImageAspectFlags::COLOR, image.desc.array_layers),
                    )
                },
            )
    }

    /// The position of `id` among the scratch images.
    fn scratch_index(&self, id: graph::ImageId) -> Option<usize> {
        self.resources.scratch.iter().position(|s| *s == id)
    }

    /// The Vulkan layout of a barrier's `old_layout`: the host's layout before the frame stands
    /// in for the graph's External.
    fn layout_before(&self, layout: Layout) -> vk::ImageLayout {
        match (layout, self.host) {
            (Layout::External, Some(host)) => host.current_layout,
            _ => vk_layout(layout),
        }
    }

    /// The Vulkan layout of a barrier's `new_layout`: the layout the host wants after the frame
    /// stands in for the graph's External.
    fn layout_after(&self, layout: Layout) -> vk::ImageLayout {
        match (layout, self.host) {
            (Layout::External, Some(host)) => host.final_layout,
            _ => vk_layout(layout),
        }
    }

    /// The view and extent of a colour attachment: the framebuffer's (or a scratch image's,
    /// the framebuffer's size), or the host's image (the framebuffer's size over the
    /// supersampling factor).
    fn attachment(&self, id: graph::ImageId) -> (vk::ImageView, u32, u32) {
        if let Some(host) = self.host.filter(|_| Some(id) == self.resources.external) {
            return (host.view, host.width, host.height);
        }
        let scratch_view = self.scratch_index(id).map(|k| {
            let view = self
                .targets
                .scratch
                .as_ref()
                .and_then(|scratch| scratch.image.layer_views.get(k).copied());
            debug_assert!(view.is_some(), "scratch image {k} was not made");
            view.unwrap_or(self.targets.colour.view)
        });
        let shape = &self.frame.shape;
        (
            scratch_view.unwrap_or(self.targets.colour.view),
            shape.width,
            shape.height,
        )
    }
}

impl Recorder<'_> {
    /// Records `plan` into `cb`: per step its barriers, the rendering instance it begins, a debug
    /// label, its draws or its copy, the end of its instance. `pipelines` holds each step's
    /// pipeline (`None` for a readback). Returns the compute commands it recorded.
    pub(super) fn record(
        &self,
        cb: vk::CommandBuffer,
        plan: &FramePlan,
        resources: &FrameResources,
        format: TargetFormat,
        pipelines: &[Option<vk::Pipeline>],
    ) -> ComputeCommands {
        let mut recorded = ComputeCommands::default();
        let (gpu, frame) = (self.gpu, self.frame);
        let targets = &frame.targets[&format];
        let images = FrameImages {
            frame,
            resources,
            targets,
            host: self.host.filter(|_| resources.external.is_some()),
        };
        for (step, pipeline) in plan.steps.iter().zip(pipelines) {
            self.barriers(cb, &images, &step.barriers);
            let accesses = step.buffer_barriers.iter().map(|b| (b.src, b.dst));
            super::compute::memory_barriers(gpu, cb, accesses);
            if let Some(instance) = &step.begin {
                self.begin_rendering(cb, &images, instance);
            }
            gpu.begin_label(cb, &step.pass.name);
            match &step.pass.kind {
                PassKind::Draw { draws, .. } => {
                    // Every draw pass has a pipeline (pipeline_key is Some for draws).
                    if let Some(pipeline) = *pipeline {
                        // SAFETY: recording inside a rendering instance with a compatible pipeline.
                        unsafe {
                            gpu.device().cmd_bind_pipeline(
                                cb,
                                vk::PipelineBindPoint::GRAPHICS,
                                pipeline,
                            )
                        };
                        for draw in draws {
                            self.record_draw(cb, *draw, targets);
                        }
                    }
                }
                PassKind::Compute { dispatches, .. } => {
                    for dispatch in dispatches {
                        self.compute(cb, *dispatch, &mut recorded);
                    }
                }
                PassKind::Readback { .. } => self.copy_to_readback(cb, targets),
                // The hand-back, and the host's read, are this step's barriers: no command.
                PassKind::Export { .. } | PassKind::HostRead { .. } => {}
            }
            gpu.end_label(cb);
            if step.end {
                // SAFETY: closes the instance begun by this run's first step.
                unsafe { gpu.device().cmd_end_rendering(cb) };
            }
        }
        recorded
    }

    /// Records a step's barriers (nothing for none).
    fn barriers(&self, cb: vk::CommandBuffer, images: &FrameImages, barriers: &[Barrier]) {
        if barriers.is_empty() {
            return;
        }
        let barriers: Vec<vk::ImageMemoryBarrier2> = barriers
            .iter()
            .map(|b| {
                let (image, range) = images.image(b.image);
                let (src_stage, src_access) = vk_access(b.src);
                let (dst_stage, dst_access) = vk_access(b.dst);
                vk::ImageMemoryBarrier2::default()
                    .src_stage_mask(src_stage)
                    .src_access_mask(src_access)
                    .dst_stage_mask(dst_stage)
                    .dst_access_mask(dst_access)
                    .old_layout(images.layout_before(b.old_layout))
                    .new_layout(images.layout_after(b.new_layout))
                    .image(image)
                    .subresource_range(range)
            })
            .collect();
        // SAFETY: recording; the barriers describe images alive for the submission.
        unsafe {
            self.gpu.device().cmd_pipeline_barrier2(
                cb,
                &vk::DependencyInfo::default().image_memory_barriers(&barriers),
            )
        };
    }

    /// Begins a rendering instance on its attachments, with a viewport and scissor covering the
    /// colour attachment.
    fn begin_rendering(
        &self,
        cb: vk::CommandBuffer,
        images: &FrameImages,
        instance: &RenderingInstance,
    ) {
        let load_op = |load: LoadOp| match load {
            LoadOp::Clear(c) => (vk::AttachmentLoadOp::CLEAR, c),
            LoadOp::Load => (vk::AttachmentLoadOp::LOAD, [0.0; 4]),
            LoadOp::DontCare => (vk::AttachmentLoadOp::DONT_CARE, [0.0; 4]),
        };
        let store_op = |s: StoreOp| match s {
            StoreOp::Store => vk::AttachmentStoreOp::STORE,
            StoreOp::DontCare => vk::AttachmentStoreOp::DONT_CARE,
        };
        let (colour_load, colour_clear) = load_op(instance.colour.1);
        let (view, width, height) = images.attachment(instance.colour.0);
        let colour = [vk::RenderingAttachmentInfo::default()
            .image_view(view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(colour_load)
            .store_op(store_op(instance.colour.2))
            .clear_value(vk::ClearValue {
                color: vk::ClearColorValue {
                    float32: colour_clear,
                },
            })];
        let depth = instance.depth.map(|(_, load, store)| {
            let (depth_load, depth_clear) = load_op(load);
            vk::RenderingAttachmentInfo::default()
                .image_view(images.targets.depth.view)
                .image_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL)
                .load_op(depth_load)
                .store_op(store_op(store))
                .clear_value(vk::ClearValue {
                    depth_stencil: vk::ClearDepthStencilValue {
                        depth: depth_clear[0],
                        stencil: 0,
                    },
                })
        });
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: width as f32,
            height: height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        let scissor = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D { width, height },
        };
        let mut rendering = vk::RenderingInfo::default()
            .render_area(scissor)
            .layer_count(1)
            .color_attachments(&colour);
        if let Some(depth) = depth.as_ref() {
            rendering = rendering.depth_attachment(depth);
        }
        let device = self.gpu.device();
        // SAFETY: recording; attachments are in the layouts the plan's barriers set.
        unsafe {
            device.cmd_begin_rendering(cb, &rendering);
            device.cmd_set_viewport(cb, 0, &[viewport]);
            device.cmd_set_scissor(cb, 0, &[scissor]);
        }
    }

    /// The copy of the colour target into the readback buffer, made visible to the host.
    fn copy_to_readback(&self, cb: vk::CommandBuffer, targets: &Targets) {
        let shape = &self.frame.shape;
        let device = self.gpu.device();
        // SAFETY: the colour target is TRANSFER_SRC after this step's barrier; the readback
        // buffer holds a frame of its format; both live as long as the frame.
        unsafe {
            copies::copy_image_to_buffer(
                device,
                cb,
                targets.colour.handle,
                targets.readback.handle,
                shape.width,
                shape.height,
            );
            copies::host_reads_transfers(device, cb);
        }
    }

    /// Records one pass of a compute work (a resident lens part's tessellation).
    fn compute(&self, cb: vk::CommandBuffer, dispatch: Draw, recorded: &mut ComputeCommands) {
        let Draw::Compute { lens, part, pass } = dispatch else {
            debug_assert!(false, "not a compute dispatch: {dispatch:?}");
            return;
        };
        if let Some(work) = self
            .frame
            .lenses
            .get(lens.index())
            .and_then(|l| l.works.get(part))
        {
            super::compute::record(self.gpu, cb, work, pass, recorded);
        }
    }

    /// Records one draw with its push constants and descriptor sets; the pipeline is bound.
    /// `targets` are the framebuffer's (the box filter reads their colour, the group sum and
    /// the programmable layer their scratch images).
    fn record_draw(&self, cb: vk::CommandBuffer, draw: Draw, targets: &Targets) {
        match draw {
            Draw::BoxFilter {
                supersampling,
                half,
            } => {
                let k = supersampling.max(1);
                // The CPU filter's scale, computed the same way (RenderedImage::box_downsample),
                // and the readback's clamp of overflowed RGBA16F texels.
                let constants = ResolveConstants {
                    supersampling: k,
                    scale: 1.0 / (k * k) as f32,
                    limit: if half {
                        super::image::HALF_MAX
                    } else {
                        f32::INFINITY
                    },
                };
                self.full_screen(
                    cb,
                    self.pipelines.box_filter_layout,
                    targets.box_filter_set,
                    bytemuck::bytes_of(&constants),
                );
            }
            Draw::GroupSum { groups } => {
                // The renderer made the scratch images the plan names before recording.
                let Some(set) = targets
                    .scratch
                    .as_ref()
                    .and_then(|s| s.prefix_sets.get((groups as usize).checked_sub(1)?))
                else {
                    debug_assert!(false, "a group sum without its scratch images");
                    return;
                };
                self.full_screen(
                    cb,
                    self.pipelines.group_sum_layout,
                    *set,
                    bytemuck::bytes_of(&GroupSumConstants { groups }),
                );
            }
            Draw::Environment { mesh } => self.environment(cb, mesh),
            Draw::Glossy { index } => self.glossy(cb, index),
            Draw::LensZero { lens }
            | Draw::SinglePass { lens }
            | Draw::Layer { lens, .. }
            | Draw::ProgrammableLayer { lens, .. } => self.lens(cb, draw, lens, targets),
            Draw::Compute { .. } => debug_assert!(false, "a compute dispatch in a draw pass"),
        }
    }

    /// A full-screen triangle with `set` bound as set 0 of `layout` and `constants` pushed to
    /// the fragment stage.
    fn full_screen(
        &self,
        cb: vk::CommandBuffer,
        layout: vk::PipelineLayout,
        set: vk::DescriptorSet,
        constants: &[u8],
    ) {
        self.bind(
            cb,
            layout,
            &[set],
            vk::ShaderStageFlags::FRAGMENT,
            constants,
        );
        // SAFETY: recording inside a rendering instance with the matching pipeline bound.
        unsafe { self.gpu.device().cmd_draw(cb, 3, 1, 0, 0) };
    }

    /// Binds `sets` as sets 0.. of `layout` and pushes `constants` to `stages`.
    fn bind(
        &self,
        cb: vk::CommandBuffer,
        layout: vk::PipelineLayout,
        sets: &[vk::DescriptorSet],
        stages: vk::ShaderStageFlags,
        constants: &[u8],
    ) {
        let device = self.gpu.device();
        // SAFETY: recording with a pipeline of `layout` bound; the sets live as long as the
        // frame and its targets.
        unsafe {
            device.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::GRAPHICS,
                layout,
                0,
                sets,
                &[],
            );
            device.cmd_push_constants(cb, layout, stages, 0, constants);
        }
    }

    /// Environment mesh `mesh`: its light-map set, vertex and index buffers.
    fn environment(&self, cb: vk::CommandBuffer, mesh: usize) {
        let (device, frame) = (self.gpu.device(), self.frame);
        let mesh = &frame.environment[mesh];
        let constants = EnvironmentConstants {
            view_proj: frame.view_proj,
        };
        self.bind(
            cb,
            self.pipelines.environment_layout,
            &[mesh.set],
            vk::ShaderStageFlags::VERTEX,
            bytemuck::bytes_of(&constants),
        );
        // SAFETY: recording inside a rendering instance with the environment pipeline bound;
        // the buffers live as long as `frame`.
        unsafe {
            device.cmd_bind_vertex_buffers(
                cb,
                0,
                &[mesh.positions.handle, mesh.colours.handle, mesh.uvs.handle],
                &[0, 0, 0],
            );
            device.cmd_bind_index_buffer(cb, mesh.indices.handle, 0, vk::IndexType::UINT32);
            device.cmd_draw_indexed(cb, mesh.index_count, 1, 0, 0, 0);
        }
    }

    /// Glossy object `index`: its set (data, maps, sampler), vertex and index buffers.
    fn glossy(&self, cb: vk::CommandBuffer, index: usize) {
        let (device, frame) = (self.gpu.device(), self.frame);
        let glossy = &frame.glossy[index];
        let mesh = &glossy.mesh;
        // SAFETY: recording inside a rendering instance with the glossy pipeline bound; the set
        // and buffers live as long as `frame`.
        unsafe {
            device.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::GRAPHICS,
                self.pipelines.glossy_layout,
                0,
                &[glossy.set],
                &[],
            );
            device.cmd_bind_vertex_buffers(
                cb,
                0,
                &[mesh.positions.handle, mesh.normals.handle],
                &[0, 0],
            );
            device.cmd_bind_index_buffer(cb, mesh.indices.handle, 0, vk::IndexType::UINT32);
            device.cmd_draw_indexed(cb, mesh.index_count, 1, 0, 0, 0);
        }
    }

    /// One draw of lens object `lens` (the prime or alpha clear, a layer, a programmable layer,
    /// the single pass): per part, its descriptor sets and push constants, then its triangles.
    fn lens(&self, cb: vk::CommandBuffer, draw: Draw, lens: LensIndex, targets: &Targets) {
        let gpu_lens = &self.frame.lenses[lens.index()];
        for part in &gpu_lens.parts {
            self.lens_part(cb, draw, gpu_lens, part, targets);
        }
    }

    /// [`Self::lens`] for one part of the lens object.
    fn lens_part(
        &self,
        cb: vk::CommandBuffer,
        draw: Draw,
        gpu_lens: &GpuLens,
        part: &LensPart,
        targets: &Targets,
    ) {
        let mut constants = self.lens_constants(gpu_lens, part.stride);
        let weight = |v: usize| self.viewpoint_weight(v);
        // One layer of one (viewpoint, term) group: its weight, F·G and directions.
        let mut one_layer = |viewpoint: usize, term: Term, layer: LayerIndex| {
            let layer = layer.index() as u32;
            let (fg, directions) = gpu_lens.offsets(term, part.stride).unwrap_or((0, 0));
            constants.weight_a = weight(viewpoint);
            constants.fg_offset_t = fg;
            constants.direction_offset_t = directions + layer * part.stride;
            constants.layer = layer;
            part.sets[viewpoint]
        };
        // The convex-hull split: the draws that sample layer 0 draw the hull triangles (the
        // last indices) apart, with that layer taken as empty.
        let samples_local = match draw {
            Draw::Layer { layer, .. } | Draw::ProgrammableLayer { layer, .. } => layer.index() == 0,
            Draw::SinglePass { .. } => true,
            _ => false,
        };
        // Set 0, and set 1 for the programmable layer (no allocation per draw).
        let (layout, sets, set_count) = match draw {
            Draw::Layer {
                viewpoint,
                term,
                layer,
                ..
            } => (
                self.pipelines.lens_layout,
                [one_layer(viewpoint, term, layer), vk::DescriptorSet::null()],
                1,
            ),
            Draw::ProgrammableLayer {
                viewpoint,
                term,
                layer,
                read,
                reset_alpha,
                ..
            } => {
                let Some(scratch) = &targets.scratch else {
                    debug_assert!(false, "a programmable layer without its scratch");
                    return;
                };
                let set = one_layer(viewpoint, term, layer);
                constants.read_current = 1;
                constants.reset_alpha = u32::from(reset_alpha);
                (
                    self.pipelines.programmable_layout,
                    [set, scratch.layer_sets[read as usize]],
                    2,
                )
            }
            Draw::SinglePass { .. } => {
                // The single pass blends the viewpoints with weight > 0 in order, as the plan's
                // specialization counts them and its set binds their arrays: binding 1 and
                // weight_a are the first active viewpoint's, then b, then c.
                let mut active = (0..part.sets.len()).map(weight).filter(|&w| w > 0.0);
                constants.weight_a = active.next().unwrap_or(0.0);
                constants.weight_b = active.next().unwrap_or(0.0);
                constants.weight_c = active.next().unwrap_or(0.0);
                (
                    self.pipelines.lens_layout,
                    [part.single_pass_set, vk::DescriptorSet::null()],
                    1,
                )
            }
            Draw::LensZero { .. } => (
                self.pipelines.lens_layout,
                [part.single_pass_set, vk::DescriptorSet::null()],
                1,
            ),
            Draw::Environment { .. }
            | Draw::Glossy { .. }
            | Draw::GroupSum { .. }
            | Draw::BoxFilter { .. }
            | Draw::Compute { .. } => {
                debug_assert!(false, "not a lens draw: {draw:?}");
                return;
            }
        };
        self.bind(
            cb,
            layout,
            &sets[..set_count],
            vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
            bytemuck::bytes_of(&constants),
        );
        let device = self.gpu.device();
        let (indices, counts) = match &part.buffers {
            PartBuffers::Host(host) => {
                let hull = host.hull_index_count.min(host.index_count) * u32::from(samples_local);
                let rest = host.index_count - hull;
                (host.indices.handle, DrawCounts::Direct(rest, hull))
            }
            PartBuffers::Device(part) => (part.indices.handle, DrawCounts::Indirect(&part.args)),
        };
        // SAFETY: recording inside a rendering instance with the matching lens pipeline bound;
        // the index buffer and a resident part's arguments live as long as the frame (whose
        // first barrier made the tessellation's writes visible to these reads); the push
        // constants are the layout's.
        unsafe {
            device.cmd_bind_index_buffer(cb, indices, 0, vk::IndexType::UINT32);
            let skip_local = |constants: &mut LensConstants| {
                constants.skip_local = 1;
                device.cmd_push_constants(
                    cb,
                    layout,
                    vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                    0,
                    bytemuck::bytes_of(&*constants),
                );
            };
            match counts {
                DrawCounts::Direct(rest, hull) => {
                    if rest > 0 {
                        device.cmd_draw_indexed(cb, rest, 1, 0, 0, 0);
                    }
                    if hull > 0 {
                        skip_local(&mut constants);
                        device.cmd_draw_indexed(cb, hull, 1, rest, 0, 0);
                    }
                }
                // The counts are the GPU's: every triangle, or the non-hull ones and then the
                // hull's without the local layer.
                DrawCounts::Indirect(args) if samples_local => {
                    device.cmd_draw_indexed_indirect(cb, args.handle, INDIRECT_REST, 1, 20);
                    skip_local(&mut constants);
                    device.cmd_draw_indexed_indirect(cb, args.handle, INDIRECT_HULL, 1, 20);
                }
                DrawCounts::Indirect(args) => {
                    device.cmd_draw_indexed_indirect(cb, args.handle, INDIRECT_ALL, 1, 20);
                }
            }
        }
    }

    /// The weight of viewpoint sample `v` (0 for one the frame does not have).
    fn viewpoint_weight(&self, v: usize) -> f32 {
        self.frame
            .shape
            .viewpoint_weights
            .get(v)
            .copied()
            .unwrap_or(0.0)
    }

    /// A lens part's push constants before a draw picks its group and layer: both terms'
    /// offsets in data arrays `stride` vec4s apart, the layer count and term mask, no weights.
    /// For path classes (which the single pass reads as one run of slots from the first class's
    /// F·G on), the first class's offsets and the class count in place of the term mask.
    fn lens_constants(&self, lens: &GpuLens, stride: u32) -> LensConstants {
        let offsets = |term| lens.offsets(term, stride).unwrap_or((0, 0));
        let classes = lens
            .terms
            .iter()
            .filter(|t| matches!(t, Term::Class(_)))
            .count();
        let (fg_t, direction_t) = match lens.terms.first() {
            Some(&first) if classes > 0 => offsets(first),
            _ => offsets(Term::Refraction),
        };
        let (fg_r, direction_r) = offsets(Term::Reflection);
        let term_mask = if classes > 0 {
            classes as u32
        } else {
            u32::from(lens.terms.contains(&Term::Refraction))
                | (u32::from(lens.terms.contains(&Term::Reflection)) << 1)
        };
        LensConstants {
            view_proj: self.frame.view_proj,
            weight_a: 0.0,
            weight_b: 0.0,
            weight_c: 0.0,
            layer_count: lens.layer_count,
            term_mask,
            position_offset: 0,
            fg_offset_t: fg_t,
            fg_offset_r: fg_r,
            direction_offset_t: direction_t,
            direction_offset_r: direction_r,
            vertex_count: stride,
            layer: 0,
            ..Zeroable::zeroed()
        }
    }
}
