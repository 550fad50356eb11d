//! The hybrid frame's per-vertex work on the GPU: the scene's geometry and BVHs resident in
//! storage buffers ([`GpuGeometry`]), and compute passes that trace the eye ray and both greedy
//! paths at each lens vertex by the CPU oracle's rules in f32 (`shaders/wgsl/tracer.wgsl`).
//!
//! [`GpuTracer::trace_vertices`] runs the vertex-path pass over given vertices and reads the
//! records back: what the agreement with the CPU oracle is measured on.

use std::sync::Arc;

use ash::vk;
use glam::{DVec3, Vec3};
use lensmap_shaders::TracerConstants;

use super::paths::{ScreenCamera, TermPath, VertexPaths, VertexPrecision};
use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError, VkContext};
use crate::render::descriptors::{Binding, DescriptorPool, Resource, create_set_layout, write_set};
use crate::trace::{
    Bounces, Ray, bvh_gpu::GpuGeometry, schlick_table::SchlickTable, stats::TraceCounters,
    world::TraceScene,
};

mod assemble;
mod recorder;
mod resident;
mod tessellate;
mod texgen;
mod walk;

pub use resident::{DeviceCounts, read_counts};
pub use tessellate::{
    DeviceExtras, DeviceTessellation, GPU_MAX_DEPTH, GpuStageMs, GpuTessellation,
    GpuTessellationRequest,
};
pub use texgen::TexgenRequest;
pub use walk::{GpuTraversal, Traversal};

/// The next [`GpuTracer::id`].
static NEXT_TRACER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

const STORAGE: Binding = Binding {
    ty: vk::DescriptorType::STORAGE_BUFFER,
    stage: vk::ShaderStageFlags::COMPUTE,
};

/// Invocations per workgroup of the tracer's passes (`@workgroup_size` in tracer.wgsl).
const WORKGROUP: u32 = 64;

/// Bytes of one vertex record (tracer.wgsl `VertexRecord`: seven vec4).
const RECORD_BYTES: u64 = 7 * 16;

/// Counters the passes add to (tracer.wgsl `COUNTER_*`).
const COUNTERS: usize = 3;

/// The most vertices one pass traces: under the guaranteed 65,535 workgroups of a dispatch, and
/// small enough that its u32 counters cannot wrap (that would take 65,536 triangle tests per
/// vertex on average).
const MAX_BATCH: u64 = 65_536;

/// Where a traced vertex's paths start and stop (the CPU oracle's options).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathSettings {
    /// The lens object (TraceScene order) and the scene object the vertices are on.
    pub lens: usize,
    /// Scene object of the vertices.
    pub object: usize,
    /// Where the paths stop.
    pub bounces: Bounces,
    /// Most interfaces a path may meet.
    pub max_interfaces: u32,
}

/// One vertex as the GPU traced it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuVertex {
    /// Both terms' paths (f32 values widened).
    pub paths: VertexPaths,
    /// Whether the eye sees the vertex.
    pub visible: bool,
    /// Screen position in subpixels, when it has one.
    pub screen: Option<glam::Vec2>,
}

/// A device and a tracer resident on it: what a frame's vertices are traced on when the GPU
/// traces them ([`crate::hybrid::frame::GpuReadBack`], [`crate::hybrid::frame::GpuResident`]).
#[derive(Clone, Copy)]
pub struct GpuPaths<'a> {
    /// The device `tracer` was made on.
    pub gpu: &'a Gpu,
    /// The scene's resident geometry and passes.
    pub tracer: &'a GpuTracer,
}

/// The resident geometry and the tracer's pipelines on one device.
pub struct GpuTracer {
    device: ash::Device,
    /// What finds a ray's hits: the BVHs, or the driver's acceleration structures.
    walk: walk::Walk,
    /// What its passes compute in.
    precision: VertexPrecision,
    triangles: Buffer,
    materials: Buffer,
    schlick: Buffer,
    schlick_texels: u32,
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    vertex_paths: vk::Pipeline,
    /// The pass over a tessellation level's new vertices (`cs_level_paths`).
    level_paths: vk::Pipeline,
    /// Bound where a pass reads no tessellation (the level pass's bindings 8 and 9).
    unbound: Buffer,
    /// The tessellation's passes.
    tessellation: recorder::ComputePasses,
    /// The texgen pass.
    texgen: recorder::ComputePasses,
    /// The draw list's passes.
    draw_list: recorder::ComputePasses,
    /// Valid bits of the queue's timestamps (0: none; the GPU stages are then not timed).
    timestamp_bits: u32,
    /// Whether tessellations time their stages with timestamps ([`GpuTracer::time_stages`]).
    timed: std::sync::atomic::AtomicBool,
    /// The parts and triangles of the scene it was made from ([`GpuTracer::holds`]).
    shape: (usize, usize),
    /// Unique among the tracers of this process ([`GpuTracer::id`]).
    id: u64,
    /// What each pass uses and resets: held for the whole pass, so that passes from two threads
    /// take turns.
    pass: std::sync::Mutex<PassState>,
}

/// The descriptor pool every pass's set comes from, and the pass's buffers, kept between passes
/// and grown to the largest batch so far (a frame's levels reuse them instead of allocating four
/// buffers each).
struct PassState {
    pool: DescriptorPool,
    scratch: Option<Scratch>,
    /// The tessellation's buffers, shared by the scene objects and kept between frames.
    tessellation: Option<tessellate::Scratch>,
    /// The vertex capacity the tessellation's buffers have, or are to have once grown (0:
    /// none made yet).
    capacity: u64,
    /// The most the device holds for the last tessellation (its dispatch and binding limits,
    /// texgen's lens data included): what growing stops at.
    device_limit: u64,
    /// What the tessellation's buffers hold: every input tessellated so far (only grows).
    extent: tessellate::Extent,
    /// Each tessellated scene object's resident mesh, sets and outputs.
    objects: rustc_hash::FxHashMap<usize, resident::ObjectState>,
    /// The tessellations' submissions, not waited for.
    submissions: resident::Submissions,
}

/// A pass's buffers for up to `capacity` vertices: their inputs, records, the counters, and the
/// host copy of the counters (first, 16 bytes) and records (after).
struct Scratch {
    capacity: u64,
    vertices: Buffer,
    records: Buffer,
    counters: Buffer,
    readback: Buffer,
}

/// Bytes of one input vertex (position, normal: two vec4).
const VERTEX_BYTES: u64 = 32;

/// Where the records start in the readback buffer: after the counters, 16-byte aligned.
const READBACK_RECORDS: u64 = 16;

impl Scratch {
    fn new(gpu: &Gpu, capacity: u64) -> Result<Scratch, GpuError> {
        Ok(Scratch {
            capacity,
            vertices: Buffer::new(
                gpu,
                "tracer vertices",
                capacity * VERTEX_BYTES,
                BufferUsage::Storage,
            )?,
            records: Buffer::new(
                gpu,
                "tracer records",
                capacity * RECORD_BYTES,
                BufferUsage::Device,
            )?,
            counters: Buffer::new(
                gpu,
                "tracer counters",
                4 * COUNTERS as u64,
                BufferUsage::Device,
            )?,
            readback: Buffer::new(
                gpu,
                "tracer readback",
                READBACK_RECORDS + capacity * RECORD_BYTES,
                BufferUsage::Readback,
            )?,
        })
    }
}

impl Drop for GpuTracer {
    fn drop(&mut self) {
        // The tessellations' submissions are not waited for when made: before anything they use
        // goes. (A frame that draws a part holds the part's buffers itself.)
        let state = self.pass.get_mut().unwrap_or_else(|e| e.into_inner());
        let _ = state.submissions.wait_all();
        // SAFETY: every submission that used the pipelines completed (above, or the owner
        // waited for trace_vertices' own).
        unsafe {
            self.device.destroy_pipeline(self.vertex_paths, None);
            self.device.destroy_pipeline(self.level_paths, None);
            self.device.destroy_pipeline_layout(self.layout, None);
            self.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A compute pipeline layout of one set, `set_layout`, and push constants `C` (the caller
/// destroys it).
fn compute_layout<C>(
    gpu: &Gpu,
    set_layout: vk::DescriptorSetLayout,
) -> Result<vk::PipelineLayout, GpuError> {
    let push = [vk::PushConstantRange {
        stage_flags: vk::ShaderStageFlags::COMPUTE,
        offset: 0,
        size: std::mem::size_of::<C>() as u32,
    }];
    let set_layouts = [set_layout];
    // SAFETY: the create info lives until return.
    unsafe {
        gpu.device().create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default()
                .set_layouts(&set_layouts)
                .push_constant_ranges(&push),
            None,
        )
    }
    .vk("vkCreatePipelineLayout")
}

/// Valid bits of the timestamps of `gpu`'s queue.
fn timestamp_bits(gpu: &Gpu) -> u32 {
    let vulkan = gpu.vulkan();
    // SAFETY: the physical device belongs to the instance.
    let families = unsafe {
        vulkan
            .instance
            .get_physical_device_queue_family_properties(vulkan.physical_device)
    };
    families
        .get(vulkan.queue_family as usize)
        .map_or(0, |family| family.timestamp_valid_bits)
}

/// Refuses a buffer of `vec4s` vec4 past the device's `maxStorageBufferRange`.
fn check_range(gpu: &Gpu, what: &str, vec4s: usize) -> Result<(), GpuError> {
    let range = u64::from(gpu.properties().limits.max_storage_buffer_range);
    let bytes = 16 * vec4s as u64;
    if bytes > range {
        return Err(GpuError::BadUpload {
            what: what.into(),
            problem: format!(
                "{bytes} bytes, past the device's maxStorageBufferRange of {range}; trace this scene on the CPU"
            ),
        });
    }
    Ok(())
}

/// `data` as the bytes of a storage buffer (at least one element, so every binding is valid).
fn storage<T: bytemuck::Pod>(gpu: &Gpu, name: &str, data: &[T]) -> Result<Buffer, GpuError> {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    let padded = if bytes.is_empty() {
        &[0u8; 16][..]
    } else {
        bytes
    };
    Buffer::with_data(gpu, name, padded, BufferUsage::Storage)
}

impl GpuTracer {
    /// Uploads `trace`'s geometry (once per scene) for `traversal` and creates the passes, which
    /// trace in `precision` (f64: devices with [`Gpu::shader_float64`]). `fresnel`: the Schlick
    /// table the paths look Fresnel up in, `None` to evaluate it exactly.
    pub fn new(
        gpu: &Gpu,
        trace: &TraceScene,
        fresnel: Option<&SchlickTable>,
        (traversal, precision): (GpuTraversal, VertexPrecision),
    ) -> Result<GpuTracer, GpuError> {
        if precision == VertexPrecision::F64 && !gpu.shader_float64() {
            return Err(GpuError::NoSuitableDevice(format!(
                "{} ({}) has no shaderFloat64, which the GPU tracer's f64 passes need (lensmap enables it where the driver offers it, and uses a host's device without it); trace in f32 or on the CPU",
                gpu.device_name(),
                gpu.device_id().driver_description()
            )));
        }
        let geometry = GpuGeometry::new(trace);
        let texels = fresnel.map_or(&[0.0f32][..], |t| t.texels());
        // Buffers and the pool first: they free themselves if a later step fails.
        let walk = walk::Walk::new(gpu, &geometry, traversal)?;
        let triangles = match precision {
            VertexPrecision::F32 => {
                check_range(gpu, "tracer triangles", geometry.triangles.len())?;
                storage(gpu, "tracer triangles", &geometry.triangles)?
            }
            VertexPrecision::F64 => {
                check_range(gpu, "tracer triangles", 2 * geometry.triangles_f64.len())?;
                storage(gpu, "tracer triangles", &geometry.triangles_f64)?
            }
        };
        let materials = storage(gpu, "tracer materials", &geometry.materials)?;
        let schlick = storage(gpu, "tracer schlick", texels)?;
        let pool = DescriptorPool::new(gpu, walk.bindings(), 4)?;
        let set_layout = create_set_layout(gpu, walk.bindings())?;
        let layout = match compute_layout::<TracerConstants>(gpu, set_layout) {
            Ok(layout) => layout,
            Err(e) => {
                // SAFETY: created above, unused.
                unsafe { gpu.device().destroy_descriptor_set_layout(set_layout, None) };
                return Err(e);
            }
        };
        let module = match precision {
            VertexPrecision::F32 => walk.module().to_owned(),
            VertexPrecision::F64 => format!("{}_f64", walk.module()),
        };
        let pipeline = |entry: &str| {
            lensmap_shaders::shader(&module, entry)
                .ok_or_else(|| GpuError::BadUpload {
                    what: format!("{module}.wgsl"),
                    problem: format!("entry point {entry} was not compiled"),
                })
                .and_then(|shader| gpu.create_compute_pipeline(&shader, layout))
        };
        let made = pipeline("cs_vertex_paths").and_then(|vertex_paths| {
            match pipeline("cs_level_paths") {
                Ok(level_paths) => Ok((vertex_paths, level_paths)),
                Err(e) => {
                    // SAFETY: created above, unused.
                    unsafe { gpu.device().destroy_pipeline(vertex_paths, None) };
                    Err(e)
                }
            }
        });
        let rest = made.and_then(|pipelines| {
            let more = tessellate::tessellation_passes(gpu).and_then(|passes| {
                Ok((
                    (passes, texgen::texgen_pass(gpu)?),
                    (
                        resident::draw_list_passes(gpu)?,
                        resident::Submissions::new(gpu)?,
                    ),
                    storage(gpu, "tracer unbound", &[0u32; 4])?,
                ))
            });
            match more {
                Ok(more) => Ok((pipelines, more)),
                Err(e) => {
                    // SAFETY: created above, unused.
                    unsafe {
                        gpu.device().destroy_pipeline(pipelines.0, None);
                        gpu.device().destroy_pipeline(pipelines.1, None);
                    }
                    Err(e)
                }
            }
        });
        let (
            (vertex_paths, level_paths),
            ((tessellation, texgen), (draw_list, submissions), unbound),
        ) = match rest {
            Ok(made) => made,
            Err(e) => {
                // SAFETY: both were created above and nothing uses them yet.
                unsafe {
                    gpu.device().destroy_pipeline_layout(layout, None);
                    gpu.device().destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(e);
            }
        };
        Ok(GpuTracer {
            device: gpu.device().clone(),
            walk,
            precision,
            triangles,
            materials,
            schlick,
            schlick_texels: fresnel.map_or(0, |t| t.texels().len() as u32),
            set_layout,
            layout,
            vertex_paths,
            level_paths,
            unbound,
            tessellation,
            texgen,
            draw_list,
            timestamp_bits: timestamp_bits(gpu),
            timed: std::sync::atomic::AtomicBool::new(false),
            shape: (geometry.roots.len(), geometry.triangle_count()),
            id: NEXT_TRACER.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            pass: std::sync::Mutex::new(PassState {
                pool,
                scratch: None,
                tessellation: None,
                capacity: 0,
                device_limit: 0,
                extent: tessellate::Extent::default(),
                objects: rustc_hash::FxHashMap::default(),
                submissions,
            }),
        })
    }

    /// How it finds a ray's hits.
    pub fn traversal(&self) -> GpuTraversal {
        self.walk.traversal()
    }

    /// What its passes compute in.
    pub fn precision(&self) -> VertexPrecision {
        self.precision
    }

    /// What bindings 0 to 4 of a tracer pass's set point at: the walk's two, the triangles, the
    /// materials and the Schlick table.
    fn geometry_resources(&self) -> Vec<Resource> {
        let (walk, parts) = self.walk.resources();
        vec![
            walk,
            Resource::Buffer(self.triangles.handle),
            Resource::Buffer(self.materials.handle),
            parts,
            Resource::Buffer(self.schlick.handle),
        ]
    }

    /// The constants of a pass over `settings`' vertices seen by `camera`.
    fn constants(&self, camera: &ScreenCamera, settings: &PathSettings) -> TracerConstants {
        TracerConstants {
            view_proj: camera.view_proj.to_cols_array_2d(),
            eye: camera.eye.as_vec3().to_array(),
            part: 1 + settings.lens as u32,
            subpixels: camera.subpixels.to_array(),
            object: settings.object as u32,
            first_vertex: 0,
            vertex_count: 0,
            first_bounce_only: u32::from(settings.bounces == Bounces::First),
            max_interfaces: settings.max_interfaces,
            schlick_texels: self.schlick_texels,
        }
    }

    /// Traces the vertices `(position, unit normal)` of `settings.object` from `camera` and reads
    /// the records back, with the rays and triangle tests spent: one compute pass, or one per
    /// chunk where a batch's records would pass the device's `maxStorageBufferRange` or
    /// [`MAX_BATCH`] vertices.
    pub fn trace_vertices(
        &self,
        gpu: &Gpu,
        camera: &ScreenCamera,
        settings: &PathSettings,
        vertices: &[(Vec3, Vec3)],
    ) -> Result<(Vec<GpuVertex>, TraceCounters), GpuError> {
        self.check_device(gpu)?;
        let range = u64::from(gpu.properties().limits.max_storage_buffer_range);
        let chunk = (range / RECORD_BYTES).clamp(1, MAX_BATCH) as usize;
        let mut traced = Vec::with_capacity(vertices.len());
        let mut counters = TraceCounters::default();
        for part in vertices.chunks(chunk) {
            let (records, spent) = self.trace_batch(gpu, camera, settings, part)?;
            traced.extend(records);
            counters += spent;
        }
        Ok((traced, counters))
    }

    /// Whether its tessellations time their stages by the device's timestamps
    /// ([`GpuTessellation::stage_ms`]). Off by default: a timestamp waits for everything before
    /// it, which on lavapipe costs the frame tens of milliseconds.
    pub fn time_stages(&self, on: bool) {
        self.timed.store(on, std::sync::atomic::Ordering::Relaxed);
    }

    /// Refuses a device other than the one the tracer was made on.
    fn check_device(&self, gpu: &Gpu) -> Result<(), GpuError> {
        if gpu.device().handle() != self.device.handle() {
            return Err(GpuError::BadUpload {
                what: "the GPU tracer".into(),
                problem: "it was made on another device than the one asked to trace".into(),
            });
        }
        Ok(())
    }

    /// Notes that submission `value` of `timeline` (a frame's) recorded tessellations this tracer
    /// prepared ([`GpuTracer::tessellate_on_device`]): the buffers, sets and pipelines they name
    /// are kept until it completed.
    pub fn used_until(&self, timeline: Arc<crate::gpu::Timeline>, value: u64) {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        pass.submissions.used_until(timeline, value);
    }

    /// An identity unique among the tracers of this process: the buffers a frame drawn where its
    /// tessellation lies belong to this tracer's device, and such a frame is another tracer's
    /// frame for no other.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Whether this tracer holds `trace`'s geometry: the same parts and triangles (what a
    /// tracer made from another scene would not have).
    pub fn holds(&self, trace: &TraceScene) -> bool {
        self.shape == GpuGeometry::shape_of(trace)
    }

    /// [`GpuTracer::trace_vertices`] in one pass (the batch fits one dispatch and buffer).
    fn trace_batch(
        &self,
        gpu: &Gpu,
        camera: &ScreenCamera,
        settings: &PathSettings,
        vertices: &[(Vec3, Vec3)],
    ) -> Result<(Vec<GpuVertex>, TraceCounters), GpuError> {
        let count = vertices.len() as u64;
        let data: Vec<[f32; 4]> = vertices
            .iter()
            .flat_map(|(p, n)| [p.extend(1.0).to_array(), n.extend(0.0).to_array()])
            .collect();
        // A poisoned lock only means another pass panicked: the pool is reset anyway.
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let PassState { pool, scratch, .. } = &mut *pass;
        if scratch.as_ref().is_some_and(|s| s.capacity < count) {
            // The old buffers first: they go before the larger ones are made.
            *scratch = None;
        }
        let Scratch {
            vertices: vertex_buffer,
            records,
            counters,
            readback,
            ..
        } = match scratch {
            Some(kept) => kept,
            None => scratch.insert(Scratch::new(gpu, count.max(1))?),
        };
        vertex_buffer.write(0, bytemuck::cast_slice(&data), "tracer vertices")?;
        pool.reset()?;
        let set = pool.allocate(self.set_layout, 1)?[0];
        let mut resources = self.geometry_resources();
        resources.extend(
            [
                &*vertex_buffer,
                &*records,
                &*counters,
                &self.unbound,
                &self.unbound,
            ]
            .iter()
            .map(|b| Resource::Buffer(b.handle)),
        );
        write_set(gpu, set, self.walk.bindings(), &resources);
        let mut constants = self.constants(camera, settings);
        constants.vertex_count = count as u32;
        let device = gpu.device();
        let (records, counters, readback) = (&*records, &*counters, &*readback);
        gpu.submit_and_wait(|cb| {
            // SAFETY: every handle is live until the wait returns; the barriers order the fill
            // before the pass and the pass before the copies.
            unsafe {
                device.cmd_fill_buffer(cb, counters.handle, 0, vk::WHOLE_SIZE, 0);
                barrier(device, cb, TRANSFER_TO_COMPUTE);
                device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.vertex_paths);
                device.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::COMPUTE,
                    self.layout,
                    0,
                    &[set],
                    &[],
                );
                device.cmd_push_constants(
                    cb,
                    self.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(&constants),
                );
                device.cmd_dispatch(cb, (count as u32).div_ceil(WORKGROUP), 1, 1);
                barrier(device, cb, COMPUTE_TO_TRANSFER);
                let region = |size: u64, dst: u64| vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: dst,
                    size,
                };
                device.cmd_copy_buffer(
                    cb,
                    counters.handle,
                    readback.handle,
                    &[region(4 * COUNTERS as u64, 0)],
                );
                if count > 0 {
                    device.cmd_copy_buffer(
                        cb,
                        records.handle,
                        readback.handle,
                        &[region(count * RECORD_BYTES, READBACK_RECORDS)],
                    );
                }
                barrier(device, cb, TRANSFER_TO_HOST);
            }
            Ok(())
        })?;
        let bytes = readback.read();
        let words: &[u32] = bytemuck::cast_slice(&bytes[..readback.size as usize]);
        let record_words = (RECORD_BYTES / 4) as usize;
        let first = (READBACK_RECORDS / 4) as usize;
        let out = (0..count as usize)
            .map(|i| decode(&words[first + i * record_words..first + (i + 1) * record_words]))
            .collect();
        let counters = TraceCounters {
            primary_rays: u64::from(words[0]),
            secondary_rays: u64::from(words[1]),
            shadow_rays: 0,
            triangle_tests: u64::from(words[2]),
        };
        Ok((out, counters))
    }
}

/// A memory barrier between two stages of one command buffer: (source stage, access,
/// destination stage, access).
type Dependency = (
    vk::PipelineStageFlags2,
    vk::AccessFlags2,
    vk::PipelineStageFlags2,
    vk::AccessFlags2,
);

const TRANSFER_TO_COMPUTE: Dependency = (
    vk::PipelineStageFlags2::TRANSFER,
    vk::AccessFlags2::TRANSFER_WRITE,
    vk::PipelineStageFlags2::COMPUTE_SHADER,
    vk::AccessFlags2::from_raw(
        vk::AccessFlags2::SHADER_STORAGE_READ.as_raw()
            | vk::AccessFlags2::SHADER_STORAGE_WRITE.as_raw(),
    ),
);

const COMPUTE_TO_TRANSFER: Dependency = (
    vk::PipelineStageFlags2::COMPUTE_SHADER,
    vk::AccessFlags2::SHADER_STORAGE_WRITE,
    vk::PipelineStageFlags2::TRANSFER,
    vk::AccessFlags2::TRANSFER_READ,
);

const TRANSFER_TO_HOST: Dependency = (
    vk::PipelineStageFlags2::TRANSFER,
    vk::AccessFlags2::TRANSFER_WRITE,
    vk::PipelineStageFlags2::HOST,
    vk::AccessFlags2::HOST_READ,
);

/// Records a global memory barrier.
///
/// # Safety
/// `cb` is recording.
unsafe fn barrier(device: &ash::Device, cb: vk::CommandBuffer, dependency: Dependency) {
    let (src_stage, src_access, dst_stage, dst_access) = dependency;
    let barriers = [vk::MemoryBarrier2::default()
        .src_stage_mask(src_stage)
        .src_access_mask(src_access)
        .dst_stage_mask(dst_stage)
        .dst_access_mask(dst_access)];
    // SAFETY: the caller says `cb` is recording.
    unsafe {
        device.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().memory_barriers(&barriers),
        )
    };
}

/// One vertex record's 28 words as a [`GpuVertex`].
fn decode(w: &[u32]) -> GpuVertex {
    let f = |i: usize| f32::from_bits(w[i]);
    let v3 = |i: usize| DVec3::new(f64::from(f(i)), f64::from(f(i + 1)), f64::from(f(i + 2)));
    let term = |base: usize| {
        (f(base + 11) != 0.0).then(|| TermPath {
            fg: v3(base),
            outgoing: Ray {
                origin: v3(base + 4),
                direction: v3(base + 8),
            },
            topology: (w[base + 3], w[base + 7]),
        })
    };
    let screen = (f(26) != 0.0).then(|| glam::Vec2::new(f(24), f(25)));
    GpuVertex {
        paths: VertexPaths {
            terms: [term(0), term(12)],
        },
        visible: f(27) != 0.0,
        screen,
    }
}
