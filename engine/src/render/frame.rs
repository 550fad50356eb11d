//! The compositor on the GPU: uploads a [`FrameInput`], records a compiled plan into one command
//! buffer (dynamic rendering, synchronization2, a debug label around every pass), submits it and
//! reads the colour target back.

use std::{collections::HashMap, sync::Arc, time::Instant};

use ash::vk;
use bytemuck::{Pod, Zeroable};

use crate::cubemap::CubeMap;
use crate::{
    gpu::{
        Buffer, BufferUsage, Gpu, GpuError, GraphicsPipelineDesc, Image, ImageDesc, VertexInput,
        context::Shared,
    },
    graph::{
        self, Access, Blend, CompareOp, Cull, Format, Layout, LoadOp, PassKind, PipelineKey, Plan,
        StoreOp,
    },
    trace::Term,
};

use super::{
    FrameInput, RenderError,
    plan::{Draw, FrameResources, FrameShape, TargetFormat, Variant, frame_graph, program},
};

/// A frame read back from the GPU, converted to f32 RGBA (rows top to bottom).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGBA per pixel, exactly as stored in the target (RGBA8 as n/255).
    pub pixels: Vec<[f32; 4]>,
}

impl RenderedImage {
    /// The image box-filtered by k×k (k ≥ 1 dividing both sides): supersampled frames to pixels.
    pub fn box_downsample(&self, k: u32) -> RenderedImage {
        let k = k.max(1);
        if k == 1 || !self.width.is_multiple_of(k) || !self.height.is_multiple_of(k) {
            return self.clone();
        }
        let (width, height) = (self.width / k, self.height / k);
        let scale = 1.0 / (k * k) as f32;
        let pixels = (0..width * height)
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let mut sum = [0.0f32; 4];
                for dy in 0..k {
                    for dx in 0..k {
                        let p = self.pixels[((y * k + dy) * self.width + x * k + dx) as usize];
                        for c in 0..4 {
                            sum[c] += p[c];
                        }
                    }
                }
                sum.map(|v| v * scale)
            })
            .collect();
        RenderedImage {
            width,
            height,
            pixels,
        }
    }
}

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

/// Push constants of the lens shaders (`LensConstants` in shaders/wgsl/lens.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LensConstants {
    view_proj: [f32; 16],
    weight_a: f32,
    weight_b: f32,
    layer_count: u32,
    term_mask: u32,
    position_offset: u32,
    fg_offset_t: u32,
    fg_offset_r: u32,
    direction_offset_t: u32,
    direction_offset_r: u32,
    vertex_count: u32,
    layer: u32,
    _pad: u32,
}

/// A lens object's data on the GPU.
struct GpuLens {
    /// The storage buffer the descriptor sets point at (kept alive here).
    _data: Buffer,
    indices: Buffer,
    index_count: u32,
    vertex_count: u32,
    /// Offset (vec4 units) of F·G per term, and of layer 0's directions per term.
    fg_offset: HashMap<Term, u32>,
    direction_offset: HashMap<Term, u32>,
    layer_count: u32,
    /// One cube-map array per viewpoint sample (shared with the renderer's cache).
    layers: Vec<Arc<Image>>,
    /// One descriptor set per viewpoint (binding 1 = that viewpoint, binding 2 = the other).
    sets: Vec<vk::DescriptorSet>,
}

struct GpuMesh {
    positions: Buffer,
    colours: Buffer,
    indices: Buffer,
    index_count: u32,
}

struct Targets {
    colour: Image,
    depth: Image,
    readback: Buffer,
}

/// A frame's data uploaded once and rendered any number of times, in any variant and format.
pub struct UploadedFrame {
    shape: FrameShape,
    view_proj: [f32; 16],
    environment: Vec<Arc<GpuMesh>>,
    lenses: Vec<GpuLens>,
    descriptor_pool: vk::DescriptorPool,
    targets: HashMap<TargetFormat, Targets>,
    shared: Arc<Shared>,
}

impl Drop for UploadedFrame {
    fn drop(&mut self) {
        // SAFETY: every submission using these sets was waited for.
        unsafe {
            let _ = self.shared.device.device_wait_idle();
            self.shared
                .device
                .destroy_descriptor_pool(self.descriptor_pool, None);
        }
    }
}

impl UploadedFrame {
    /// The frame's shape (what its plan depends on).
    pub fn shape(&self) -> &FrameShape {
        &self.shape
    }
}

/// Pipelines, layouts and the sampler shared by every frame.
pub struct Renderer {
    shared: Arc<Shared>,
    lens_set_layout: vk::DescriptorSetLayout,
    lens_layout: vk::PipelineLayout,
    environment_layout: vk::PipelineLayout,
    sampler: vk::Sampler,
    pipelines: HashMap<PipelineKey, vk::Pipeline>,
    command_buffer: vk::CommandBuffer,
    /// Uploaded layered EMs, keyed by the identity of their `Arc<CubeMap>`s: a frame that hands
    /// over the same maps as a recent one reuses their cube-map array instead of uploading again.
    layer_cache: HashMap<Vec<usize>, CachedLayers>,
    /// Uploaded environment meshes, keyed by the identity of their `Arc<EnvironmentMesh>`.
    mesh_cache: HashMap<usize, CachedMesh>,
    /// Uploads so far (for evicting cache entries no recent frame used).
    generation: u64,
}

/// One uploaded environment mesh and the mesh it holds (kept so its address stays unique).
struct CachedMesh {
    _mesh: Arc<super::EnvironmentMesh>,
    buffers: Arc<GpuMesh>,
    last_used: u64,
}

/// One uploaded cube-map array and the maps it holds (kept so their addresses stay unique).
struct CachedLayers {
    _maps: Vec<Arc<CubeMap>>,
    image: Arc<Image>,
    last_used: u64,
}

impl Drop for Renderer {
    fn drop(&mut self) {
        let device = &self.shared.device;
        // SAFETY: all submissions were waited for; these objects belong to this device.
        unsafe {
            let _ = device.device_wait_idle();
            for pipeline in self.pipelines.values() {
                device.destroy_pipeline(*pipeline, None);
            }
            device.destroy_pipeline_layout(self.lens_layout, None);
            device.destroy_pipeline_layout(self.environment_layout, None);
            device.destroy_descriptor_set_layout(self.lens_set_layout, None);
            device.destroy_sampler(self.sampler, None);
        }
    }
}

fn vk_format(format: Format) -> vk::Format {
    match format {
        Format::Rgba8Unorm => vk::Format::R8G8B8A8_UNORM,
        Format::Rgba16Float => vk::Format::R16G16B16A16_SFLOAT,
        Format::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
        Format::Depth32Float => vk::Format::D32_SFLOAT,
    }
}

fn vk_layout(layout: Layout) -> vk::ImageLayout {
    match layout {
        Layout::Undefined => vk::ImageLayout::UNDEFINED,
        Layout::ColourAttachment => vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        // Valid for depth-only formats without the separateDepthStencilLayouts feature.
        Layout::DepthAttachment => vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
        Layout::ShaderRead => vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        Layout::TransferSrc => vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
    }
}

fn vk_access(access: Access) -> (vk::PipelineStageFlags2, vk::AccessFlags2) {
    match access {
        // Whatever ran before on the queue (earlier frames included) finishes first.
        Access::None => (
            vk::PipelineStageFlags2::ALL_COMMANDS,
            vk::AccessFlags2::NONE,
        ),
        Access::ColourAttachment => (
            vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
            vk::AccessFlags2::COLOR_ATTACHMENT_READ | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
        ),
        Access::DepthAttachment => (
            vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS,
            vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE,
        ),
        Access::FragmentSample => (
            vk::PipelineStageFlags2::FRAGMENT_SHADER,
            vk::AccessFlags2::SHADER_SAMPLED_READ,
        ),
        Access::VertexStorageRead => (
            vk::PipelineStageFlags2::VERTEX_SHADER,
            vk::AccessFlags2::SHADER_STORAGE_READ,
        ),
        Access::TransferRead => (
            vk::PipelineStageFlags2::COPY,
            vk::AccessFlags2::TRANSFER_READ,
        ),
        Access::TransferWrite => (
            vk::PipelineStageFlags2::COPY,
            vk::AccessFlags2::TRANSFER_WRITE,
        ),
    }
}

fn vk_compare(op: CompareOp) -> vk::CompareOp {
    match op {
        CompareOp::Less => vk::CompareOp::LESS,
        CompareOp::LessOrEqual => vk::CompareOp::LESS_OR_EQUAL,
    }
}

fn blend_state(blend: Blend, mask: graph::ColourMask) -> vk::PipelineColorBlendAttachmentState {
    let state = vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::from_raw(u32::from(mask.0)));
    match blend {
        Blend::Replace => state.blend_enable(false),
        // Front-to-back "over" (DESIGN.md): src·(1 − dstα) + dst·1 on colour and alpha.
        Blend::FrontToBackOver => state
            .blend_enable(true)
            .src_color_blend_factor(vk::BlendFactor::ONE_MINUS_DST_ALPHA)
            .dst_color_blend_factor(vk::BlendFactor::ONE)
            .color_blend_op(vk::BlendOp::ADD)
            .src_alpha_blend_factor(vk::BlendFactor::ONE_MINUS_DST_ALPHA)
            .dst_alpha_blend_factor(vk::BlendFactor::ONE)
            .alpha_blend_op(vk::BlendOp::ADD),
    }
}

fn vec4_bytes(values: impl IntoIterator<Item = [f32; 4]>) -> Vec<u8> {
    values
        .into_iter()
        .flat_map(|v| v.map(f32::to_le_bytes))
        .flatten()
        .collect()
}

impl Renderer {
    /// Creates the layouts and sampler; pipelines are created on first use.
    pub fn new(gpu: &Gpu) -> Result<Renderer, GpuError> {
        let device = gpu.device();
        let bindings = [
            vk::DescriptorSetLayoutBinding::default()
                .binding(0)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::VERTEX),
            vk::DescriptorSetLayoutBinding::default()
                .binding(1)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::FRAGMENT),
            vk::DescriptorSetLayoutBinding::default()
                .binding(2)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::FRAGMENT),
            vk::DescriptorSetLayoutBinding::default()
                .binding(3)
                .descriptor_type(vk::DescriptorType::SAMPLER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::FRAGMENT),
        ];
        let mut renderer = Renderer {
            shared: gpu.shared.clone(),
            lens_set_layout: vk::DescriptorSetLayout::null(),
            lens_layout: vk::PipelineLayout::null(),
            environment_layout: vk::PipelineLayout::null(),
            sampler: vk::Sampler::null(),
            pipelines: HashMap::new(),
            command_buffer: gpu.allocate_command_buffer()?,
            layer_cache: HashMap::new(),
            mesh_cache: HashMap::new(),
            generation: 0,
        };
        let vk_err = |call| move |result| GpuError::Vulkan { call, result };
        // SAFETY: create infos live until each call returns; Drop destroys what was created
        // (null handles are ignored by vkDestroy*).
        unsafe {
            renderer.lens_set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .map_err(vk_err("vkCreateDescriptorSetLayout"))?;
            let lens_push = [vk::PushConstantRange {
                stage_flags: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                offset: 0,
                size: std::mem::size_of::<LensConstants>() as u32,
            }];
            let set_layouts = [renderer.lens_set_layout];
            renderer.lens_layout = device
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
                size: 64,
            }];
            renderer.environment_layout = device
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .push_constant_ranges(&environment_push),
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
            renderer.sampler = device
                .create_sampler(&sampler, None)
                .map_err(vk_err("vkCreateSampler"))?;
        }
        Ok(renderer)
    }

    /// Validates and uploads a frame's data. Layered EMs already uploaded for one of the last two
    /// frames (the same `Arc<CubeMap>`s) are reused.
    pub fn upload(&mut self, gpu: &Gpu, frame: &FrameInput) -> Result<UploadedFrame, RenderError> {
        frame.validate()?;
        self.generation += 1;
        let environment = frame
            .environment
            .iter()
            .filter(|m| !m.triangles.is_empty())
            .map(|mesh| self.environment_mesh(gpu, mesh))
            .collect::<Result<Vec<_>, GpuError>>()?;

        let set_count = frame
            .lenses
            .iter()
            .map(|l| l.layers.len())
            .sum::<usize>()
            .max(1) as u32;
        let pool_sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: set_count,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::SAMPLED_IMAGE,
                descriptor_count: 2 * set_count,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::SAMPLER,
                descriptor_count: set_count,
            },
        ];
        let device = gpu.device();
        // SAFETY: valid create info; destroyed by UploadedFrame::drop.
        let descriptor_pool = unsafe {
            device.create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(set_count)
                    .pool_sizes(&pool_sizes),
                None,
            )
        }
        .map_err(|result| GpuError::Vulkan {
            call: "vkCreateDescriptorPool",
            result,
        })?;
        let mut uploaded = UploadedFrame {
            shape: FrameShape::of(frame),
            view_proj: frame.view_proj.to_cols_array(),
            environment,
            lenses: Vec::new(),
            descriptor_pool,
            targets: HashMap::new(),
            shared: gpu.shared.clone(),
        };
        for (index, lens) in frame.lenses.iter().enumerate() {
            let gpu_lens = self.upload_lens(gpu, descriptor_pool, index, lens)?;
            uploaded.lenses.push(gpu_lens);
        }
        let generation = self.generation;
        self.layer_cache
            .retain(|_, cached| cached.last_used + 1 >= generation);
        self.mesh_cache
            .retain(|_, cached| cached.last_used + 1 >= generation);
        Ok(uploaded)
    }

    /// The vertex and index buffers of an environment mesh, from the cache or freshly uploaded.
    fn environment_mesh(
        &mut self,
        gpu: &Gpu,
        mesh: &Arc<super::EnvironmentMesh>,
    ) -> Result<Arc<GpuMesh>, GpuError> {
        let key = Arc::as_ptr(mesh) as usize;
        if let Some(cached) = self.mesh_cache.get_mut(&key) {
            cached.last_used = self.generation;
            return Ok(cached.buffers.clone());
        }
        let floats = |v: &[glam::Vec3]| -> Vec<u8> {
            v.iter()
                .flat_map(|p| p.to_array())
                .flat_map(f32::to_le_bytes)
                .collect()
        };
        let indices: Vec<u8> = mesh
            .triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let buffers = Arc::new(GpuMesh {
            positions: Buffer::with_data(
                gpu,
                "environment positions",
                &floats(&mesh.positions),
                BufferUsage::Vertex,
            )?,
            colours: Buffer::with_data(
                gpu,
                "environment colours",
                &floats(&mesh.colours),
                BufferUsage::Vertex,
            )?,
            indices: Buffer::with_data(gpu, "environment indices", &indices, BufferUsage::Index)?,
            index_count: (mesh.triangles.len() * 3) as u32,
        });
        self.mesh_cache.insert(
            key,
            CachedMesh {
                _mesh: mesh.clone(),
                buffers: buffers.clone(),
                last_used: self.generation,
            },
        );
        Ok(buffers)
    }

    /// The cube-map array holding `cubes`, from the cache or freshly uploaded.
    fn layer_image(
        &mut self,
        gpu: &Gpu,
        name: &str,
        cubes: &[Arc<CubeMap>],
    ) -> Result<Arc<Image>, GpuError> {
        let key: Vec<usize> = cubes.iter().map(|c| Arc::as_ptr(c) as usize).collect();
        if let Some(cached) = self.layer_cache.get_mut(&key) {
            cached.last_used = self.generation;
            return Ok(cached.image.clone());
        }
        let size = cubes.first().map_or(1, |c| c.size);
        let mut image = Image::new(
            gpu,
            ImageDesc::cube_array(
                name,
                vk::Format::R32G32B32A32_SFLOAT,
                size,
                cubes.len() as u32,
            ),
        )?;
        for level in 0..image.desc.mip_levels as usize {
            let bytes = vec4_bytes(
                cubes
                    .iter()
                    .flat_map(|cube| cube.levels[level].iter().flatten().copied()),
            );
            image.upload(gpu, level as u32, 0, 6 * cubes.len() as u32, &bytes)?;
        }
        let image = Arc::new(image);
        self.layer_cache.insert(
            key,
            CachedLayers {
                _maps: cubes.to_vec(),
                image: image.clone(),
                last_used: self.generation,
            },
        );
        Ok(image)
    }

    fn upload_lens(
        &mut self,
        gpu: &Gpu,
        pool: vk::DescriptorPool,
        index: usize,
        lens: &super::LensObject,
    ) -> Result<GpuLens, GpuError> {
        let vertex_count = lens.positions.len() as u32;
        let mut data: Vec<[f32; 4]> = lens
            .positions
            .iter()
            .map(|p| p.extend(1.0).to_array())
            .collect();
        let mut fg_offset = HashMap::new();
        let mut direction_offset = HashMap::new();
        for term in &lens.terms {
            fg_offset.insert(term.term, data.len() as u32);
            data.extend(term.fg.iter().map(|c| c.extend(0.0).to_array()));
            direction_offset.insert(term.term, data.len() as u32);
            for layer in &term.directions {
                data.extend(layer.iter().map(|d| d.extend(0.0).to_array()));
            }
        }
        let name = format!("lens{index} data");
        let data = Buffer::with_data(gpu, &name, &vec4_bytes(data), BufferUsage::Storage)?;
        let indices: Vec<u8> = lens
            .triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let indices = Buffer::with_data(
            gpu,
            &format!("lens{index} indices"),
            &indices,
            BufferUsage::Index,
        )?;

        let mut layers = Vec::new();
        for (viewpoint, cubes) in lens.layers.iter().enumerate() {
            layers.push(self.layer_image(gpu, &format!("lens{index}/em{viewpoint}"), cubes)?);
        }

        let layouts = vec![self.lens_set_layout; layers.len()];
        let device = gpu.device();
        // SAFETY: the pool was sized for one set per (lens, viewpoint).
        let sets = unsafe {
            device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&layouts),
            )
        }
        .map_err(|result| GpuError::Vulkan {
            call: "vkAllocateDescriptorSets",
            result,
        })?;
        for (viewpoint, set) in sets.iter().enumerate() {
            let other = if layers.len() > 1 {
                1 - viewpoint.min(1)
            } else {
                viewpoint
            };
            let buffer_info = [vk::DescriptorBufferInfo {
                buffer: data.handle,
                offset: 0,
                range: vk::WHOLE_SIZE,
            }];
            let image_a = [vk::DescriptorImageInfo {
                sampler: vk::Sampler::null(),
                image_view: layers[viewpoint].view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            }];
            let image_b = [vk::DescriptorImageInfo {
                image_view: layers[other].view,
                ..image_a[0]
            }];
            let sampler = [vk::DescriptorImageInfo {
                sampler: self.sampler,
                ..Default::default()
            }];
            let writes = [
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(0)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(&buffer_info),
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(1)
                    .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                    .image_info(&image_a),
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(2)
                    .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                    .image_info(&image_b),
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(3)
                    .descriptor_type(vk::DescriptorType::SAMPLER)
                    .image_info(&sampler),
            ];
            // SAFETY: the set is not in use; the infos live until return.
            unsafe { device.update_descriptor_sets(&writes, &[]) };
        }
        Ok(GpuLens {
            _data: data,
            indices,
            index_count: (lens.triangles.len() * 3) as u32,
            vertex_count,
            fg_offset,
            direction_offset,
            layer_count: lens.layer_count() as u32,
            layers,
            sets,
        })
    }

    fn pipeline(&mut self, gpu: &Gpu, key: PipelineKey) -> Result<vk::Pipeline, GpuError> {
        if let Some(pipeline) = self.pipelines.get(&key) {
            return Ok(*pipeline);
        }
        let shader = |file, entry| {
            lensmap_shaders::shader(file, entry).ok_or(GpuError::Vulkan {
                call: "shader lookup",
                result: vk::Result::ERROR_INITIALIZATION_FAILED,
            })
        };
        let (vertex, fragment, vertex_input, layout) = match key.program {
            program::ENVIRONMENT => (
                shader("environment", "vs_environment")?,
                shader("environment", "fs_environment")?,
                VertexInput::PositionColour,
                self.environment_layout,
            ),
            program::LENS_LAYER => (
                shader("lens", "vs_layer")?,
                shader("lens", "fs_layer")?,
                VertexInput::None,
                self.lens_layout,
            ),
            program::LENS_SINGLE_PASS => (
                shader("lens", "vs_single_pass")?,
                {
                    let [layers, terms, viewpoints] = key.specialization;
                    let wanted =
                        format!("LAYER_COUNT={layers},TERM_MASK={terms},VIEWPOINTS={viewpoints}");
                    lensmap_shaders::specialized("lens", "fs_single_pass_specialized", &wanted)
                        .ok_or(GpuError::Vulkan {
                            call: "specialized shader lookup",
                            result: vk::Result::ERROR_INITIALIZATION_FAILED,
                        })?
                },
                VertexInput::None,
                self.lens_layout,
            ),
            _ => (
                shader("lens", "vs_position")?,
                shader("lens", "fs_zero")?,
                VertexInput::None,
                self.lens_layout,
            ),
        };
        let pipeline = gpu.create_graphics_pipeline(&GraphicsPipelineDesc {
            vertex,
            fragment,
            vertex_input,
            colour_format: vk_format(key.colour_format),
            depth_format: key.depth_format.map(vk_format),
            blend: blend_state(key.blend, key.write_mask),
            depth_test: key.depth_test.map(vk_compare),
            depth_write: key.depth_write,
            cull_mode: match key.cull {
                Cull::None => vk::CullModeFlags::NONE,
                Cull::Back => vk::CullModeFlags::BACK,
            },
            layout,
        })?;
        self.pipelines.insert(key, pipeline);
        Ok(pipeline)
    }

    /// The plan a frame would record.
    pub fn plan(frame: &UploadedFrame, variant: Variant, format: TargetFormat) -> Plan<Draw> {
        Self::plan_with_resources(frame, variant, format).0
    }

    /// The plan and the graph's handles of the frame's images.
    fn plan_with_resources(
        frame: &UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> (Plan<Draw>, FrameResources) {
        let (graph, resources) = frame_graph(&frame.shape, variant, format);
        // The frame graph is well-formed by construction (lens names are unique, checked by
        // FrameInput::validate); a failure here is a bug in plan.rs.
        (
            graph.compile().expect("frame graphs always compile"),
            resources,
        )
    }

    /// Renders the frame and reads it back.
    pub fn render(
        &mut self,
        gpu: &Gpu,
        frame: &mut UploadedFrame,
        variant: Variant,
        format: TargetFormat,
    ) -> Result<(RenderedImage, FrameTimings), RenderError> {
        if variant == Variant::SinglePass
            && let Some(lens) = frame
                .shape
                .lenses
                .iter()
                .find(|l| l.layer_count() > super::MAX_LAYERS_SINGLE_PASS)
        {
            return Err(RenderError::BadInput(format!(
                "lens \"{}\" has {} layers; the single-pass variant supports at most {}: use the multipass variant",
                lens.name,
                lens.layer_count(),
                super::MAX_LAYERS_SINGLE_PASS
            )));
        }
        let start = Instant::now();
        let (plan, resources) = Self::plan_with_resources(frame, variant, format);
        let (width, height) = (frame.shape.width, frame.shape.height);
        if let std::collections::hash_map::Entry::Vacant(slot) = frame.targets.entry(format) {
            let colour_format = vk_format(format.graph_format());
            let targets = Targets {
                colour: Image::new(
                    gpu,
                    ImageDesc::colour_target("colour", colour_format, width, height),
                )?,
                depth: Image::new(gpu, ImageDesc::depth_target("depth", width, height))?,
                readback: Buffer::new(
                    gpu,
                    "readback",
                    u64::from(width)
                        * u64::from(height)
                        * u64::from(crate::gpu::format_bytes(colour_format)),
                    BufferUsage::Readback,
                )?,
            };
            slot.insert(targets);
        }
        // One pipeline per step (None for a readback), derived from the step's declaration.
        let mut pipelines = Vec::with_capacity(plan.steps.len());
        for step in &plan.steps {
            if let Some(key) = step.pass.pipeline_key(&plan.images) {
                pipelines.push(Some(self.pipeline(gpu, key)?));
            } else {
                pipelines.push(None);
            }
        }
        let command_buffer = self.command_buffer;
        let mut record_ms = 0.0;
        let execute_start = std::cell::Cell::new(Instant::now());
        gpu.record_submit_wait(command_buffer, |cb| {
            self.record(gpu, cb, (&plan, &resources), frame, format, &pipelines)?;
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

    fn record(
        &self,
        gpu: &Gpu,
        cb: vk::CommandBuffer,
        (plan, resources): (&Plan<Draw>, &FrameResources),
        frame: &UploadedFrame,
        format: TargetFormat,
        pipelines: &[Option<vk::Pipeline>],
    ) -> Result<(), GpuError> {
        let device = gpu.device();
        let targets = &frame.targets[&format];
        let (width, height) = (frame.shape.width, frame.shape.height);
        // The graph's image handles → the frame's Vulkan images (imported cube arrays never need
        // barriers within a frame: uploads leave them SHADER_READ_ONLY; mapped all the same).
        let image_of = |id: graph::ImageId| -> (vk::Image, vk::ImageAspectFlags, u32) {
            if id == resources.colour {
                return (targets.colour.handle, vk::ImageAspectFlags::COLOR, 1);
            }
            if id == resources.depth {
                return (targets.depth.handle, vk::ImageAspectFlags::DEPTH, 1);
            }
            resources
                .layers
                .iter()
                .zip(&frame.lenses)
                .flat_map(|(ids, lens)| ids.iter().zip(&lens.layers))
                .find(|(layer_id, _)| **layer_id == id)
                .map_or(
                    (vk::Image::null(), vk::ImageAspectFlags::COLOR, 1),
                    |(_, image)| {
                        (
                            image.handle,
                            vk::ImageAspectFlags::COLOR,
                            image.desc.array_layers,
                        )
                    },
                )
        };
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

        for (step, pipeline) in plan.steps.iter().zip(pipelines) {
            if !step.barriers.is_empty() {
                let barriers: Vec<vk::ImageMemoryBarrier2> = step
                    .barriers
                    .iter()
                    .map(|b| {
                        let (image, aspect, layers) = image_of(b.image);
                        let (src_stage, src_access) = vk_access(b.src);
                        let (dst_stage, dst_access) = vk_access(b.dst);
                        vk::ImageMemoryBarrier2::default()
                            .src_stage_mask(src_stage)
                            .src_access_mask(src_access)
                            .dst_stage_mask(dst_stage)
                            .dst_access_mask(dst_access)
                            .old_layout(vk_layout(b.old_layout))
                            .new_layout(vk_layout(b.new_layout))
                            .image(image)
                            .subresource_range(vk::ImageSubresourceRange {
                                aspect_mask: aspect,
                                base_mip_level: 0,
                                level_count: vk::REMAINING_MIP_LEVELS,
                                base_array_layer: 0,
                                layer_count: layers,
                            })
                    })
                    .collect();
                // SAFETY: recording; the barriers describe images alive for the submission.
                unsafe {
                    device.cmd_pipeline_barrier2(
                        cb,
                        &vk::DependencyInfo::default().image_memory_barriers(&barriers),
                    )
                };
            }
            if let Some(instance) = &step.begin {
                let clear = |load: LoadOp| match load {
                    LoadOp::Clear(c) => (vk::AttachmentLoadOp::CLEAR, c),
                    LoadOp::Load => (vk::AttachmentLoadOp::LOAD, [0.0; 4]),
                    LoadOp::DontCare => (vk::AttachmentLoadOp::DONT_CARE, [0.0; 4]),
                };
                let store = |s: StoreOp| match s {
                    StoreOp::Store => vk::AttachmentStoreOp::STORE,
                    StoreOp::DontCare => vk::AttachmentStoreOp::DONT_CARE,
                };
                let (colour_load, colour_clear) = clear(instance.colour.1);
                let colour = [vk::RenderingAttachmentInfo::default()
                    .image_view(targets.colour.view)
                    .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                    .load_op(colour_load)
                    .store_op(store(instance.colour.2))
                    .clear_value(vk::ClearValue {
                        color: vk::ClearColorValue {
                            float32: colour_clear,
                        },
                    })];
                let depth = instance.depth.map(|(_, load, s)| {
                    let (depth_load, depth_clear) = clear(load);
                    vk::RenderingAttachmentInfo::default()
                        .image_view(targets.depth.view)
                        .image_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL)
                        .load_op(depth_load)
                        .store_op(store(s))
                        .clear_value(vk::ClearValue {
                            depth_stencil: vk::ClearDepthStencilValue {
                                depth: depth_clear[0],
                                stencil: 0,
                            },
                        })
                });
                let mut rendering = vk::RenderingInfo::default()
                    .render_area(scissor)
                    .layer_count(1)
                    .color_attachments(&colour);
                if let Some(depth) = depth.as_ref() {
                    rendering = rendering.depth_attachment(depth);
                }
                // SAFETY: recording; attachments are in the layouts the plan's barriers set.
                unsafe {
                    device.cmd_begin_rendering(cb, &rendering);
                    device.cmd_set_viewport(cb, 0, &[viewport]);
                    device.cmd_set_scissor(cb, 0, &[scissor]);
                }
            }
            gpu.begin_label(cb, &step.pass.name);
            match &step.pass.kind {
                PassKind::Draw { draws, .. } => {
                    // Every draw pass has a pipeline (pipeline_key is Some for draws).
                    if let Some(pipeline) = *pipeline {
                        // SAFETY: recording inside a rendering instance with a compatible pipeline.
                        unsafe {
                            device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::GRAPHICS, pipeline)
                        };
                        for draw in draws {
                            self.record_draw(device, cb, frame, *draw);
                        }
                    }
                }
                PassKind::Readback { .. } => {
                    let region = vk::BufferImageCopy::default()
                        .image_subresource(vk::ImageSubresourceLayers {
                            aspect_mask: vk::ImageAspectFlags::COLOR,
                            mip_level: 0,
                            base_array_layer: 0,
                            layer_count: 1,
                        })
                        .image_extent(vk::Extent3D {
                            width,
                            height,
                            depth: 1,
                        });
                    let to_host = [vk::MemoryBarrier2::default()
                        .src_stage_mask(vk::PipelineStageFlags2::COPY)
                        .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                        .dst_stage_mask(vk::PipelineStageFlags2::HOST)
                        .dst_access_mask(vk::AccessFlags2::HOST_READ)];
                    // SAFETY: the colour target is TRANSFER_SRC after this step's barrier.
                    unsafe {
                        device.cmd_copy_image_to_buffer(
                            cb,
                            targets.colour.handle,
                            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                            targets.readback.handle,
                            &[region],
                        );
                        device.cmd_pipeline_barrier2(
                            cb,
                            &vk::DependencyInfo::default().memory_barriers(&to_host),
                        );
                    }
                }
            }
            gpu.end_label(cb);
            if step.end {
                // SAFETY: closes the instance begun by this run's first step.
                unsafe { device.cmd_end_rendering(cb) };
            }
        }
        Ok(())
    }

    fn record_draw(
        &self,
        device: &ash::Device,
        cb: vk::CommandBuffer,
        frame: &UploadedFrame,
        draw: Draw,
    ) {
        let lens_constants = |lens: &GpuLens| LensConstants {
            view_proj: frame.view_proj,
            weight_a: 0.0,
            weight_b: 0.0,
            layer_count: lens.layer_count,
            term_mask: u32::from(lens.fg_offset.contains_key(&Term::Refraction))
                | (u32::from(lens.fg_offset.contains_key(&Term::Reflection)) << 1),
            position_offset: 0,
            fg_offset_t: lens.fg_offset.get(&Term::Refraction).copied().unwrap_or(0),
            fg_offset_r: lens.fg_offset.get(&Term::Reflection).copied().unwrap_or(0),
            direction_offset_t: lens
                .direction_offset
                .get(&Term::Refraction)
                .copied()
                .unwrap_or(0),
            direction_offset_r: lens
                .direction_offset
                .get(&Term::Reflection)
                .copied()
                .unwrap_or(0),
            vertex_count: lens.vertex_count,
            layer: 0,
            _pad: 0,
        };
        let weight = |v: usize| frame.shape.viewpoint_weights.get(v).copied().unwrap_or(0.0);
        // SAFETY (all arms): recording inside a rendering instance with the matching pipeline bound;
        // buffers and sets live as long as `frame`.
        unsafe {
            match draw {
                Draw::Environment { mesh } => {
                    let mesh = &frame.environment[mesh];
                    device.cmd_push_constants(
                        cb,
                        self.environment_layout,
                        vk::ShaderStageFlags::VERTEX,
                        0,
                        bytemuck::bytes_of(&frame.view_proj),
                    );
                    device.cmd_bind_vertex_buffers(
                        cb,
                        0,
                        &[mesh.positions.handle, mesh.colours.handle],
                        &[0, 0],
                    );
                    device.cmd_bind_index_buffer(cb, mesh.indices.handle, 0, vk::IndexType::UINT32);
                    device.cmd_draw_indexed(cb, mesh.index_count, 1, 0, 0, 0);
                }
                Draw::LensZero { lens } | Draw::SinglePass { lens } | Draw::Layer { lens, .. } => {
                    let gpu_lens = &frame.lenses[lens];
                    let mut constants = lens_constants(gpu_lens);
                    let set = match draw {
                        Draw::Layer {
                            viewpoint,
                            term,
                            layer,
                            ..
                        } => {
                            constants.weight_a = weight(viewpoint);
                            constants.fg_offset_t = gpu_lens.fg_offset[&term];
                            constants.direction_offset_t = gpu_lens.direction_offset[&term]
                                + layer as u32 * gpu_lens.vertex_count;
                            constants.layer = layer as u32;
                            gpu_lens.sets[viewpoint]
                        }
                        _ => {
                            // The single pass blends the viewpoints with weight > 0 in order, as
                            // the plan's specialization counts them: binding 1 and weight_a are
                            // the first active viewpoint's, binding 2 and weight_b the second's.
                            let active: Vec<usize> = (0..gpu_lens.sets.len())
                                .filter(|&v| weight(v) > 0.0)
                                .collect();
                            let first = active.first().copied().unwrap_or(0);
                            constants.weight_a = weight(first);
                            constants.weight_b = active.get(1).map_or(0.0, |&v| weight(v));
                            gpu_lens.sets[first]
                        }
                    };
                    device.cmd_bind_descriptor_sets(
                        cb,
                        vk::PipelineBindPoint::GRAPHICS,
                        self.lens_layout,
                        0,
                        &[set],
                        &[],
                    );
                    device.cmd_push_constants(
                        cb,
                        self.lens_layout,
                        vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                        0,
                        bytemuck::bytes_of(&constants),
                    );
                    device.cmd_bind_index_buffer(
                        cb,
                        gpu_lens.indices.handle,
                        0,
                        vk::IndexType::UINT32,
                    );
                    device.cmd_draw_indexed(cb, gpu_lens.index_count, 1, 0, 0, 0);
                }
            }
        }
    }
}

/// Converts read-back texels to f32 RGBA.
fn decode(bytes: &[u8], format: TargetFormat, pixels: usize) -> Vec<[f32; 4]> {
    match format {
        TargetFormat::Rgba8 => bytes
            .chunks_exact(4)
            .take(pixels)
            .map(|c| [0, 1, 2, 3].map(|i| f32::from(c[i]) / 255.0))
            .collect(),
        TargetFormat::Rgba16f => bytes
            .chunks_exact(8)
            .take(pixels)
            .map(|c| {
                [0, 1, 2, 3].map(|i| half::f16::from_le_bytes([c[2 * i], c[2 * i + 1]]).to_f32())
            })
            .collect(),
        TargetFormat::Rgba32f => bytes
            .chunks_exact(16)
            .take(pixels)
            .map(|c| {
                [0, 1, 2, 3].map(|i| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                })
            })
            .collect(),
    }
}
