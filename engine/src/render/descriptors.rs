//! The compositor's descriptor-set layouts as data (the pooling, allocating and writing of sets
//! is [`crate::gpu::descriptors`]'s).

use ash::vk;

use super::MAX_VIEWPOINTS;
pub(crate) use crate::gpu::descriptors::{Binding, DescriptorPool, Resource, write_set};

const fn binding(ty: vk::DescriptorType, stage: vk::ShaderStageFlags) -> Binding {
    Binding::new(ty, stage)
}

/// Set 0 of the lens programs: the lens data (storage buffer, read by the vertex stage), one
/// cube-map array per viewpoint sample the single pass blends (bindings 1 ..=
/// [`MAX_VIEWPOINTS`]: `layers_a`, `_b`, `_c` of `lens.wgsl`; a layer pass reads binding 1),
/// and the sampler.
pub(crate) const LENS_SET: &[Binding] = &[
    binding(
        vk::DescriptorType::STORAGE_BUFFER,
        vk::ShaderStageFlags::VERTEX,
    ),
    binding(
        vk::DescriptorType::SAMPLED_IMAGE,
        vk::ShaderStageFlags::FRAGMENT,
    ),
    binding(
        vk::DescriptorType::SAMPLED_IMAGE,
        vk::ShaderStageFlags::FRAGMENT,
    ),
    binding(
        vk::DescriptorType::SAMPLED_IMAGE,
        vk::ShaderStageFlags::FRAGMENT,
    ),
    binding(vk::DescriptorType::SAMPLER, vk::ShaderStageFlags::FRAGMENT),
];

// The data, a cube-map array per viewpoint, the sampler.
const _: () = assert!(LENS_SET.len() == MAX_VIEWPOINTS + 2);

/// Set 0 of the environment program: the mesh's light map and its sampler.
pub(crate) const ENVIRONMENT_SET: &[Binding] = &[
    binding(
        vk::DescriptorType::SAMPLED_IMAGE,
        vk::ShaderStageFlags::FRAGMENT,
    ),
    binding(vk::DescriptorType::SAMPLER, vk::ShaderStageFlags::FRAGMENT),
];

/// One image read with texel fetches: the box filter's colour target, the scratch images the
/// group sum adds and the programmable layer reads.
pub(crate) const SAMPLED_IMAGE_SET: &[Binding] = &[binding(
    vk::DescriptorType::SAMPLED_IMAGE,
    vk::ShaderStageFlags::FRAGMENT,
)];
