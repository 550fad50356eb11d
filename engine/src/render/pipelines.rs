//! What every frame's pipelines share, and the pipelines themselves: the descriptor-set layouts
//! (created from their descriptions in [`super::descriptors`]), the pipeline layouts (their
//! push-constant ranges sized by the structs generated from the WGSL), the trilinear sampler of
//! the layered EMs and the bilinear one of the light maps, and one pipeline per [`PipelineKey`],
//! created on first use from the pass's declaration.

use std::{collections::HashMap, sync::Arc};

use ash::vk;
use lensmap_shaders::{EnvironmentConstants, GroupSumConstants, LensConstants, ResolveConstants};

use super::{
    ShaderProgram,
    descriptors::{ENVIRONMENT_SET, LENS_SET, SAMPLED_IMAGE_SET},
    glossy::GLOSSY_SET,
    vulkan::{blend_state, vk_compare, vk_format},
};
use crate::{
    gpu::{
        Gpu, GpuError, GraphicsPipelineDesc, VkContext, context::Shared, descriptors::SetLayout,
    },
    graph::{Cull, PipelineKey},
};

/// Layouts, the sampler and the pipelines created so far, all on one device.
pub(super) struct Pipelines {
    shared: Arc<Shared>,
    /// Set 0 of the lens programs ([`LENS_SET`]).
    pub(super) lens_set_layout: SetLayout,
    /// The lens programs' layout: set 0 and [`LensConstants`].
    pub(super) lens_layout: vk::PipelineLayout,
    /// Set 0 of the environment program ([`ENVIRONMENT_SET`]).
    pub(super) environment_set_layout: SetLayout,
    /// The environment program's layout: set 0 and [`EnvironmentConstants`].
    pub(super) environment_layout: vk::PipelineLayout,
    /// Set 0 of the glossy program ([`GLOSSY_SET`]).
    pub(super) glossy_set_layout: SetLayout,
    /// The glossy program's layout: set 0 alone (its data is in the set's storage buffer).
    pub(super) glossy_layout: vk::PipelineLayout,
    /// One sampled image ([`SAMPLED_IMAGE_SET`]): set 0 of the box filter (the colour target)
    /// and of the group sum (the scratch images' array view), set 1 of the programmable layer
    /// (one scratch image).
    pub(super) sampled_image_set_layout: SetLayout,
    /// The box filter's layout: the sampled image and [`ResolveConstants`].
    pub(super) box_filter_layout: vk::PipelineLayout,
    /// The group sum's layout: the sampled image and [`GroupSumConstants`].
    pub(super) group_sum_layout: vk::PipelineLayout,
    /// The programmable layer's layout: the lens programs' set 0, the sampled image as set 1,
    /// and [`LensConstants`].
    pub(super) programmable_layout: vk::PipelineLayout,
    /// Trilinear, clamp to edge, every level.
    pub(super) sampler: vk::Sampler,
    /// Light maps: bilinear, clamp to edge, level 0 only (charts' gutters are sized for one
    /// level).
    pub(super) light_map_sampler: vk::Sampler,
    pipelines: HashMap<PipelineKey<ShaderProgram>, vk::Pipeline>,
}

impl Drop for Pipelines {
    fn drop(&mut self) {
        let device = &self.shared.device;
        // SAFETY: all submissions were waited for; these objects belong to this device (null
        // handles from a failed `new` are ignored by vkDestroy*).
        unsafe {
            let _ = device.device_wait_idle();
            for pipeline in self.pipelines.values() {
                device.destroy_pipeline(*pipeline, None);
            }
            for layout in [
                self.lens_layout,
                self.environment_layout,
                self.glossy_layout,
                self.box_filter_layout,
                self.group_sum_layout,
                self.programmable_layout,
            ] {
                device.destroy_pipeline_layout(layout, None);
            }
            device.destroy_sampler(self.sampler, None);
            device.destroy_sampler(self.light_map_sampler, None);
        }
    }
}

/// The push constants `T` of a pipeline layout, read by `stages`.
fn push_constants<T>(stages: vk::ShaderStageFlags) -> vk::PushConstantRange {
    vk::PushConstantRange {
        stage_flags: stages,
        offset: 0,
        size: std::mem::size_of::<T>() as u32,
    }
}

/// Creates the pipeline layout of `sets` (set i is `sets[i]`) and at most one push-constant
/// range.
fn create_layout(
    gpu: &Gpu,
    sets: &[vk::DescriptorSetLayout],
    push: impl Into<Option<vk::PushConstantRange>>,
) -> Result<vk::PipelineLayout, GpuError> {
    let push: Vec<vk::PushConstantRange> = push.into().into_iter().collect();
    // SAFETY: the create info lives until the call returns; Pipelines::drop destroys the layout.
    unsafe {
        gpu.device().create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default()
                .set_layouts(sets)
                .push_constant_ranges(&push),
            None,
        )
    }
    .vk("vkCreatePipelineLayout")
}

/// Creates a linear sampler clamping to the edge, with `mipmap_mode` between levels
/// `0..=max_lod`. Cube maps filter seamlessly (Vulkan's default).
fn create_sampler(
    gpu: &Gpu,
    mipmap_mode: vk::SamplerMipmapMode,
    max_lod: f32,
) -> Result<vk::Sampler, GpuError> {
    let info = vk::SamplerCreateInfo::default()
        .mag_filter(vk::Filter::LINEAR)
        .min_filter(vk::Filter::LINEAR)
        .mipmap_mode(mipmap_mode)
        .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
        .min_lod(0.0)
        .max_lod(max_lod);
    // SAFETY: valid create info; Pipelines::drop destroys the sampler.
    unsafe { gpu.device().create_sampler(&info, None) }.vk("vkCreateSampler")
}

impl Pipelines {
    /// Creates the layouts and the samplers; pipelines are created on first use.
    pub(super) fn new(gpu: &Gpu) -> Result<Pipelines, GpuError> {
        // The set layouts own themselves; every other handle starts null, so that Drop after a
        // failure destroys what was created.
        let mut pipelines = Pipelines {
            shared: gpu.shared.clone(),
            lens_set_layout: SetLayout::new(gpu, LENS_SET.to_vec())?,
            lens_layout: vk::PipelineLayout::null(),
            environment_set_layout: SetLayout::new(gpu, ENVIRONMENT_SET.to_vec())?,
            environment_layout: vk::PipelineLayout::null(),
            glossy_set_layout: SetLayout::new(gpu, GLOSSY_SET.to_vec())?,
            glossy_layout: vk::PipelineLayout::null(),
            sampled_image_set_layout: SetLayout::new(gpu, SAMPLED_IMAGE_SET.to_vec())?,
            box_filter_layout: vk::PipelineLayout::null(),
            group_sum_layout: vk::PipelineLayout::null(),
            programmable_layout: vk::PipelineLayout::null(),
            sampler: vk::Sampler::null(),
            light_map_sampler: vk::Sampler::null(),
            pipelines: HashMap::new(),
        };
        let p = &mut pipelines;
        let (vertex, fragment) = (vk::ShaderStageFlags::VERTEX, vk::ShaderStageFlags::FRAGMENT);
        let lens_push = push_constants::<LensConstants>(vertex | fragment);
        p.lens_layout = create_layout(gpu, &[p.lens_set_layout.handle], lens_push)?;
        p.environment_layout = create_layout(
            gpu,
            &[p.environment_set_layout.handle],
            push_constants::<EnvironmentConstants>(vertex),
        )?;
        p.glossy_layout = create_layout(gpu, &[p.glossy_set_layout.handle], None)?;
        p.box_filter_layout = create_layout(
            gpu,
            &[p.sampled_image_set_layout.handle],
            push_constants::<ResolveConstants>(fragment),
        )?;
        p.group_sum_layout = create_layout(
            gpu,
            &[p.sampled_image_set_layout.handle],
            push_constants::<GroupSumConstants>(fragment),
        )?;
        p.programmable_layout = create_layout(
            gpu,
            &[p.lens_set_layout.handle, p.sampled_image_set_layout.handle],
            lens_push,
        )?;
        p.sampler = create_sampler(gpu, vk::SamplerMipmapMode::LINEAR, vk::LOD_CLAMP_NONE)?;
        p.light_map_sampler = create_sampler(gpu, vk::SamplerMipmapMode::NEAREST, 0.0)?;
        Ok(pipelines)
    }

    /// The pipeline layout a program's pipelines use: the environment's or the lens programs'
    /// descriptor set and push constants.
    pub(super) fn layout_of(&self, program: ShaderProgram) -> vk::PipelineLayout {
        match program {
            ShaderProgram::Environment => self.environment_layout,
            ShaderProgram::Glossy => self.glossy_layout,
            ShaderProgram::LensZero
            | ShaderProgram::LensLayer
            | ShaderProgram::LensSinglePass(_) => self.lens_layout,
            ShaderProgram::BoxFilter => self.box_filter_layout,
            ShaderProgram::GroupSum => self.group_sum_layout,
            ShaderProgram::LensLayerProgrammable => self.programmable_layout,
        }
    }

    /// The pipeline for `key`, created on first use.
    pub(super) fn get(
        &mut self,
        gpu: &Gpu,
        key: PipelineKey<ShaderProgram>,
    ) -> Result<vk::Pipeline, GpuError> {
        if let Some(pipeline) = self.pipelines.get(&key) {
            return Ok(*pipeline);
        }
        // Every program's SPIR-V exists (unit-tested over all programs in `program.rs`).
        let (vertex, fragment) = key.program.shaders().ok_or(GpuError::Vulkan {
            call: "shader lookup",
            result: vk::Result::ERROR_INITIALIZATION_FAILED,
        })?;
        let pipeline = gpu.create_graphics_pipeline(&GraphicsPipelineDesc {
            vertex,
            fragment,
            vertex_input: key.program.vertex_input(),
            colour_format: vk_format(key.colour_format),
            depth_format: key.depth_format.map(vk_format),
            blend: blend_state(key.blend, key.write_mask),
            depth_test: key.depth_test.map(vk_compare),
            depth_write: key.depth_write,
            cull_mode: match key.cull {
                Cull::None => vk::CullModeFlags::NONE,
                Cull::Back => vk::CullModeFlags::BACK,
            },
            layout: self.layout_of(key.program),
        })?;
        self.pipelines.insert(key, pipeline);
        Ok(pipeline)
    }
}
