//! Uploading a frame: the lens objects' per-vertex data and indices into buffers, their layered
//! EMs into cube-map arrays, the environment meshes into vertex buffers and their light maps into
//! RGBA16F textures (each mesh with its own descriptor set), one descriptor set per (lens,
//! viewpoint) and one for each lens object's single pass, and the targets of each framebuffer
//! format on first use. Layered EMs and environment meshes (light maps included) are cached by
//! the identity of their `Arc`s, so frames that hand over the same maps and meshes upload them
//! once. Before anything is uploaded, the frame's maps are checked against the device's budget
//! for maps ([`super::budget`]).

use std::{collections::HashMap, sync::Arc};

use ash::vk;

use super::{
    DeviceLensPart, EnvironmentMesh, FrameInput, FrameShape, LensObject, MAX_VIEWPOINTS, MapBytes,
    RenderError, SinglePassLimits, TargetFormat,
    descriptors::{DescriptorPool, ENVIRONMENT_SET, LENS_SET, Resource, write_set},
    pipelines::Pipelines,
    targets::Targets,
};
use crate::{
    cubemap::CubeMap,
    gpu::{Buffer, BufferUsage, Gpu, GpuError, Image, ImageDesc, Timeline},
    index::LensIndex,
    trace::Term,
};

/// A lens object's data on the GPU: its layered EMs and the parts it is drawn in.
pub(super) struct GpuLens {
    /// Its terms in the order its data holds them.
    pub(super) terms: Vec<Term>,
    pub(super) layer_count: u32,
    /// One cube-map array per viewpoint sample (shared with the renderer's cache).
    pub(super) layers: Vec<Arc<Image>>,
    /// What is drawn: the host's mesh (one part), or a resident object's parts.
    pub(super) parts: Vec<LensPart>,
    /// The compute work that makes a resident object's parts, recorded by the frame's first
    /// submission (held until the frame is uploaded over or dropped, after its submissions).
    pub(super) works: Vec<Arc<super::compute::ComputeWork>>,
}

/// Where a lens part's data and indices are and how many to draw.
pub(super) enum PartBuffers {
    /// Uploaded from the host.
    Host(Box<HostPart>),
    /// The GPU tessellation's own buffers, drawn by the indirect draws it wrote (kept alive until
    /// the frame's last submission completed).
    Device(Arc<DeviceLensPart>),
}

/// A lens part uploaded from the host: kept, and rewritten in place, by the next frame uploaded
/// into the same [`UploadedFrame`] when large enough. The last `hull_index_count` of
/// `index_count` indices are drawn without layer 0 (three per hull triangle of the convex-hull
/// split, [`LensObject::hull_triangles`](super::LensObject::hull_triangles)).
pub(super) struct HostPart {
    data: Buffer,
    pub(super) indices: Buffer,
    pub(super) index_count: u32,
    pub(super) hull_index_count: u32,
}

/// One mesh of a lens object with its vertex data and descriptor sets.
pub(super) struct LensPart {
    pub(super) buffers: PartBuffers,
    /// vec4s between the arrays of the data buffer (its vertex count, or the tessellation's
    /// capacity).
    pub(super) stride: u32,
    /// One descriptor set per viewpoint, for its layer passes (every cube-map binding that
    /// viewpoint's).
    pub(super) sets: Vec<vk::DescriptorSet>,
    /// The single pass's set: bindings 1, 2, … the viewpoints with a weight above zero, in order
    /// (the last one repeated in bindings past them).
    pub(super) single_pass_set: vk::DescriptorSet,
}

impl LensPart {
    /// The data buffer the sets point at.
    fn data(&self) -> vk::Buffer {
        match &self.buffers {
            PartBuffers::Host(host) => host.data.handle,
            PartBuffers::Device(part) => part.data.handle,
        }
    }
}

impl GpuLens {
    /// Offsets (vec4 units) in a part's data of `term`'s F·G and of its layer 0's directions:
    /// the positions first, then per term F·G and one array per layer, `stride` apart.
    pub(super) fn offsets(&self, term: Term, stride: u32) -> Option<(u32, u32)> {
        let slot = self.terms.iter().position(|&t| t == term)? as u32;
        let fg = stride * (1 + slot * (1 + self.layer_count));
        Some((fg, fg + stride))
    }
}

/// An environment mesh's vertex and index buffers, its light map (a shared white 1×1 map for a
/// mesh without one) and the descriptor set that binds it, from a pool of its own (the mesh
/// outlives frames in the cache).
pub(super) struct GpuMesh {
    pub(super) positions: Buffer,
    pub(super) colours: Buffer,
    pub(super) uvs: Buffer,
    pub(super) indices: Buffer,
    pub(super) index_count: u32,
    /// Kept alive for the descriptor set.
    _light_map: Arc<Image>,
    /// The pool of `set`: no submission using the set is pending when the mesh drops, as every
    /// uploaded frame holds its meshes until its last submission completed.
    _descriptor_pool: DescriptorPool,
    pub(super) set: vk::DescriptorSet,
}

/// A frame's data uploaded once and rendered any number of times, in any variant and format.
///
/// Its buffers, descriptor pool and targets are reusable: uploading the next frame *into* it
/// ([`super::Renderer::upload_into`]) rewrites the mapped lens buffers in place (growing them only
/// when a frame needs more), resets the descriptor pool instead of creating one, and keeps the
/// colour, depth and readback targets of the same size, so a steady stream of frames allocates
/// nothing but each glossy draw's small data buffer and descriptor set (its mesh and maps are
/// cached).
pub struct UploadedFrame {
    pub(super) shape: FrameShape,
    /// What the single pass composites on the device the frame was uploaded to.
    pub(super) single_pass: SinglePassLimits,
    pub(super) view_proj: [[f32; 4]; 4],
    pub(super) environment: Vec<Arc<GpuMesh>>,
    pub(super) glossy: Vec<super::glossy::GpuGlossy>,
    pub(super) lenses: Vec<GpuLens>,
    /// The pool of the lens descriptor sets (`None` only while a new frame takes it over).
    pool: Option<DescriptorPool>,
    pub(super) targets: HashMap<TargetFormat, Targets>,
    /// The timeline value of the last submission that reads this frame (0: none) and the
    /// timeline it counts on: the frame is not changed or freed before it completes.
    pub(super) last_submission: Option<(Arc<Timeline>, u64)>,
}

impl Drop for UploadedFrame {
    fn drop(&mut self) {
        // The pool, buffers and targets die after this: their last use must have completed.
        if let Some((timeline, value)) = &self.last_submission {
            let _ = timeline.wait(*value);
        }
    }
}

impl UploadedFrame {
    /// The frame's shape (what its plan depends on).
    pub fn shape(&self) -> &FrameShape {
        &self.shape
    }
}

/// The renderer's uploads that outlive one frame, by `Arc` identity.
#[derive(Default)]
pub(super) struct UploadCache {
    /// Uploaded layered EMs, keyed by the identity of their `Arc<CubeMap>`s: a frame that hands
    /// over the same maps as a recent one reuses their cube-map array instead of uploading again.
    layer_cache: HashMap<Vec<usize>, CachedLayers>,
    /// Uploaded environment meshes, keyed by the identity of their `Arc<EnvironmentMesh>`.
    mesh_cache: HashMap<usize, CachedMesh>,
    /// Uploaded glossy meshes, keyed by the identity of their `Arc<GlossyMesh>` (held, so the
    /// address stays unique), with the upload generation that last used them.
    glossy_cache: HashMap<
        usize,
        (
            Arc<super::GlossyMesh>,
            Arc<super::glossy::GpuGlossyMesh>,
            u64,
        ),
    >,
    /// Uploads so far (for evicting cache entries no recent frame used).
    generation: u64,
    /// The white 1×1 light map of meshes without one, made on first use.
    white: Option<Arc<Image>>,
    /// Cube maps whose texels were validated and scanned for emptiness, by the identity of their
    /// `Arc` (held, so the address stays unique): frames that hand over the same maps are not
    /// scanned again.
    checked_cubes: HashMap<usize, CheckedCube>,
}

/// A validated cube map.
struct CheckedCube {
    _cube: Arc<CubeMap>,
    /// Whether every texel is zero (its pass changes nothing and is not recorded).
    empty: bool,
    last_used: u64,
}

/// One uploaded environment mesh and the mesh it holds (kept so its address stays unique).
struct CachedMesh {
    _mesh: Arc<EnvironmentMesh>,
    buffers: Arc<GpuMesh>,
    last_used: u64,
}

/// One uploaded cube-map array and the maps it holds (kept so their addresses stay unique).
struct CachedLayers {
    _maps: Vec<Arc<CubeMap>>,
    image: Arc<Image>,
    last_used: u64,
}

fn vec4_bytes<'a>(faces: impl IntoIterator<Item = &'a [[f32; 4]]> + Clone) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(faces.clone().into_iter().map(|f| f.len() * 16).sum());
    for face in faces {
        if cfg!(target_endian = "little") {
            // The same bytes as the per-value conversion below, copied at once (a test rendering
            // uploads a 2 MiB map, and the per-value path would take most of its upload time).
            bytes.extend_from_slice(bytemuck::cast_slice(face));
        } else {
            bytes.extend(face.iter().flatten().flat_map(|v| v.to_le_bytes()));
        }
    }
    bytes
}

impl UploadCache {
    /// Validates and uploads a frame's data, into `previous` when given (its last submission
    /// must have completed): its lens buffers, descriptor pool and targets are reused where they
    /// are large enough. Layered EMs and environment meshes already uploaded for one of the last
    /// two frames (the same `Arc`s) are reused, and their contents are not validated again.
    pub(super) fn upload(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        frame: &FrameInput,
        previous: Option<UploadedFrame>,
    ) -> Result<UploadedFrame, RenderError> {
        super::budget::check_dimensions(gpu, frame.width, frame.height)?;
        frame.validate_unless_checked(&|address| {
            self.mesh_cache.contains_key(&address)
                || self.checked_cubes.contains_key(&address)
                || self.layer_cache.keys().any(|key| key.contains(&address))
        })?;
        // Before anything is allocated: the frame's maps, each once (those already resident from
        // a recent frame included, as this frame needs them resident too). A recent frame's maps
        // that this one does not reuse are released with that frame and are not counted.
        super::budget::check_map_budget(gpu, &MapBytes::of_frame(frame))?;
        self.generation += 1;
        let generation = self.generation;
        for cube in frame.lenses.iter().flat_map(|l| l.layers.iter().flatten()) {
            self.checked_cubes
                .entry(Arc::as_ptr(cube) as usize)
                .and_modify(|checked| checked.last_used = generation)
                .or_insert_with(|| CheckedCube {
                    _cube: cube.clone(),
                    empty: cube.is_all_zero(),
                    last_used: generation,
                });
        }
        let environment = frame
            .environment
            .iter()
            .filter(|m| !m.triangles.is_empty())
            .map(|mesh| self.environment_mesh(gpu, pipelines, mesh))
            .collect::<Result<Vec<_>, GpuError>>()?;
        let glossy = frame
            .glossy
            .iter()
            .enumerate()
            .map(|(g, draw)| self.glossy_draw(gpu, pipelines, g, draw, &frame.view_proj))
            .collect::<Result<Vec<_>, GpuError>>()?;

        // Per lens part a set per viewpoint and the single pass's.
        let set_count = frame
            .lenses
            .iter()
            .map(|l| (l.layers.len() + 1) * l.resident.as_ref().map_or(1, |r| r.parts.len()))
            .sum::<usize>()
            .max(1) as u32;
        let (width, height) = (frame.width, frame.height);
        let (pool, targets, mut old_lenses) = match previous {
            Some(mut previous) => {
                if let Some((timeline, value)) = previous.last_submission.take() {
                    timeline.wait(value)?;
                }
                let pool = previous.pool.take();
                let targets = std::mem::take(&mut previous.targets);
                let lenses = std::mem::take(&mut previous.lenses);
                let same_size = previous.shape.width == width && previous.shape.height == height;
                (
                    pool,
                    if same_size { targets } else { HashMap::new() },
                    lenses,
                )
            }
            None => (None, HashMap::new(), Vec::new()),
        };
        let pool = match pool {
            Some(pool) if pool.capacity() >= set_count => {
                pool.reset()?;
                pool
            }
            _ => DescriptorPool::new(gpu, LENS_SET, set_count)?,
        };
        let checked = &self.checked_cubes;
        let shape = FrameShape::of(frame, |cube| {
            checked
                .get(&(Arc::as_ptr(cube) as usize))
                .is_some_and(|c| c.empty)
        });
        let mut lenses = Vec::with_capacity(frame.lenses.len());
        let mut reusable = old_lenses.drain(..).map(Some).collect::<Vec<_>>();
        for (index, (lens, lens_shape)) in frame.lenses.iter().zip(&shape.lenses).enumerate() {
            let old = reusable.get_mut(index).and_then(Option::take);
            let active = shape.active_viewpoints(lens_shape);
            lenses.push(self.upload_lens(
                gpu,
                pipelines,
                &pool,
                LensToUpload {
                    index,
                    lens,
                    active: &active,
                },
                old,
            )?);
        }
        let uploaded = UploadedFrame {
            shape,
            single_pass: SinglePassLimits::of_device(&gpu.properties().limits),
            view_proj: frame.view_proj.to_cols_array_2d(),
            environment,
            glossy,
            lenses,
            pool: Some(pool),
            targets,
            last_submission: None,
        };
        self.layer_cache
            .retain(|_, cached| cached.last_used + 1 >= generation);
        self.mesh_cache
            .retain(|_, cached| cached.last_used + 1 >= generation);
        self.glossy_cache
            .retain(|_, (_, _, last_used)| *last_used + 1 >= generation);
        self.checked_cubes
            .retain(|_, checked| checked.last_used + 1 >= generation);
        Ok(uploaded)
    }

    /// Replaces the layered EMs of lens `lens` in an uploaded frame (one list per viewpoint, the
    /// same count and face size as before), uploading only the maps: what the baker's test
    /// renderings change from one rendering to the next. Every submission of the frame must have
    /// completed (the renderer waits for its own).
    pub(super) fn replace_layers(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        frame: &mut UploadedFrame,
        lens: LensIndex,
        layers: &[Vec<Arc<CubeMap>>],
    ) -> Result<(), RenderError> {
        let bad = |s: String| Err(RenderError::BadInput(s));
        // No map budget to check: the new maps are as many and as large as the ones they replace,
        // which the frame's upload checked.
        // The descriptor sets and maps change: nothing submitted may still read them.
        if let Some((timeline, value)) = &frame.last_submission {
            timeline.wait(*value)?;
        }
        let Some(gpu_lens) = frame.lenses.get_mut(lens.index()) else {
            return bad(format!("lens {lens} is not in the uploaded frame"));
        };
        let Some(shape) = frame.shape.lenses.get(lens.index()) else {
            return bad(format!("lens {lens} is not in the uploaded frame"));
        };
        let active = frame.shape.active_viewpoints(shape);
        if layers.len() != gpu_lens.layers.len()
            || layers
                .iter()
                .any(|v| v.len() != gpu_lens.layer_count as usize)
        {
            return bad(format!(
                "lenses[{lens}]: {} viewpoints of {:?} layers given; the uploaded frame has {} of {}",
                layers.len(),
                layers.iter().map(Vec::len).collect::<Vec<_>>(),
                gpu_lens.layers.len(),
                gpu_lens.layer_count
            ));
        }
        let size = gpu_lens
            .layers
            .first()
            .map_or(1, |image| image.desc.extent.width);
        for (v, cubes) in layers.iter().enumerate() {
            for (i, cube) in cubes.iter().enumerate() {
                if let Err(error) = cube.validate(Some(size)) {
                    return bad(format!("lenses[{lens}].layers[{v}][{i}]: {error}"));
                }
            }
        }
        self.generation += 1;
        let images = layers
            .iter()
            .enumerate()
            .map(|(viewpoint, cubes)| {
                self.layer_image(gpu, &format!("lens{lens}/em{viewpoint}"), cubes)
            })
            .collect::<Result<Vec<_>, GpuError>>()?;
        let generation = self.generation;
        self.layer_cache
            .retain(|_, cached| cached.last_used + 1 >= generation);
        write_lens_sets(gpu, pipelines, &*gpu_lens, &images, &active);
        gpu_lens.layers = images;
        frame.shape.lenses[lens.index()].empty = FrameShape::empty_layers(layers);
        Ok(())
    }

    /// The vertex and index buffers of an environment mesh, from the cache or freshly uploaded.
    fn environment_mesh(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        mesh: &Arc<EnvironmentMesh>,
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
        let (uvs, light_map) = match &mesh.light_map {
            Some(light_map) => {
                let map = &light_map.map;
                let mut image = Image::new(
                    gpu,
                    ImageDesc::texture_2d(
                        "light map",
                        vk::Format::R16G16B16A16_SFLOAT,
                        map.width,
                        map.height,
                    ),
                )?;
                image.upload(gpu, 0, 0, 1, &map.to_bytes())?;
                (light_map.uvs.clone(), Arc::new(image))
            }
            None => (
                vec![glam::Vec2::ZERO; mesh.positions.len()],
                self.white_map(gpu)?,
            ),
        };
        let uv_bytes: Vec<u8> = uvs
            .iter()
            .flat_map(|uv| uv.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let descriptor_pool = DescriptorPool::new(gpu, ENVIRONMENT_SET, 1)?;
        let set = descriptor_pool.allocate_one(
            gpu,
            &pipelines.environment_set_layout,
            &[
                Resource::Image(light_map.view),
                Resource::Sampler(pipelines.light_map_sampler),
            ],
        )?;
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
            uvs: Buffer::with_data(gpu, "environment uvs", &uv_bytes, BufferUsage::Vertex)?,
            indices: Buffer::with_data(gpu, "environment indices", &indices, BufferUsage::Index)?,
            index_count: (mesh.triangles.len() * 3) as u32,
            _light_map: light_map,
            _descriptor_pool: descriptor_pool,
            set: set.0,
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

    /// Glossy draw `g` uploaded: its mesh from the cache or freshly uploaded, its maps as one
    /// cube-map array (cached like layered EMs), its data and descriptor set.
    fn glossy_draw(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        g: usize,
        draw: &super::GlossyDraw,
        view_proj: &glam::Mat4,
    ) -> Result<super::glossy::GpuGlossy, GpuError> {
        let key = Arc::as_ptr(&draw.mesh) as usize;
        let generation = self.generation;
        let mesh = match self.glossy_cache.get_mut(&key) {
            Some((_, mesh, last_used)) => {
                *last_used = generation;
                mesh.clone()
            }
            None => {
                let mesh = Arc::new(super::glossy::GpuGlossyMesh::new(gpu, &draw.mesh)?);
                self.glossy_cache
                    .insert(key, (draw.mesh.clone(), mesh.clone(), generation));
                mesh
            }
        };
        let maps = self.layer_image(gpu, &format!("glossy{g}/maps"), &draw.flat_maps())?;
        super::glossy::GpuGlossy::new(
            gpu,
            super::glossy::GlossySampling {
                layout: &pipelines.glossy_set_layout,
                sampler: pipelines.sampler,
            },
            mesh,
            maps,
            &draw.data(view_proj),
        )
    }

    /// The white 1×1 light map (RGBA16F ones), made once.
    fn white_map(&mut self, gpu: &Gpu) -> Result<Arc<Image>, GpuError> {
        if let Some(white) = &self.white {
            return Ok(white.clone());
        }
        let mut image = Image::new(
            gpu,
            ImageDesc::texture_2d("white light map", vk::Format::R16G16B16A16_SFLOAT, 1, 1),
        )?;
        let one = crate::lightmap::LightMap::uniform(1, 1, [1.0; 4]);
        image.upload(gpu, 0, 0, 1, &one.to_bytes())?;
        let image = Arc::new(image);
        self.white = Some(image.clone());
        Ok(image)
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
        let levels: Vec<Vec<u8>> = (0..image.desc.mip_levels as usize)
            .map(|level| {
                vec4_bytes(
                    cubes
                        .iter()
                        .flat_map(|cube| cube.levels[level].iter().map(Vec::as_slice)),
                )
            })
            .collect();
        image.upload_all(gpu, &levels)?;
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

    /// Uploads lens object `index`'s vertex data and indices (a resident object's are on the
    /// device already), into `old`'s buffers where they are large enough, and allocates and
    /// writes its descriptor sets from `pool`; its single pass blends the viewpoints `active`.
    fn upload_lens(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        pool: &DescriptorPool,
        LensToUpload {
            index,
            lens,
            active,
        }: LensToUpload<'_>,
        old: Option<GpuLens>,
    ) -> Result<GpuLens, GpuError> {
        let buffers = match &lens.resident {
            Some(resident) => resident
                .parts
                .iter()
                .map(|part| (PartBuffers::Device(part.clone()), part.stride))
                .collect(),
            None => {
                let old = old.and_then(|o| o.parts.into_iter().next());
                vec![host_buffers(gpu, index, lens, old.map(|o| o.buffers))?]
            }
        };
        let mut layers = Vec::new();
        for (viewpoint, cubes) in lens.layers.iter().enumerate() {
            layers.push(self.layer_image(gpu, &format!("lens{index}/em{viewpoint}"), cubes)?);
        }
        // The pool was sized for one set per (lens part, viewpoint) and one per lens part.
        let mut parts = Vec::with_capacity(buffers.len());
        for (buffers, stride) in buffers {
            let mut sets = pool.allocate(pipelines.lens_set_layout.handle, layers.len() + 1)?;
            let single_pass_set = sets.pop().ok_or(GpuError::Vulkan {
                call: "vkAllocateDescriptorSets",
                result: vk::Result::ERROR_OUT_OF_POOL_MEMORY,
            })?;
            parts.push(LensPart {
                buffers,
                stride,
                sets,
                single_pass_set,
            });
        }
        let gpu_lens = GpuLens {
            works: lens
                .resident
                .as_ref()
                .map_or_else(Vec::new, |r| r.works.clone()),
            terms: lens.terms.iter().map(|t| t.term).collect(),
            layer_count: lens.layer_count() as u32,
            layers,
            parts,
        };
        write_lens_sets(gpu, pipelines, &gpu_lens, &gpu_lens.layers, active);
        Ok(gpu_lens)
    }
}

/// A host lens object's vertex data and indices uploaded, into `old`'s buffers where they are
/// large enough; and its stride (its vertex count).
fn host_buffers(
    gpu: &Gpu,
    index: usize,
    lens: &LensObject,
    old: Option<PartBuffers>,
) -> Result<(PartBuffers, u32), GpuError> {
    let vertex_count = lens.positions.len() as u32;
    let mut data: Vec<[f32; 4]> = lens
        .positions
        .iter()
        .map(|p| p.extend(1.0).to_array())
        .collect();
    for term in &lens.terms {
        data.extend(term.fg.iter().map(|c| c.extend(0.0).to_array()));
        for layer in &term.directions {
            data.extend(layer.iter().map(|d| d.extend(0.0).to_array()));
        }
    }
    let (old_data, old_indices) = match old {
        Some(PartBuffers::Host(host)) => (Some(host.data), Some(host.indices)),
        _ => (None, None),
    };
    let data = reuse_or_new(
        gpu,
        old_data,
        &format!("lens{index} data"),
        bytemuck::cast_slice(&data),
        BufferUsage::Storage,
    )?;
    let indices = reuse_or_new(
        gpu,
        old_indices,
        &format!("lens{index} indices"),
        bytemuck::cast_slice(&lens.triangles),
        BufferUsage::Index,
    )?;
    Ok((
        PartBuffers::Host(Box::new(HostPart {
            data,
            indices,
            index_count: (lens.triangles.len() * 3) as u32,
            hull_index_count: (lens.hull_triangles.min(lens.triangles.len()) * 3) as u32,
        })),
        vertex_count,
    ))
}

/// `data` in `old` when it is large enough (rewritten in place: the mapped memory is the
/// buffer), else in a new buffer with a quarter to spare, so that a growing stream of frames
/// reallocates rarely.
fn reuse_or_new(
    gpu: &Gpu,
    old: Option<Buffer>,
    name: &str,
    data: &[u8],
    usage: BufferUsage,
) -> Result<Buffer, GpuError> {
    let mut buffer = match old {
        Some(buffer) if buffer.size >= data.len() as u64 => buffer,
        _ => {
            let size = data.len() as u64;
            Buffer::new(gpu, name, size + size / 4, usage)?
        }
    };
    buffer.write(0, data, name)?;
    Ok(buffer)
}

/// A lens object to upload: its index in the frame, its data, and the viewpoints its single pass
/// blends.
struct LensToUpload<'a> {
    index: usize,
    lens: &'a LensObject,
    active: &'a [usize],
}

/// Points the descriptor sets of every part of `lens` at its data buffer, cube-map arrays
/// `layers` (one per viewpoint) and the sampler: each viewpoint's set at that viewpoint's array in
/// every binding, the single pass's at the `active` viewpoints' arrays in order (the last one
/// repeated where fewer than [`MAX_VIEWPOINTS`] are active). The sets must not be in use by a
/// pending submission.
fn write_lens_sets(
    gpu: &Gpu,
    pipelines: &Pipelines,
    lens: &GpuLens,
    layers: &[Arc<Image>],
    active: &[usize],
) {
    for part in &lens.parts {
        let write = |set: vk::DescriptorSet, viewpoint_in_binding: &dyn Fn(usize) -> usize| {
            let mut resources = vec![Resource::Buffer(part.data())];
            resources.extend(
                (0..MAX_VIEWPOINTS).map(|k| Resource::Image(layers[viewpoint_in_binding(k)].view)),
            );
            resources.push(Resource::Sampler(pipelines.sampler));
            write_set(gpu, set, LENS_SET, &resources);
        };
        for (viewpoint, set) in part.sets.iter().enumerate() {
            write(*set, &|_| viewpoint);
        }
        // A lens with no active viewpoint has no single pass; its set still points at valid
        // arrays.
        write(part.single_pass_set, &|k| {
            active.get(k).or(active.last()).copied().unwrap_or(0)
        });
    }
}
