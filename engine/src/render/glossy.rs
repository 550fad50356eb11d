//! Glossy objects in a compositor frame: what the glossy pass draws (reflection-space IBR,
//! [`crate::rsibr`]), its checks, and its upload: the mesh's vertex buffers (cached like the
//! environment meshes), the slots' maps as one cube-map array (cached like layered EMs), and the
//! draw's data in a storage buffer (`GlossyData` of `shaders/wgsl/glossy.wgsl`).

use std::sync::Arc;

use ash::vk;
use glam::{Mat3, Vec3};

use super::RenderError;
use super::descriptors::{Binding, DescriptorPool, Resource};
use crate::cubemap::CubeMap;
use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError, Image};
use crate::rsibr::MapLobe;
use crate::scene::Glossy;

/// The most view samples one glossy draw blends (a spherical triangle's three).
pub const MAX_GLOSSY_SLOTS: usize = 3;

/// A glossy object's triangles: positions and unit shading normals.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyMesh {
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex unit normals.
    pub normals: Vec<Vec3>,
    /// Triangles (both sides are drawn).
    pub triangles: Vec<[u32; 3]>,
}

/// One view sample a glossy draw blends.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossySlot {
    /// Its weight (the slots' weights need not sum to 1: the blend divides by them).
    pub weight: f32,
    /// The rotation of lookup directions into its maps ([`crate::rsibr::ViewSlot::rotation`]).
    pub rotation: Mat3,
    /// Its maps, one per lobe of the draw, premultiplied by confidence, all of one size.
    pub maps: Vec<Arc<CubeMap>>,
}

/// A glossy object drawn by the glossy pass: opaque, after the environment, depth tested.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyDraw {
    /// The object's name (pass labels).
    pub name: String,
    /// Its triangles; shared like the environment meshes.
    pub mesh: Arc<GlossyMesh>,
    /// Its BRDF (the coat's index of refraction is read).
    pub brdf: Glossy,
    /// Its lobes, one to three, in map order.
    pub lobes: Vec<MapLobe>,
    /// One to [`MAX_GLOSSY_SLOTS`] view samples.
    pub slots: Vec<GlossySlot>,
    /// The camera position, metres (each fragment's view direction starts there).
    pub eye: Vec3,
}

fn bad<T>(message: String) -> Result<T, RenderError> {
    Err(RenderError::BadInput(message))
}

impl GlossyDraw {
    /// Glossy draw `g`'s sizes, indices and values; the contents of maps `checked` knows (by the
    /// address of their `Arc`) are not scanned again.
    pub(super) fn validate(
        &self,
        g: usize,
        checked: &dyn Fn(usize) -> bool,
    ) -> Result<(), RenderError> {
        let at = format!("glossy[{g}] ({})", self.name);
        let mesh = &self.mesh;
        if mesh.triangles.is_empty() {
            return bad(format!("{at}.mesh has no triangles; leave the draw out"));
        }
        if mesh.normals.len() != mesh.positions.len()
            || mesh
                .normals
                .iter()
                .any(|n| !n.is_finite() || *n == Vec3::ZERO)
            || mesh.positions.iter().any(|p| !p.is_finite())
        {
            return bad(format!(
                "{at}.mesh needs finite positions and one finite, non-zero normal per position ({} normals for {} positions)",
                mesh.normals.len(),
                mesh.positions.len()
            ));
        }
        if let Some(t) = mesh
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= mesh.positions.len()))
        {
            return bad(format!(
                "{at}.mesh.triangles[{t}] indexes past the positions"
            ));
        }
        if !self.eye.is_finite() {
            return bad(format!("{at}.eye has NaN or infinite values"));
        }
        if self.lobes.is_empty() || self.lobes.len() > MapLobe::ALL.len() {
            return bad(format!(
                "{at}.lobes has {} entries; give 1 to 3",
                self.lobes.len()
            ));
        }
        if self.slots.is_empty() || self.slots.len() > MAX_GLOSSY_SLOTS {
            return bad(format!(
                "{at}.slots has {} entries; give 1 to {MAX_GLOSSY_SLOTS}",
                self.slots.len()
            ));
        }
        if let Some(coat) = self
            .brdf
            .coat
            .filter(|c| !(c.ior.is_finite() && c.ior > 1.0))
        {
            return bad(format!(
                "{at}.brdf.coat.ior {} must be finite and > 1",
                coat.ior
            ));
        }
        let size = self.slots[0].maps.first().map_or(1, |m| m.size);
        for (s, slot) in self.slots.iter().enumerate() {
            if !(slot.weight.is_finite() && slot.weight >= 0.0 && slot.rotation.is_finite()) {
                return bad(format!(
                    "{at}.slots[{s}]: the weight must be finite and ≥ 0, the rotation finite"
                ));
            }
            if slot.maps.len() != self.lobes.len() {
                return bad(format!(
                    "{at}.slots[{s}].maps has {} maps for {} lobes; give one per lobe",
                    slot.maps.len(),
                    self.lobes.len()
                ));
            }
            for (k, map) in slot.maps.iter().enumerate() {
                let known = checked(Arc::as_ptr(map) as usize);
                let result = if known && map.size == size {
                    Ok(())
                } else {
                    map.validate(Some(size))
                };
                if let Err(error) = result {
                    return bad(format!("{at}.slots[{s}].maps[{k}]: {error}"));
                }
            }
        }
        Ok(())
    }

    /// The maps in the order of the cube-map array: slot by slot, lobe by lobe.
    pub(super) fn flat_maps(&self) -> Vec<Arc<CubeMap>> {
        self.slots
            .iter()
            .flat_map(|s| s.maps.iter().cloned())
            .collect()
    }

    /// `GlossyData` of `glossy.wgsl` (std430): view-projection, eye and slot count, weights and
    /// coat index, lobe kinds and count, three rotations.
    pub(super) fn data(&self, view_proj: &glam::Mat4) -> Vec<u8> {
        let mut floats: Vec<f32> = view_proj.to_cols_array().to_vec();
        floats.extend(self.eye.to_array());
        floats.push(self.slots.len() as f32);
        let mut weights = [0.0f32; 4];
        for (w, slot) in weights.iter_mut().zip(&self.slots) {
            *w = slot.weight;
        }
        weights[3] = self.brdf.coat.map_or(0.0, |c| c.ior);
        floats.extend(weights);
        let mut kinds = [0u32; 4];
        for (kind, lobe) in kinds.iter_mut().zip(&self.lobes) {
            *kind = match lobe {
                MapLobe::Diffuse => 0,
                MapLobe::Specular => 1,
                MapLobe::Coat => 2,
            };
        }
        kinds[3] = self.lobes.len() as u32;
        floats.extend(kinds.map(f32::from_bits));
        for s in 0..MAX_GLOSSY_SLOTS {
            let rotation = self
                .slots
                .get(s)
                .map_or(Mat3::IDENTITY, |slot| slot.rotation);
            floats.extend(glam::Mat4::from_mat3(rotation).to_cols_array());
        }
        bytemuck::cast_slice(&floats).to_vec()
    }
}

/// Set 0 of the glossy program: the draw's data, the maps' cube-map array, the sampler.
pub(crate) const GLOSSY_SET: &[Binding] = &[
    Binding {
        ty: vk::DescriptorType::STORAGE_BUFFER,
        stage: vk::ShaderStageFlags::from_raw(
            vk::ShaderStageFlags::VERTEX.as_raw() | vk::ShaderStageFlags::FRAGMENT.as_raw(),
        ),
    },
    Binding {
        ty: vk::DescriptorType::SAMPLED_IMAGE,
        stage: vk::ShaderStageFlags::FRAGMENT,
    },
    Binding {
        ty: vk::DescriptorType::SAMPLER,
        stage: vk::ShaderStageFlags::FRAGMENT,
    },
];

/// A glossy mesh's vertex and index buffers.
pub(super) struct GpuGlossyMesh {
    pub(super) positions: Buffer,
    pub(super) normals: Buffer,
    pub(super) indices: Buffer,
    pub(super) index_count: u32,
}

impl GpuGlossyMesh {
    /// Uploads `mesh`.
    pub(super) fn new(gpu: &Gpu, mesh: &GlossyMesh) -> Result<GpuGlossyMesh, GpuError> {
        let floats = |v: &[Vec3]| -> Vec<u8> {
            bytemuck::cast_slice(&v.iter().map(|p| p.to_array()).collect::<Vec<_>>()).to_vec()
        };
        Ok(GpuGlossyMesh {
            positions: Buffer::with_data(
                gpu,
                "glossy positions",
                &floats(&mesh.positions),
                BufferUsage::Vertex,
            )?,
            normals: Buffer::with_data(
                gpu,
                "glossy normals",
                &floats(&mesh.normals),
                BufferUsage::Vertex,
            )?,
            indices: Buffer::with_data(
                gpu,
                "glossy indices",
                bytemuck::cast_slice(&mesh.triangles),
                BufferUsage::Index,
            )?,
            index_count: (mesh.triangles.len() * 3) as u32,
        })
    }
}

/// One glossy draw uploaded: its mesh, maps, data and descriptor set.
pub(super) struct GpuGlossy {
    pub(super) mesh: Arc<GpuGlossyMesh>,
    /// Kept alive for the descriptor set.
    _maps: Arc<Image>,
    _data: Buffer,
    /// The pool of `set` (no submission using it is pending when the frame drops).
    _pool: DescriptorPool,
    pub(super) set: vk::DescriptorSet,
}

/// The layout and sampler a glossy draw's set is made with.
pub(super) struct GlossySampling<'a> {
    /// Set 0 of the glossy program.
    pub(super) layout: &'a crate::gpu::descriptors::SetLayout,
    /// The maps' sampler.
    pub(super) sampler: vk::Sampler,
}

impl GpuGlossy {
    /// The draw's set of `sampling`'s layout, pointing at `data` (its `GlossyData`), `maps`
    /// and the sampler.
    pub(super) fn new(
        gpu: &Gpu,
        sampling: GlossySampling<'_>,
        mesh: Arc<GpuGlossyMesh>,
        maps: Arc<Image>,
        data: &[u8],
    ) -> Result<GpuGlossy, GpuError> {
        let data = Buffer::with_data(gpu, "glossy data", data, BufferUsage::Storage)?;
        let pool = DescriptorPool::new(gpu, GLOSSY_SET, 1)?;
        let set = pool
            .allocate_one(
                gpu,
                sampling.layout,
                &[
                    Resource::Buffer(data.handle),
                    Resource::Image(maps.view),
                    Resource::Sampler(sampling.sampler),
                ],
            )?
            .0;
        Ok(GpuGlossy {
            mesh,
            _maps: maps,
            _data: data,
            _pool: pool,
            set,
        })
    }
}
