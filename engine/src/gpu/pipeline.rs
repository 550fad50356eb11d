//! Graphics pipelines for dynamic rendering, built from a plain description. `render/` derives the
//! description from a pass's declared fixed-function state, so the pipeline key is the declaration.

use ash::vk;
use lensmap_shaders::Shader;

use super::{Gpu, GpuError, VkContext};

/// Vertex attributes a pipeline reads (the lens shaders read a storage buffer instead).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VertexInput {
    /// No vertex buffers.
    None,
    /// Binding 0: position (vec3 f32), binding 1: colour (vec3 f32), binding 2: light-map
    /// texture coordinates (vec2 f32).
    PositionColourUv,
    /// Binding 0: position (vec3 f32), binding 1: normal (vec3 f32).
    PositionNormal,
}

/// Everything a graphics pipeline is made of.
#[derive(Clone, Copy, Debug)]
pub struct GraphicsPipelineDesc {
    /// Vertex stage.
    pub vertex: Shader,
    /// Fragment stage.
    pub fragment: Shader,
    /// Vertex buffers.
    pub vertex_input: VertexInput,
    /// The single colour attachment's format.
    pub colour_format: vk::Format,
    /// The depth attachment's format, if any.
    pub depth_format: Option<vk::Format>,
    /// Blend state and colour write mask of the colour attachment.
    pub blend: vk::PipelineColorBlendAttachmentState,
    /// Depth compare op, `None` for no depth test.
    pub depth_test: Option<vk::CompareOp>,
    /// Whether depth is written.
    pub depth_write: bool,
    /// Face culling (front face is counter-clockwise).
    pub cull_mode: vk::CullModeFlags,
    /// The layout (descriptor sets and push constants).
    pub layout: vk::PipelineLayout,
}

impl Gpu {
    /// Creates a shader module from compiled SPIR-V. Destroy with `vkDestroyShaderModule`.
    pub fn create_shader_module(&self, shader: &Shader) -> Result<vk::ShaderModule, GpuError> {
        let words = shader.words();
        let info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: `words` is SPIR-V validated by naga at build time.
        unsafe { self.shared.device.create_shader_module(&info, None) }.vk("vkCreateShaderModule")
    }

    /// Creates a compute pipeline of `shader` with `layout`.
    pub fn create_compute_pipeline(
        &self,
        shader: &Shader,
        layout: vk::PipelineLayout,
    ) -> Result<vk::Pipeline, GpuError> {
        let device = &self.shared.device;
        let module = self.create_shader_module(shader)?;
        let name = std::ffi::CString::new(shader.entry).unwrap_or_default();
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(&name);
        let info = vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout);
        // SAFETY: every pointer in `info` lives until return; the module is destroyed after.
        let result =
            unsafe { device.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) };
        // SAFETY: the module is no longer needed once the pipeline exists (or failed).
        unsafe { device.destroy_shader_module(module, None) };
        match result {
            Ok(pipelines) => Ok(pipelines[0]),
            Err((_, result)) => Err(GpuError::Vulkan {
                call: "vkCreateComputePipelines",
                result,
            }),
        }
    }

    /// Creates a graphics pipeline for dynamic rendering with dynamic viewport and scissor.
    pub fn create_graphics_pipeline(
        &self,
        desc: &GraphicsPipelineDesc,
    ) -> Result<vk::Pipeline, GpuError> {
        let device = &self.shared.device;
        let vertex_module = self.create_shader_module(&desc.vertex)?;
        let fragment_module = match self.create_shader_module(&desc.fragment) {
            Ok(module) => module,
            Err(e) => {
                // SAFETY: unused module of this device.
                unsafe { device.destroy_shader_module(vertex_module, None) };
                return Err(e);
            }
        };
        let vertex_name = std::ffi::CString::new(desc.vertex.entry).unwrap_or_default();
        let fragment_name = std::ffi::CString::new(desc.fragment.entry).unwrap_or_default();
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vertex_module)
                .name(&vertex_name),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(fragment_module)
                .name(&fragment_name),
        ];
        let bindings = [
            vk::VertexInputBindingDescription {
                binding: 0,
                stride: 12,
                input_rate: vk::VertexInputRate::VERTEX,
            },
            vk::VertexInputBindingDescription {
                binding: 1,
                stride: 12,
                input_rate: vk::VertexInputRate::VERTEX,
            },
            vk::VertexInputBindingDescription {
                binding: 2,
                stride: 8,
                input_rate: vk::VertexInputRate::VERTEX,
            },
        ];
        let attributes = [
            vk::VertexInputAttributeDescription {
                location: 0,
                binding: 0,
                format: vk::Format::R32G32B32_SFLOAT,
                offset: 0,
            },
            vk::VertexInputAttributeDescription {
                location: 1,
                binding: 1,
                format: vk::Format::R32G32B32_SFLOAT,
                offset: 0,
            },
            vk::VertexInputAttributeDescription {
                location: 2,
                binding: 2,
                format: vk::Format::R32G32_SFLOAT,
                offset: 0,
            },
        ];
        let vertex_input = match desc.vertex_input {
            VertexInput::None => vk::PipelineVertexInputStateCreateInfo::default(),
            VertexInput::PositionColourUv => vk::PipelineVertexInputStateCreateInfo::default()
                .vertex_binding_descriptions(&bindings)
                .vertex_attribute_descriptions(&attributes),
            // The first two bindings and attributes: position and normal, both vec3.
            VertexInput::PositionNormal => vk::PipelineVertexInputStateCreateInfo::default()
                .vertex_binding_descriptions(&bindings[..2])
                .vertex_attribute_descriptions(&attributes[..2]),
        };
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull_mode)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(desc.depth_test.is_some())
            .depth_write_enable(desc.depth_write)
            .depth_compare_op(desc.depth_test.unwrap_or(vk::CompareOp::ALWAYS));
        let attachments = [desc.blend];
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let colour_formats = [desc.colour_format];
        let mut rendering = vk::PipelineRenderingCreateInfo::default()
            .color_attachment_formats(&colour_formats)
            .depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED));
        let info = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(desc.layout)
            .push_next(&mut rendering);
        // SAFETY: every pointer in `info` lives until return; the modules are destroyed after.
        let result =
            unsafe { device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) };
        // SAFETY: modules are no longer needed once the pipeline exists (or failed).
        unsafe {
            device.destroy_shader_module(vertex_module, None);
            device.destroy_shader_module(fragment_module, None);
        }
        match result {
            Ok(pipelines) => Ok(pipelines[0]),
            Err((_, result)) => Err(GpuError::Vulkan {
                call: "vkCreateGraphicsPipelines",
                result,
            }),
        }
    }
}
