//! Descriptor sets as data, and the one place they are pooled, allocated and written. A layout is
//! a list of [`Binding`]s (binding i is the list's entry i), made from a shader's generated set
//! ([`Binding::of_shader`]) or written out; pools are sized from it, and a set is written from one
//! [`Resource`] per binding with the descriptor types the list gives, so a layout, its pool and
//! its writes cannot disagree. [`SetLayout`] and [`DescriptorPool`] own their Vulkan objects.

use std::sync::Arc;

use ash::vk;

use super::{Buffer, Gpu, GpuError, VkContext, context::Shared};

/// One binding of a descriptor-set layout: one descriptor of `ty`, read by `stage`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Binding {
    /// The descriptor type.
    pub(crate) ty: vk::DescriptorType,
    /// The shader stage that reads it.
    pub(crate) stage: vk::ShaderStageFlags,
}

impl Binding {
    /// One descriptor of `ty`, read by `stage`.
    pub(crate) const fn new(ty: vk::DescriptorType, stage: vk::ShaderStageFlags) -> Binding {
        Binding { ty, stage }
    }

    /// The bindings of a shader's set as `shaders/build.rs` generated it, read by the stages
    /// whose entry points use them.
    pub(crate) fn of_shader(set: &[lensmap_shaders::Binding]) -> Vec<Binding> {
        set.iter()
            .map(|b| {
                let ty = match b.kind {
                    lensmap_shaders::BindingKind::StorageRead
                    | lensmap_shaders::BindingKind::StorageReadWrite => {
                        vk::DescriptorType::STORAGE_BUFFER
                    }
                    lensmap_shaders::BindingKind::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
                    lensmap_shaders::BindingKind::SampledImage => vk::DescriptorType::SAMPLED_IMAGE,
                    lensmap_shaders::BindingKind::Sampler => vk::DescriptorType::SAMPLER,
                    lensmap_shaders::BindingKind::AccelerationStructure => {
                        vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
                    }
                };
                let mut stage = vk::ShaderStageFlags::empty();
                for (bit, flag) in [
                    (lensmap_shaders::STAGE_VERTEX, vk::ShaderStageFlags::VERTEX),
                    (
                        lensmap_shaders::STAGE_FRAGMENT,
                        vk::ShaderStageFlags::FRAGMENT,
                    ),
                    (
                        lensmap_shaders::STAGE_COMPUTE,
                        vk::ShaderStageFlags::COMPUTE,
                    ),
                ] {
                    if b.stages & bit != 0 {
                        stage |= flag;
                    }
                }
                Binding { ty, stage }
            })
            .collect()
    }
}

/// A descriptor-set layout that destroys itself, with its bindings.
pub(crate) struct SetLayout {
    shared: Arc<Shared>,
    pub(crate) handle: vk::DescriptorSetLayout,
    pub(crate) bindings: Vec<Binding>,
}

impl SetLayout {
    /// The layout of `bindings`.
    pub(crate) fn new(gpu: &Gpu, bindings: Vec<Binding>) -> Result<SetLayout, GpuError> {
        Ok(SetLayout {
            shared: gpu.shared.clone(),
            handle: create_set_layout(gpu, &bindings)?,
            bindings,
        })
    }
}

impl Drop for SetLayout {
    fn drop(&mut self) {
        // SAFETY: the owner waited for every use of the layout's pipelines and sets.
        unsafe {
            self.shared
                .device
                .destroy_descriptor_set_layout(self.handle, None)
        };
    }
}

/// A descriptor set, allocated from a [`DescriptorPool`] that outlives its uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DescriptorSet(pub(crate) vk::DescriptorSet);

impl Resource {
    /// A whole buffer.
    pub(crate) fn buffer(buffer: &Buffer) -> Resource {
        Resource::Buffer(buffer.handle)
    }
}

/// Creates the set layout of `bindings`.
pub(crate) fn create_set_layout(
    gpu: &Gpu,
    bindings: &[Binding],
) -> Result<vk::DescriptorSetLayout, GpuError> {
    let bindings: Vec<vk::DescriptorSetLayoutBinding> = bindings
        .iter()
        .enumerate()
        .map(|(index, b)| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(index as u32)
                .descriptor_type(b.ty)
                .descriptor_count(1)
                .stage_flags(b.stage)
        })
        .collect();
    // SAFETY: the create info lives until the call returns; the caller destroys the layout.
    unsafe {
        gpu.device().create_descriptor_set_layout(
            &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
            None,
        )
    }
    .vk("vkCreateDescriptorSetLayout")
}

/// What one binding of a set is pointed at.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Resource {
    /// A whole buffer.
    Buffer(vk::Buffer),
    /// An image view, in `SHADER_READ_ONLY_OPTIMAL`.
    Image(vk::ImageView),
    /// A sampler.
    Sampler(vk::Sampler),
    /// A top-level acceleration structure, for ray queries.
    AccelerationStructure(vk::AccelerationStructureKHR),
}

/// Points binding i of `set` (of the layout `bindings`) at `resources[i]`. The set must not be
/// in use by a pending submission.
pub(crate) fn write_set(
    gpu: &Gpu,
    set: vk::DescriptorSet,
    bindings: &[Binding],
    resources: &[Resource],
) {
    debug_assert_eq!(bindings.len(), resources.len(), "one resource per binding");
    let buffers: Vec<[vk::DescriptorBufferInfo; 1]> = resources
        .iter()
        .map(|resource| match *resource {
            Resource::Buffer(buffer) => [vk::DescriptorBufferInfo {
                buffer,
                offset: 0,
                range: vk::WHOLE_SIZE,
            }],
            _ => Default::default(),
        })
        .collect();
    let images: Vec<[vk::DescriptorImageInfo; 1]> = resources
        .iter()
        .map(|resource| match *resource {
            Resource::Image(image_view) => [vk::DescriptorImageInfo {
                sampler: vk::Sampler::null(),
                image_view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            }],
            Resource::Sampler(sampler) => [vk::DescriptorImageInfo {
                sampler,
                ..Default::default()
            }],
            _ => Default::default(),
        })
        .collect();
    let structures: Vec<[vk::AccelerationStructureKHR; 1]> = resources
        .iter()
        .map(|resource| match *resource {
            Resource::AccelerationStructure(structure) => [structure],
            _ => Default::default(),
        })
        .collect();
    let mut structure_infos: Vec<vk::WriteDescriptorSetAccelerationStructureKHR> = structures
        .iter()
        .map(|s| {
            vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(s)
        })
        .collect();
    let writes: Vec<vk::WriteDescriptorSet> = bindings
        .iter()
        .zip(resources)
        .zip(&mut structure_infos)
        .enumerate()
        .map(|(index, ((binding, resource), structure))| {
            let write = vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(index as u32)
                .descriptor_type(binding.ty);
            match resource {
                Resource::Buffer(_) => write.buffer_info(&buffers[index]),
                Resource::Image(_) | Resource::Sampler(_) => write.image_info(&images[index]),
                Resource::AccelerationStructure(_) => {
                    write.descriptor_count(1).push_next(structure)
                }
            }
        })
        .collect();
    // SAFETY: the caller says the set is not in use; the infos live until return.
    unsafe { gpu.device().update_descriptor_sets(&writes, &[]) };
}

/// A descriptor pool that destroys itself; its sets are freed with it, or reset together when a
/// frame is uploaded into it again.
pub(crate) struct DescriptorPool {
    shared: Arc<Shared>,
    handle: vk::DescriptorPool,
    /// Sets it was sized for.
    capacity: u32,
}

impl DescriptorPool {
    /// A pool for `sets` sets of the layout `bindings`.
    pub(crate) fn new(
        gpu: &Gpu,
        bindings: &[Binding],
        sets: u32,
    ) -> Result<DescriptorPool, GpuError> {
        // Per descriptor type, in the order the layout first names it: its count per set × sets.
        let mut sizes: Vec<vk::DescriptorPoolSize> = Vec::new();
        for binding in bindings {
            match sizes.iter_mut().find(|size| size.ty == binding.ty) {
                Some(size) => size.descriptor_count += sets,
                None => sizes.push(vk::DescriptorPoolSize {
                    ty: binding.ty,
                    descriptor_count: sets,
                }),
            }
        }
        // SAFETY: valid create info; destroyed by Drop.
        let handle = unsafe {
            gpu.device().create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(sets)
                    .pool_sizes(&sizes),
                None,
            )
        }
        .vk("vkCreateDescriptorPool")?;
        Ok(DescriptorPool {
            shared: gpu.shared.clone(),
            handle,
            capacity: sets,
        })
    }

    /// Sets it was sized for.
    pub(crate) fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Allocates `count` sets of `layout` (which must be one of the layouts the pool was sized
    /// for, with room left for them).
    pub(crate) fn allocate(
        &self,
        layout: vk::DescriptorSetLayout,
        count: usize,
    ) -> Result<Vec<vk::DescriptorSet>, GpuError> {
        let layouts = vec![layout; count];
        // SAFETY: the pool was sized for its sets; it is destroyed with its owner, after the
        // sets' last use.
        unsafe {
            self.shared.device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(self.handle)
                    .set_layouts(&layouts),
            )
        }
        .vk("vkAllocateDescriptorSets")
    }

    /// Allocates one set of `layout` and points its bindings at `resources`.
    pub(crate) fn allocate_one(
        &self,
        gpu: &Gpu,
        layout: &SetLayout,
        resources: &[Resource],
    ) -> Result<DescriptorSet, GpuError> {
        let set = self
            .allocate(layout.handle, 1)?
            .pop()
            .ok_or(GpuError::Vulkan {
                call: "vkAllocateDescriptorSets",
                result: vk::Result::ERROR_OUT_OF_POOL_MEMORY,
            })?;
        write_set(gpu, set, &layout.bindings, resources);
        Ok(DescriptorSet(set))
    }

    /// Frees every set of the pool at once. No submission that uses them may be pending.
    pub(crate) fn reset(&self) -> Result<(), GpuError> {
        // SAFETY: the caller waited for the sets' last use (UploadedFrame::last_submission).
        unsafe {
            self.shared
                .device
                .reset_descriptor_pool(self.handle, vk::DescriptorPoolResetFlags::empty())
        }
        .vk("vkResetDescriptorPool")
    }
}

impl Drop for DescriptorPool {
    fn drop(&mut self) {
        // SAFETY: the owner waited for the sets' last use before dropping the pool (an uploaded
        // frame waits for its last submission; a cached mesh is dropped by its last owner after
        // that). No idle wait: evicting a moving sky dome's mesh must not stall frames in flight.
        unsafe {
            self.shared
                .device
                .destroy_descriptor_pool(self.handle, None)
        };
    }
}
