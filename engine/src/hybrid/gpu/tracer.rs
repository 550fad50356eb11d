//! The GPU tracer: the scene's geometry and BVHs resident in storage buffers, the pipelines of
//! the tracer's, the tessellation's, texgen's and the draw list's passes, and the state the
//! tessellations share ([`PassState`]). [`GpuTracer::trace_vertices`] traces given vertices and
//! reads their records back: what the agreement with the CPU oracle is measured on. Every
//! submission of its own is a compute work recorded through `render::compute`.

use std::sync::{Arc, Mutex, atomic::AtomicBool};

use glam::Vec3;
use lensmap_shaders::{
    DrawConstants, TessellateConstants, TexgenConstants, TracerConstants, drawlist, tessellate,
    texgen,
};

use super::assemble::{GpuVertex, decode};
use super::buffers::{
    CONTROL_WORDS, COUNTERS, Extent, Scratch as TessellationScratch, record_bytes, storage,
};
use super::resident::ObjectState;
use super::walk::{GpuTraversal, Walk};
use crate::gpu::descriptors::{Binding, DescriptorPool, Resource, SetLayout};
use crate::gpu::{
    Buffer, BufferUsage, CommandRing, ComputePipelines, Gpu, GpuError, Kernels, Pipeline, Timeline,
};
use crate::graph::Access;
use crate::hybrid::paths::{PathSettings, ScreenCamera, VertexPrecision};
use crate::render::compute::{
    Command, Dispatch, DispatchSize, WorkBuilder, WorkPassKind, WorkShape, push_constants, submit,
};
use crate::trace::{
    Bounces, bvh_gpu::GpuGeometry, schlick_table::SchlickTable, stats::TraceCounters,
    world::TraceScene,
};

/// The next [`GpuTracer::id`].
static NEXT_TRACER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// Submissions a tracer keeps in flight before it waits for the oldest.
const IN_FLIGHT: usize = 4;

/// The most vertices one pass traces: under the guaranteed 65,535 workgroups of a dispatch, and
/// small enough that its u32 counters cannot wrap (that would take 65,536 triangle tests per
/// vertex on average).
const MAX_BATCH: u64 = 65_536;

/// Bytes of one input vertex of [`GpuTracer::trace_vertices`] (position, normal: two vec4).
const VERTEX_BYTES: u64 = 32;

/// Where the records start in the readback buffer: after the counters, 16-byte aligned.
const READBACK_RECORDS: u64 = 16;

/// The resident geometry and the tracer's pipelines on one device.
pub struct GpuTracer {
    /// What finds a ray's hits: the BVHs, or the driver's acceleration structures.
    pub(super) walk: Walk,
    /// What its passes compute in.
    precision: VertexPrecision,
    pub(super) triangles: Buffer,
    pub(super) materials: Buffer,
    pub(super) schlick: Buffer,
    schlick_texels: u32,
    /// The pass over given vertices, then the pass over a tessellation level's new vertices.
    pub(super) tracer: ComputePipelines,
    /// The tessellation's passes, texgen's and the draw list's.
    pub(super) tessellation: Kernels<tessellate::Entry>,
    pub(super) texgen: Kernels<texgen::Entry>,
    pub(super) draw_list: Kernels<drawlist::Entry>,
    /// Valid bits of the queue's timestamps (0: none; the GPU stages are then not timed).
    pub(super) timestamp_bits: u32,
    /// Whether tessellations time their stages with timestamps ([`GpuTracer::time_stages`]).
    pub(super) timed: AtomicBool,
    /// The parts and triangles of the scene it was made from ([`GpuTracer::holds`]).
    shape: (usize, usize),
    /// Unique among the tracers of this process ([`GpuTracer::id`]).
    id: u64,
    /// What each pass uses and resets: held for the whole pass, so that passes from two threads
    /// take turns.
    pub(super) pass: Mutex<PassState>,
}

/// The descriptor pool every vertex pass's set comes from, and the pass's buffers, kept between
/// passes and grown to the largest batch so far; the tessellations' shared buffers and state.
pub(super) struct PassState {
    pool: DescriptorPool,
    scratch: Option<Scratch>,
    /// The tessellation's buffers, shared by the scene objects and kept between frames.
    pub(super) tessellation: Option<TessellationScratch>,
    /// The vertex capacity the tessellation's buffers have, or are to have once grown (0:
    /// none made yet).
    pub(super) capacity: u64,
    /// The most the device holds for the last tessellation (its dispatch and binding limits,
    /// texgen's lens data included): what growing stops at.
    pub(super) device_limit: u64,
    /// What the tessellation's buffers hold: every input tessellated so far (only grows).
    pub(super) extent: Extent,
    /// Each tessellated scene object's resident mesh, sets and outputs.
    pub(super) objects: rustc_hash::FxHashMap<usize, ObjectState>,
    /// The tracer's own submissions, not waited for, and the frames' that recorded its work.
    pub(super) submissions: CommandRing,
    /// The shapes of the tessellations' works declared so far: a frame declares the same passes
    /// again, and only their commands are made anew.
    pub(super) shapes: rustc_hash::FxHashMap<super::work::ShapeKey, Arc<WorkShape>>,
}

/// A pass's buffers for up to `capacity` vertices of records of up to `record_bytes`: their
/// inputs, records, the counters, the control words (the path classes), and the host copy of
/// the counters (first, 16 bytes) and records (after).
struct Scratch {
    capacity: u64,
    record_bytes: u64,
    vertices: Buffer,
    records: Buffer,
    counters: Buffer,
    control: Buffer,
    readback: Buffer,
}

impl Scratch {
    fn new(gpu: &Gpu, capacity: u64, record_bytes: u64) -> Result<Scratch, GpuError> {
        Ok(Scratch {
            capacity,
            record_bytes,
            vertices: Buffer::new(
                gpu,
                "tracer vertices",
                capacity * VERTEX_BYTES,
                BufferUsage::Storage,
            )?,
            records: Buffer::new(
                gpu,
                "tracer records",
                capacity * record_bytes,
                BufferUsage::Device,
            )?,
            control: Buffer::new(
                gpu,
                "tracer control",
                4 * CONTROL_WORDS as u64,
                BufferUsage::Storage,
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
                READBACK_RECORDS + capacity * record_bytes,
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
    }
}

/// The walk and the precision of a GPU tracer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TracerWalk {
    /// How it finds a ray's hits.
    pub traversal: GpuTraversal,
    /// What its passes compute in (f64: devices with [`Gpu::shader_float64`]).
    pub precision: VertexPrecision,
}

impl GpuTracer {
    /// Uploads `trace`'s geometry (once per scene) for `walk` and creates the passes. `fresnel`:
    /// the Schlick table the paths look Fresnel up in, `None` to evaluate it exactly.
    pub fn new(
        gpu: &Gpu,
        trace: &TraceScene,
        fresnel: Option<&SchlickTable>,
        walk: TracerWalk,
    ) -> Result<GpuTracer, GpuError> {
        let TracerWalk {
            traversal,
            precision,
        } = walk;
        if precision == VertexPrecision::F64 && !gpu.shader_float64() {
            return Err(GpuError::NoSuitableDevice(format!(
                "{} ({}) has no shaderFloat64, which the GPU tracer's f64 passes need (lensmap enables it where the driver offers it, and uses a host's device without it); trace in f32 or on the CPU",
                gpu.device_name(),
                gpu.device_id().driver_description()
            )));
        }
        let geometry = GpuGeometry::new(trace);
        let texels = fresnel.map_or(&[0.0f32][..], |t| t.texels());
        let walk = Walk::new(gpu, &geometry, traversal)?;
        let triangles = match precision {
            VertexPrecision::F32 => {
                super::buffers::check_range(gpu, "tracer triangles", geometry.triangles.len())?;
                storage(gpu, "tracer triangles", &geometry.triangles)?
            }
            VertexPrecision::F64 => {
                let vec4s = 2 * geometry.triangles_f64.len();
                super::buffers::check_range(gpu, "tracer triangles", vec4s)?;
                storage(gpu, "tracer triangles", &geometry.triangles_f64)?
            }
        };
        let set = Binding::of_shader(walk.set());
        let tracer = ComputePipelines::new(
            gpu,
            &walk.shaders(precision),
            set.clone(),
            std::mem::size_of::<TracerConstants>() as u32,
        )?;
        let tessellation = tessellation_kernels(gpu)?;
        let texgen = Kernels::new::<TexgenConstants>(gpu, texgen::SETS[0])?;
        let draw_list = Kernels::new::<DrawConstants>(gpu, drawlist::SETS[0])?;
        Ok(GpuTracer {
            precision,
            materials: storage(gpu, "tracer materials", &geometry.materials)?,
            schlick: storage(gpu, "tracer schlick", texels)?,
            schlick_texels: fresnel.map_or(0, |t| t.texels().len() as u32),
            walk,
            triangles,
            tracer,
            tessellation,
            texgen,
            draw_list,
            timestamp_bits: gpu.queue_timestamp_bits(),
            timed: AtomicBool::new(false),
            shape: (geometry.roots.len(), geometry.triangle_count()),
            id: NEXT_TRACER.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            pass: Mutex::new(PassState {
                pool: DescriptorPool::new(gpu, &set, 4)?,
                scratch: None,
                tessellation: None,
                capacity: 0,
                device_limit: 0,
                extent: Extent::default(),
                objects: rustc_hash::FxHashMap::default(),
                submissions: CommandRing::new(gpu, IN_FLIGHT)?,
                shapes: rustc_hash::FxHashMap::default(),
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

    /// The tracer's pass over a tessellation level's new vertices.
    pub(super) fn level_paths(&self) -> Pipeline {
        self.tracer.pipeline(1)
    }

    /// Its passes' set 0 layout.
    pub(super) fn tracer_set_layout(&self) -> &SetLayout {
        self.tracer.set_layout()
    }

    /// What bindings 0 to 4 of a tracer pass's set point at, with the names plans give them:
    /// the walk's two, the triangles, the materials and the Schlick table.
    pub(super) fn geometry(&self) -> [(Option<&Buffer>, &'static str); 5] {
        let [first, parts] = self.walk.buffers();
        [
            first,
            (Some(&self.triangles), "tracer triangles"),
            (Some(&self.materials), "tracer materials"),
            parts,
            (Some(&self.schlick), "tracer schlick"),
        ]
    }

    /// What binding 0 of a tracer pass's set points at (the walk's buffer or structure).
    pub(super) fn walk_resource(&self) -> Resource {
        self.walk.resources().0
    }

    /// Its draw list's and texgen's and the tessellation's set layouts, with the level pass's.
    pub(super) fn layouts(&self) -> super::resident::Layouts<'_> {
        super::resident::Layouts {
            level_paths: self.tracer_set_layout(),
            tessellation: self.tessellation.set_layout(),
            texgen: self.texgen.set_layout(),
            draw_list: self.draw_list.set_layout(),
        }
    }

    /// The constants of a pass over `settings`' vertices seen by `camera`.
    pub(super) fn constants(
        &self,
        camera: &ScreenCamera,
        settings: &PathSettings,
    ) -> TracerConstants {
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

    /// Traces the vertices `(position, unit normal)` of `settings.object` from `camera` (the two
    /// greedy terms, or `settings.classes`) and reads the records back, with the rays and
    /// triangle tests spent: one compute pass, or one per chunk where a batch's records would
    /// pass the device's `maxStorageBufferRange` or [`MAX_BATCH`] vertices.
    pub fn trace_vertices(
        &self,
        gpu: &Gpu,
        camera: &ScreenCamera,
        settings: &PathSettings,
        vertices: &[(Vec3, Vec3)],
    ) -> Result<(Vec<GpuVertex>, TraceCounters), GpuError> {
        self.check_device(gpu)?;
        let range = u64::from(gpu.properties().limits.max_storage_buffer_range);
        let bytes = record_bytes(settings.classes.terms().len());
        let chunk = (range / bytes).clamp(1, MAX_BATCH) as usize;
        let mut traced = Vec::with_capacity(vertices.len());
        let mut counters = TraceCounters::default();
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        for part in vertices.chunks(chunk) {
            let (records, spent) = self.trace_batch(gpu, &mut pass, camera, settings, part)?;
            traced.extend(records);
            counters += spent;
        }
        Ok((traced, counters))
    }

    /// Whether its tessellations time their stages by the device's timestamps
    /// ([`super::GpuTessellation::stage_ms`]). Off by default: a timestamp waits for everything
    /// before it, which on lavapipe costs the frame tens of milliseconds.
    pub fn time_stages(&self, on: bool) {
        self.timed.store(on, std::sync::atomic::Ordering::Relaxed);
    }

    /// Refuses a device other than the one the tracer was made on.
    pub(super) fn check_device(&self, gpu: &Gpu) -> Result<(), GpuError> {
        if !self.tracer.made_on(gpu) {
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
    pub fn used_until(&self, timeline: Arc<Timeline>, value: u64) {
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

    /// [`GpuTracer::trace_vertices`] in one pass (the batch fits one dispatch and buffer): the
    /// counters cleared, the pass, the counters and records copied to the host.
    fn trace_batch(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        camera: &ScreenCamera,
        settings: &PathSettings,
        vertices: &[(Vec3, Vec3)],
    ) -> Result<(Vec<GpuVertex>, TraceCounters), GpuError> {
        let count = vertices.len() as u64;
        let data: Vec<[f32; 4]> = vertices
            .iter()
            .flat_map(|(p, n)| [p.extend(1.0).to_array(), n.extend(0.0).to_array()])
            .collect();
        let PassState {
            pool,
            scratch,
            submissions,
            ..
        } = state;
        let classes = settings.classes.terms().len();
        let bytes = record_bytes(classes);
        if scratch
            .as_ref()
            .is_some_and(|s| s.capacity < count || s.record_bytes < bytes)
        {
            // The old buffers first: they go before the larger ones are made.
            *scratch = None;
        }
        let scratch = match scratch {
            Some(kept) => kept,
            None => scratch.insert(Scratch::new(gpu, count.max(1), bytes)?),
        };
        scratch
            .vertices
            .write(0, bytemuck::cast_slice(&data), "tracer vertices")?;
        // The control words this pass reads: the path classes.
        let mut control = [0u32; CONTROL_WORDS];
        super::buffers::write_classes(&mut control, &settings.classes);
        scratch
            .control
            .write(0, bytemuck::cast_slice(&control), "tracer control")?;
        pool.reset()?;
        let (walk, parts) = self.walk.resources();
        let resources = [
            walk,
            Resource::buffer(&self.triangles),
            Resource::buffer(&self.materials),
            parts,
            Resource::buffer(&self.schlick),
            Resource::buffer(&scratch.vertices),
            Resource::buffer(&scratch.records),
            Resource::buffer(&scratch.counters),
            Resource::buffer(&scratch.control),
            // Binding 9 (the tessellation's wanted flags) is not read here.
            Resource::buffer(&scratch.counters),
        ];
        let set = pool.allocate_one(gpu, self.tracer_set_layout(), &resources)?;
        let mut constants = self.constants(camera, settings);
        constants.vertex_count = count as u32;
        let mut work = WorkBuilder::bound();
        let geometry = self.geometry();
        let mut slots: Vec<Option<usize>> = geometry
            .iter()
            .map(|&(buffer, name)| (!name.is_empty()).then(|| work.buffer(name, buffer)))
            .collect();
        let vertices_slot = work.buffer("tracer vertices", Some(&scratch.vertices));
        let records = work.buffer("tracer records", Some(&scratch.records));
        let counters = work.buffer("tracer counters", Some(&scratch.counters));
        let readback = work.buffer("tracer readback", Some(&scratch.readback));
        let control_slot = work.buffer("tracer control", Some(&scratch.control));
        slots.extend([
            Some(vertices_slot),
            Some(records),
            Some(counters),
            Some(control_slot),
            None,
        ]);
        work.pass(
            "counters",
            WorkPassKind::Transfer,
            || vec![(counters, Access::TransferWrite)],
            || Command::Fill {
                buffer: counters,
                bytes: None,
                value: 0,
            },
        );
        let wg = lensmap_shaders::tracer::Entry::CsVertexPaths;
        let groups = (count as u32).div_ceil(lensmap_shaders::EntryPoint::workgroup_size(wg)[0]);
        work.dispatch(Dispatch {
            name: &"cs_vertex_paths",
            entry: wg,
            buffers: &slots,
            size: DispatchSize::Groups(groups),
            bound: Some((self.tracer.pipeline(0), set, push_constants(&constants))),
        });
        for (name, from, region) in [
            ("readback: counters", counters, (0, 0, 4 * COUNTERS as u64)),
            (
                "readback: records",
                records,
                (0, READBACK_RECORDS, count * bytes),
            ),
        ] {
            let uses = || {
                vec![
                    (from, Access::TransferRead),
                    (readback, Access::TransferWrite),
                ]
            };
            work.pass(name, WorkPassKind::Transfer, uses, || Command::Copy {
                from,
                to: readback,
                regions: vec![region],
            });
        }
        work.pass(
            "readback: host",
            WorkPassKind::HostRead,
            || vec![(readback, Access::HostRead)],
            || Command::HostRead,
        );
        let work = work.finish()?;
        let value = submit(gpu, submissions, &[&work])?;
        submissions.wait(value)?;
        let read = scratch.readback.read();
        let words: &[u32] = bytemuck::cast_slice(&read[..scratch.readback.size as usize]);
        let record_words = (bytes / 4) as usize;
        let first = (READBACK_RECORDS / 4) as usize;
        let out = (0..count as usize)
            .map(|i| {
                let at = first + i * record_words;
                decode(&words[at..at + record_words], classes)
            })
            .collect();
        use lensmap_shaders::tessellate as t;
        let counters = TraceCounters {
            primary_rays: u64::from(words[t::COUNTER_PRIMARY_RAYS as usize]),
            secondary_rays: u64::from(words[t::COUNTER_SECONDARY_RAYS as usize]),
            shadow_rays: 0,
            triangle_tests: u64::from(words[t::COUNTER_TRIANGLE_TESTS as usize]),
        };
        Ok((out, counters))
    }
}

/// The tessellation's pipelines on one device; refused where the device binds fewer storage
/// buffers per stage than they do.
fn tessellation_kernels(gpu: &Gpu) -> Result<Kernels<tessellate::Entry>, GpuError> {
    let set = tessellate::SETS[0];
    let limit = gpu
        .properties()
        .limits
        .max_per_stage_descriptor_storage_buffers;
    if (limit as usize) < set.len() {
        return Err(GpuError::BadUpload {
            what: "the GPU tessellation".into(),
            problem: format!(
                "it binds {} storage buffers, past the device's maxPerStageDescriptorStorageBuffers of {limit}; tessellate on the CPU",
                set.len()
            ),
        });
    }
    Kernels::new::<TessellateConstants>(gpu, set)
}
