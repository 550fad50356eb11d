//! What every frame's pipelines share, and the pipelines themselves: the lens and environment
//! descriptor-set layouts, the pipeline layouts (lens, environment, box filter) (their push-constant ranges sized by the
//! structs generated from the WGSL), the trilinear sampler of the layered EMs and the bilinear one
//! of the light maps, and one pipeline per [`PipelineKey`], created on first use from the pass's
//! declaration.

use std::{collections::HashMap, sync::Arc};

use ash::vk;
use lensmap_shaders::{EnvironmentConstants, GroupSumConstants, LensConstants, ResolveConstants};

use super::{
    ShaderProgram,
    vulkan::{blend_state, vk_compare, vk_format},
};
use crate::{
    gpu::{Gpu, GpuError, GraphicsPipelineDesc, context::Shared},
    graph::{Cull, PipelineKey},
};

/// Layouts, the sampler and the pipelines created so far, all on one device.
pub(super) struct Pipelines {
    shared: Arc<Shared>,
    /// Set 0 of the lens programs: the lens data (storage buffer), the two viewpoints' cube-map
    /// arrays and the sampler.
    pub(super) lens_set_layout: vk::DescriptorSetLayout,
    /// The lens programs' layout: set 0 and [`LensConstants`].
    pub(super) lens_layout: vk::PipelineLayout,
    /// Set 0 of the environment program: the mesh's light map and its sampler.
    pub(super) environment_set_layout: vk::DescriptorSetLayout,
    /// The environment program's layout: set 0 and [`EnvironmentConstants`].
    pub(super) environment_layout: vk::PipelineLayout,
    /// Set 0 of the box filter: the colour target it averages (read with texel fetches).
    pub(super) box_filter_set_layout: vk::DescriptorSetLayout,
    /// The box filter's layout: set 0 and [`ResolveConstants`].
    pub(super) box_filter_layout: vk::PipelineLayout,
    /// The group sum's layout: set 0 (one sampled image, as the box filter's: the scratch
    /// images' array view) and [`GroupSumConstants`].
    pub(super) group_sum_layout: vk::PipelineLayout,
    /// The programmable layer's layout: the lens programs' set 0, set 1 the scratch images'
    /// array view (the box filter's set layout), and [`LensConstants`].
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
            device.destroy_pipeline_layout(self.lens_layout, None);
            device.destroy_pipeline_layout(self.environment_layout, None);
            device.destroy_pipeline_layout(self.box_filter_layout, None);
            device.destroy_pipeline_layout(self.group_sum_layout, None);
            device.destroy_pipeline_layout(self.programmable_layout, None);
            device.destroy_descriptor_set_layout(self.lens_set_layout, None);
            device.destroy_descriptor_set_layout(self.environment_set_layout, None);
            device.destroy_descriptor_set_layout(self.box_filter_set_layout, None);
            device.destroy_sampler(self.sampler, None);
            device.destroy_sampler(self.light_map_sampler, None);
        }
    }
}

/// The size of a push-constant struct as Vulkan wants it.
fn push_size<T>() -> u32 {
    std::mem::size_of::<T>() as u32
}

impl Pipelines {
    /// Creates the layouts and the sampler; pipelines are created on first use.
    pub(super) fn new(gpu: &Gpu) -> Result<Pipelines, GpuError> {
        let device = gpu.device();
        let binding = |binding: u32, ty: vk::DescriptorType, stage: vk::ShaderStageFlags| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(binding)
                .descriptor_type(ty)
                .descriptor_count(1)
                .stage_flags(stage)
        };
        let bindings = [
            binding(
                0,
                vk::DescriptorType::STORAGE_BUFFER,
                vk::ShaderStageFlags::VERTEX,
            ),
            binding(
                1,
                vk::DescriptorType::SAMPLED_IMAGE,
                vk::ShaderStageFlags::FRAGMENT,
            ),
            binding(
                2,
                vk::DescriptorType::SAMPLED_IMAGE,
                vk::ShaderStageFlags::FRAGMENT,
            ),
            binding(
                3,
                vk::DescriptorType::SAMPLER,
                vk::ShaderStageFlags::FRAGMENT,
            ),
        ];
        let mut pipelines = Pipelines {
            shared: gpu.shared.clone(),
            lens_set_layout: vk::DescriptorSetLayout::null(),
            lens_layout: vk::PipelineLayout::null(),
            environment_set_layout: vk::DescriptorSetLayout::null(),
            environment_layout: vk::PipelineLayout::null(),
            box_filter_set_layout: vk::DescriptorSetLayout::null(),
            box_filter_layout: vk::PipelineLayout::null(),
            group_sum_layout: vk::PipelineLayout::null(),
            programmable_layout: vk::PipelineLayout::null(),
            sampler: vk::Sampler::null(),
            light_map_sampler: vk::Sampler::null(),
            pipelines: HashMap::new(),
        };
        let vk_err = |call| move |result| GpuError::Vulkan { call, result };
        // SAFETY: create infos live until each call returns; Drop destroys what was created.
        unsafe {
            pipelines.lens_set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
            let lens_push = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: push_size::<LensConstants>(),
            }];
            let set_layouts = [pipelines.lens_set_layout];
            pipelines.lens_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&set_layouts)
                        .push_constant_ranges(&lens_push),
                    None,
                )
                .map_err(vk_err("vkCreatePipelineLayout"))?;
            let environment_push = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::VERTEX,
                offset: 0,
                size: push_size::<EnvironmentConstants>(),
            }];
            let environment_bindings = [
                binding(
                    0,
                    vk::DescriptorType::SAMPLED_IMAGE,
                    vk::ShaderStageFlags::FRAGMENT,
                ),
                binding(
                    1,
                    vk::DescriptorType::SAMPLER,
                    vk::ShaderStageFlags::FRAGMENT,
                ),
            ];
            pipelines.environment_set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&environment_bindings),
                    None,
                )
                .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
            let environment_sets = [pipelines.environment_set_layout];
            pipelines.environment_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&environment_sets)
                        .push_constant_ranges(&environment_push),
                    None,
                )
                .map_err(vk_err("vkCreatePipelineLayout"))?;
            let box_filter_bindings = [binding(
                0,
                vk::DescriptorType::SAMPLED_IMAGE,
                vk::ShaderStageFlags::FRAGMENT,
            )];
            pipelines.box_filter_set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&box_filter_bindings),
                    None,
                )
                .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
            let box_filter_sets = [pipelines.box_filter_set_layout];
            let box_filter_push = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: push_size::<ResolveConstants>(),
            }];
            pipelines.box_filter_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&box_filter_sets)
                        .push_constant_ranges(&box_filter_push),
                    None,
                )
                .map_err(vk_err("vkCreatePipelineLayout"))?;
            let group_sum_push = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: push_size::<GroupSumConstants>(),
            }];
            pipelines.group_sum_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&box_filter_sets)
                        .push_constant_ranges(&group_sum_push),
                    None,
                )
                .map_err(vk_err("vkCreatePipelineLayout"))?;
            let programmable_sets = [pipelines.lens_set_layout, pipelines.box_filter_set_layout];
            pipelines.programmable_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&programmable_sets)
                        .push_constant_ranges(&lens_push),
                    None,
                )
                .map_err(vk_err("vkCreatePipelineLayout"))?;
            // Trilinear, clamp to edge, every level; cube maps filter seamlessly (Vulkan default).
            let sampler = vk::SamplerCreateInfo::default()
                .mag_filter(vk::Filter::LINEAR)
                .min_filter(vk::Filter::LINEAR)
                .mipmap_mode(vk::SamplerMipmapMode::LINEAR)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .min_lod(0.0)
                .max_lod(vk::LOD_CLAMP_NONE);
            pipelines.sampler = device
                .create_sampler(&sampler, None)
                .map_err(vk_err("vkCreateSampler"))?;
            let light_map_sampler = vk::SamplerCreateInfo::default()
                .mag_filter(vk::Filter::LINEAR)
                .min_filter(vk::Filter::LINEAR)
                .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
                .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE)
                .min_lod(0.0)
                .max_lod(0.0);
            pipelines.light_map_sampler = device
                .create_sampler(&light_map_sampler, None)
                .map_err(vk_err("vkCreateSampler"))?;
        }
        Ok(pipelines)
    }

    /// The pipeline layout a program's pipelines use: the environment's or the lens programs'
    /// descriptor set and push constants.
    pub(super) fn layout_of(&self, program: ShaderProgram) -> vk::PipelineLayout {
        match program {
            ShaderProgram::Environment => self.environment_layout,
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
