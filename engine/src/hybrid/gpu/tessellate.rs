//! The adaptive tessellation on the GPU (`shaders/wgsl/tessellate.wgsl`): the CPU tessellator's
//! rules ([`crate::hybrid::tessellate`]) level by level in compute passes, the vertex paths
//! traced by the tracer's level pass between them, every record kept on the GPU, then texgen and
//! the draw list: one compute work ([`super::work`]). A frame declares its passes in its own
//! graph and draws the result where it lies ([`GpuTracer::tessellate_on_device`],
//! [`super::resident`]); [`GpuTracer::tessellate`] submits it, waits for it and reads the mesh
//! and its records back once.
//!
//! Determinism: midpoint, edge and triangle indices come from stable prefix sums over each
//! level's triangles (in the CPU's order), and a midpoint belongs to the lowest-indexed triangle
//! that asks for it (an atomic minimum, whose result does not depend on the order the atomics
//! land in); so the output is identical run to run, and a midpoint gets the index the CPU gives
//! it where the decisions agree.
//!
//! Capacity: the buffers hold a fixed number of vertices (and six triangles and five edges per
//! vertex), shared by the scene objects. Where a tessellation's counts say they, not the vertex
//! budget, stopped its splits, they grow fourfold, up to the budget or what the device can
//! dispatch, for the next tessellation: at once for one read back (it is made again), with the
//! next frame for one drawn where it lies. Past the budget, splits stop as on the CPU
//! ([`StopReason::Budget`](crate::hybrid::tessellate::StopReason::Budget)).

use std::sync::Arc;

use lensmap_shaders::{DrawConstants, TessellateConstants, tessellate as t};

use super::assemble::{Readback, assemble};
use super::buffers::{
    CONTROL_WORDS, Extent, InputMesh, OUTPUT_BYTES, Scratch, TRIANGLE_BYTES, VERTEX_BYTES,
    device_capacity, record_bytes,
};
use super::resident::{self, ObjectState, OutputSets};
use super::texgen::{self, TexgenRequest};
use super::tracer::{GpuTracer, PassState};
use super::work::{self, Bound, Tessellation as Declared, TessellationBuffers};
use crate::gpu::{Gpu, GpuError, QueryPool};
use crate::graph::Access;
use crate::hybrid::paths::{PathSettings, ScreenCamera, VertexPaths};
use crate::hybrid::tessellate::{Tessellation, TessellationError, TessellationOptions};
use crate::render::compute::{
    Command, ComputeWork, WorkBuilder, WorkPassKind, push_constants, submit,
};
use crate::render::{DeviceLensPart, TermVertices};
use crate::scene::TriangleMesh;
use crate::trace::stats::TraceCounters;

/// The deepest subdivision the GPU walks: an edge's split tree then has at most 31 levels, what
/// the edge walk's stack of 64 entries holds (tessellate.wgsl `WALK_STACK`).
pub const GPU_MAX_DEPTH: u32 = t::WALK_STACK / 2 - 2;

/// The first capacity tried, in vertices: the paper's setting (teapot-room at 1920×1440
/// subpixels, t = 3) needs some 130,000.
const FIRST_CAPACITY: u64 = 1 << 17;

/// What a tessellation needs besides its mesh: the camera and paths, the paper's criterion and
/// the options.
pub struct GpuTessellationRequest<'a> {
    /// The frame's camera.
    pub camera: &'a ScreenCamera,
    /// The lens object and scene object, and where paths stop.
    pub settings: &'a PathSettings,
    /// cos of the paper's angle threshold.
    pub cos_threshold: f32,
    /// Whether back-facing triangles are subdivided too (an open mesh).
    pub back_faces: bool,
    /// t, the depth cap (at most [`GPU_MAX_DEPTH`]) and the vertex budget.
    pub options: &'a TessellationOptions,
    /// Texture coordinates too, for these layers (in the same submission), or not.
    pub texgen: Option<TexgenRequest<'a>>,
    /// Per input triangle whether it lies on the convex hull of the lens geometry: the draw
    /// list puts those facing the eye last (`None`: no convex-hull split).
    pub hull: Option<&'a [bool]>,
    /// Whether the vertex budget continues on the device from the tessellation submitted before
    /// (the frame's previous scene object, whose vertices the host never counted) instead of
    /// starting at `options.max_vertices`.
    pub continue_budget: bool,
}

/// What a tessellation left on the device for a frame adds to one read back.
#[derive(Clone, Copy, Debug)]
pub struct DeviceExtras<'a> {
    /// Texture coordinates too, for these layers.
    pub texgen: Option<TexgenRequest<'a>>,
    /// Per input triangle whether it lies on the convex hull of the lens geometry (`None`: no
    /// convex-hull split).
    pub hull: Option<&'a [bool]>,
    /// Whether the vertex budget continues from the frame's previous tessellation, which the
    /// host never counted ([`GpuTessellationRequest::continue_budget`]).
    pub continue_budget: bool,
}

/// A tessellation left on the device: its work for a frame to declare and record, or its
/// submission, not waited for (unless timed).
pub struct DeviceTessellation {
    /// The buffers a frame draws it from.
    pub part: Arc<DeviceLensPart>,
    /// The compute work that makes them, for the frame that draws them to run before its lens
    /// passes (`None`: submitted already, as a timed tessellation is).
    pub work: Option<Arc<ComputeWork>>,
    /// Its stages' device time (`None` unless the tracer [times them](GpuTracer::time_stages):
    /// it then waits for the submission).
    pub stage_ms: Option<GpuStageMs>,
    /// Wall time of recording and submitting it (and of waiting, when timed), ms.
    pub submission_ms: f64,
    /// The tracer's timeline value its completion signals.
    submitted: u64,
}

/// Where a GPU tessellation's time went on the device, by timestamps, ms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuStageMs {
    /// The levels' vertex-path passes.
    pub trace: f64,
    /// The levels' split passes and the T-junction removal.
    pub tessellation: f64,
    /// The texgen pass.
    pub texgen: f64,
}

/// A tessellation made on the GPU, read back.
pub struct GpuTessellation {
    /// Wall time of its main submission (every pass, recorded, run and waited for), ms: all but
    /// the read-back and rebuilding the mesh on the CPU.
    pub submission_ms: f64,
    /// Its stages' device time (`None` unless the tracer [times them](GpuTracer::time_stages)
    /// and the queue has timestamps).
    pub stage_ms: Option<GpuStageMs>,
    /// The mesh, its origins, records and stats, as the CPU tessellator gives them.
    pub tessellation: Tessellation<VertexPaths>,
    /// The rays and triangle tests of its vertex paths.
    pub counters: TraceCounters,
    /// Per term its F·G and each layer's directions, when texgen was asked for.
    pub terms: Option<Vec<TermVertices>>,
}

/// A scene object a frame is about to tessellate on the device: its index, its mesh and the
/// texgen arrays of its lens object.
pub struct PreparedObject<'a> {
    /// The scene object.
    pub object: usize,
    /// Its mesh.
    pub mesh: &'a TriangleMesh,
    /// Arrays of its lens data ([`TexgenRequest::arrays`]).
    pub arrays: u64,
    /// Path-class terms its vertices trace (0: the two greedy terms).
    pub classes: usize,
}

/// Where a tessellation's result goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// Read back by the tracer, which submits and waits for it.
    ReadBack,
    /// Left on the device for a frame to draw (recorded by the frame unless timed).
    OnDevice,
}

/// What the shared buffers must be sized for: a scene object, its texgen arrays and path-class
/// terms, the budget and whether it continues a frame's earlier objects.
struct Need {
    object: usize,
    arrays: u64,
    classes: usize,
    max_vertices: usize,
    continue_budget: bool,
}

impl GpuTracer {
    /// Tessellates scene object `object` (`mesh`) from `request.camera` on the GPU, tracing
    /// every vertex there, waits for it and reads the mesh and its records back.
    ///
    /// `object` names `mesh` within the tracer's scene: the copy kept resident for it is reused
    /// while its vertex and triangle counts match, so a mesh that changes must come under
    /// another index. Splits stop at the vertex budget as on the CPU (`Budget` leaves); the
    /// device's limits stop them the same way, and only a device that cannot hold the input
    /// mesh and one split is an error. Buffers that stop splits before the budget are grown
    /// fourfold and the tessellation made again.
    pub fn tessellate(
        &self,
        gpu: &Gpu,
        object: usize,
        mesh: &TriangleMesh,
        request: &GpuTessellationRequest<'_>,
    ) -> Result<GpuTessellation, TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            let start = std::time::Instant::now();
            let made = self.submit_tessellation(
                gpu,
                &mut pass,
                object,
                mesh,
                request,
                Placement::ReadBack,
            )?;
            pass.submissions.wait(made.submitted)?;
            let submission_ms = start.elapsed().as_secs_f64() * 1e3;
            if resident::read_counts(&made.part).capped_by_buffers && self.grow_locked(&mut pass) {
                continue;
            }
            let mut read = self.read_mesh(gpu, &mut pass, object, mesh, &made.part, request)?;
            read.stage_ms = made.stage_ms;
            read.submission_ms = submission_ms;
            return Ok(read);
        }
    }

    /// [`Self::tessellate`] left on the device: the work that makes the mesh, the lens pass's
    /// data (when `request.texgen` asks) and the draw list, for the frame that draws the returned
    /// part to run first (timed, it is submitted and waited for here instead). Its counts are
    /// read once that frame is done ([`super::read_counts`]); where they say the buffers stopped
    /// splits before the budget, [`Self::grow`] gives the next tessellation larger ones.
    pub fn tessellate_on_device(
        &self,
        gpu: &Gpu,
        object: usize,
        mesh: &TriangleMesh,
        request: &GpuTessellationRequest<'_>,
    ) -> Result<DeviceTessellation, TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let start = std::time::Instant::now();
        let mut made =
            self.submit_tessellation(gpu, &mut pass, object, mesh, request, Placement::OnDevice)?;
        made.submission_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(made)
    }

    /// Makes the buffers hold every scene object a frame is about to tessellate on the device
    /// (made or grown now, at the frame's start), so that they are never made again between two
    /// of its objects: each object's work, run later by the frame, names them.
    pub fn prepare_frame(
        &self,
        gpu: &Gpu,
        objects: &[PreparedObject<'_>],
        options: &TessellationOptions,
    ) -> Result<(), TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let state = &mut *pass;
        let mut last = None;
        for prepared in objects {
            self.keep_input(gpu, state, prepared.object, prepared.mesh)?;
            let input = &state.objects[&prepared.object].input;
            let extent = Extent::of(input, prepared.arrays, prepared.classes);
            state.extent = state.extent.max(extent);
            last = Some(prepared);
        }
        let Some(last) = last else {
            return Ok(());
        };
        // The extent holds every object's needs: the buffers are sized for them all now.
        let need = Need {
            object: last.object,
            arrays: last.arrays,
            classes: last.classes,
            max_vertices: options.max_vertices,
            continue_budget: false,
        };
        self.ensure_buffers(gpu, state, &need)
    }

    /// Whether `part` is one of this tracer's outputs (a frame's counts grow the tracer that
    /// made its parts).
    pub fn made(&self, part: &Arc<DeviceLensPart>) -> bool {
        let pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        pass.objects
            .values()
            .any(|object| object.outputs.iter().any(|o| Arc::ptr_eq(&o.part, part)))
    }

    /// Asks for buffers four times larger (up to what the device holds) for the next
    /// tessellation, which makes them once every submission that uses the old ones completed;
    /// whether they will grow.
    pub fn grow(&self) -> bool {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        self.grow_locked(&mut pass)
    }

    fn grow_locked(&self, state: &mut PassState) -> bool {
        let Some(scratch) = &state.tessellation else {
            return false;
        };
        let grown = (scratch.vertices_capacity * 4).min(state.device_limit);
        if grown <= scratch.vertices_capacity {
            return false;
        }
        state.capacity = grown;
        true
    }

    /// Scene object `object`'s input kept resident: uploaded unless it is, again where its mesh
    /// changed (after every submission that used the old one).
    fn keep_input(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        object: usize,
        mesh: &TriangleMesh,
    ) -> Result<(), TessellationError> {
        let stale = state.objects.get(&object).is_some_and(|o| {
            o.input.vertex_count as usize != mesh.positions.len()
                || o.input.triangle_count as usize != mesh.triangles.len()
        });
        if stale {
            state.submissions.wait_all()?;
            state.objects.remove(&object);
        }
        if let std::collections::hash_map::Entry::Vacant(slot) = state.objects.entry(object) {
            slot.insert(ObjectState::new(gpu, InputMesh::new(gpu, mesh)?)?);
        }
        Ok(())
    }

    /// Makes the shared buffers hold `need`'s object's input (made, or grown as asked, after
    /// every submission that used the old ones completed); an error where the device cannot
    /// hold the input and one split.
    fn ensure_buffers(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        need: &Need,
    ) -> Result<(), TessellationError> {
        let input = &state.objects[&need.object].input;
        let least = u64::from(input.vertex_count) + 4;
        let mine = Extent::of(input, need.arrays, need.classes);
        // What the buffers hold only grows: every object tessellated so far fits.
        state.extent = state.extent.max(mine);
        let extent = state.extent;
        let device = device_capacity(gpu, &extent);
        if device < least {
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: format!(
                    "the device holds at most {device} vertices, too few for the mesh's {}; tessellate on the CPU",
                    input.vertex_count
                ),
            }
            .into());
        }
        state.device_limit = device;
        // The buffers are kept while they hold every input so far (grown only by `grow`); the
        // first are sized for the paper's setting, or the budget when smaller.
        let budget = (need.max_vertices as u64).max(extent.least);
        let wanted = match state.capacity {
            0 => FIRST_CAPACITY.min(budget),
            grown => grown,
        }
        .max(extent.least)
        .min(device);
        // Kept while they hold the inputs and no growth was asked for since they were made.
        let fits = state.tessellation.as_ref().is_some_and(|s| {
            s.holds(&extent)
                && s.vertices_capacity <= device
                && s.vertices_capacity == state.capacity
        });
        if fits {
            return Ok(());
        }
        if need.continue_budget {
            // The frame's earlier objects' work, not recorded yet, names these buffers, and
            // the budget word they carry: the frame must be prepared first (prepare_frame).
            return Err(GpuError::Internal("the GPU tessellation: its buffers would be made again between two objects of one frame; the frame was not prepared for all its objects".into())
            .into());
        }
        // Nothing submitted may still use the old buffers, nor the sets that point at them.
        state.submissions.wait_all()?;
        state.tessellation = None;
        state.tessellation = Some(Scratch::new(
            gpu,
            wanted,
            extent.reserve,
            extent.record_bytes,
        )?);
        state.capacity = wanted;
        for held in state.objects.values_mut() {
            held.forget_sets();
        }
        Ok(())
    }

    /// The names and buffers of a tessellation of `held` (scene object `object`) over
    /// `scratch`, into `part` (`None` for the sets that do not name a part's outputs).
    fn buffers<'a>(
        &'a self,
        scratch: &'a Scratch,
        held: &'a ObjectState,
        object: usize,
        part: Option<&'a DeviceLensPart>,
    ) -> TessellationBuffers<'a> {
        TessellationBuffers {
            scratch: Some(scratch),
            input: Some(&held.input),
            hull: Some(&held.hull),
            shells: held.shells.as_ref().map(|(buffer, _)| buffer),
            part,
            geometry: self.geometry(),
            object,
            part_name: part.map_or("", |p| p.name.as_str()),
        }
    }

    /// Records and submits one tessellation, or declares it for a frame (the caller holds the
    /// pass state).
    fn submit_tessellation(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        object: usize,
        mesh: &TriangleMesh,
        request: &GpuTessellationRequest<'_>,
        placement: Placement,
    ) -> Result<DeviceTessellation, TessellationError> {
        self.check_device(gpu)?;
        let options = request.options;
        check_options(options)?;
        self.keep_input(gpu, state, object, mesh)?;
        let arrays = request.texgen.as_ref().map_or(0, TexgenRequest::arrays);
        let need = Need {
            object,
            arrays,
            classes: request.settings.classes.terms().len(),
            max_vertices: options.max_vertices,
            continue_budget: request.continue_budget,
        };
        self.ensure_buffers(gpu, state, &need)?;
        let hull: Vec<u32> = request
            .hull
            .map(|flags| flags.iter().map(|&f| u32::from(f)).collect())
            .unwrap_or_default();
        let shells = request.texgen.as_ref().map(TexgenRequest::shell_words);
        let unkept = |what: &str| {
            GpuError::Internal(format!("the GPU tessellation: its {what} was not kept"))
        };
        let PassState {
            tessellation: scratch,
            objects,
            submissions,
            shapes,
            ..
        } = state;
        let held = objects.get_mut(&object).ok_or_else(|| unkept("mesh"))?;
        if held.changes(&hull, shells.as_deref()) {
            submissions.wait_all()?;
            held.write_inputs(gpu, &hull, shells.as_deref())?;
        }
        let scratch = scratch.as_ref().ok_or_else(|| unkept("buffers"))?;
        let layouts = self.layouts();
        // The sets name the shared buffers and the object's input alone (made once, until
        // either is made again).
        if held.sets.is_none() {
            let names = self.buffers(scratch, held, object, None);
            let level = resident::resources(&names.level_paths(), Some(self.walk_resource()))?;
            let tessellation = resident::resources(&names.tessellation(), None)?;
            held.make_sets(gpu, &layouts, &level, &tessellation)?;
        }
        let [level_set, tessellation_set] = held.sets.ok_or_else(|| unkept("sets"))?;
        let texgen_on = arrays > 0 && held.shells.is_some();
        let at = held.free_outputs(
            gpu,
            scratch,
            arrays,
            |made| format!("object{object} output{made}"),
            |held, part| {
                let names = self.buffers(scratch, held, object, Some(part));
                let texgen = texgen_on.then(|| names.texgen());
                OutputSets::new(gpu, &layouts, texgen.as_deref(), &names.draw_list())
            },
        )?;
        let held = objects.get(&object).ok_or_else(|| unkept("mesh"))?;
        let outputs = &held.outputs[at];
        let part = outputs.part.clone();
        let levels = options.max_depth + 1;
        let timed = self.timed.load(std::sync::atomic::Ordering::Relaxed);
        let timestamps = match self.timestamp_bits {
            bits if bits > 0 && timed => Some(QueryPool::timestamps(gpu, 4 * levels + 4)?),
            _ => None,
        };
        let input = &held.input;
        let (first, written) = first_words(input, request);
        let bound = Bound {
            tessellation: &self.tessellation,
            texgen: &self.texgen,
            draw_list: &self.draw_list,
            level_paths: self.level_paths(),
            sets: [
                level_set,
                tessellation_set,
                outputs.texgen_set.unwrap_or_default(),
                outputs.draw_set,
            ],
            tracer_constants: push_constants(&self.constants(request.camera, request.settings)),
            constants: push_constants(&tessellate_constants(request, scratch, input)),
            texgen_constants: match (&request.texgen, outputs.texgen_set) {
                (Some(texgen), Some(_)) => Some(push_constants(
                    &texgen.constants(input.vertex_count, part.stride),
                )),
                _ => None,
            },
            draw_constants: push_constants(&DrawConstants {
                eye: request.camera.eye.as_vec3().to_array(),
                hull_split: u32::from(request.hull.is_some()),
            }),
            first,
            written,
            input: [input.vertex_count, input.triangle_count, input.edge_count],
            timestamps: timestamps.as_ref().map(QueryPool::handle),
        };
        let declared = Declared {
            levels,
            texgen: outputs.texgen_set.is_some(),
            buffers: self.buffers(scratch, held, object, Some(&part)),
        };
        let held_part = |object: usize, part: &str| {
            objects
                .get(&object)
                .is_some_and(|o| o.outputs.iter().any(|out| out.part.name == part))
        };
        let work = work::declare_bound(shapes, &declared, &bound, held_part)?;
        if placement == Placement::OnDevice && timestamps.is_none() {
            // Run by the frame that draws the part, as passes of its graph.
            return Ok(DeviceTessellation {
                part,
                work: Some(Arc::new(work)),
                stage_ms: None,
                submission_ms: 0.0,
                submitted: 0,
            });
        }
        let submitted = submit(gpu, submissions, &[&work])?;
        let stage_ms = match &timestamps {
            Some(pool) => {
                submissions.wait(submitted)?;
                let ticks = pool.ticks()?;
                let clock = Clock {
                    valid_bits: self.timestamp_bits,
                    period: gpu.timestamp_period(),
                };
                Some(stage_ms(&ticks, levels, clock))
            }
            None => None,
        };
        Ok(DeviceTessellation {
            part,
            work: None,
            stage_ms,
            submission_ms: 0.0,
            submitted,
        })
    }

    /// Reads the finished mesh of `part`'s tessellation back (a second, short submission: the
    /// sizes are known now) and builds the CPU tessellator's result from it. The tessellation's
    /// submission was waited for, and nothing was submitted since (the caller holds the state).
    fn read_mesh(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        object: usize,
        mesh: &TriangleMesh,
        part: &DeviceLensPart,
        request: &GpuTessellationRequest<'_>,
    ) -> Result<GpuTessellation, TessellationError> {
        let words = resident::count_words(part);
        let PassState {
            tessellation,
            objects,
            submissions,
            ..
        } = state;
        let (Some(scratch), Some(held)) = (tessellation.as_mut(), objects.get(&object)) else {
            return Err(GpuError::Internal(
                "the GPU tessellation: its buffers were not kept".into(),
            )
            .into());
        };
        let input = &held.input;
        let vertex_count = u64::from(words[t::CONTROL_VERTICES as usize]);
        let triangle_count = u64::from(words[t::CONTROL_LEVEL_HI as usize]);
        let output_count = u64::from(words[t::CONTROL_OUTPUT as usize]);
        let output_capacity = scratch.output_capacity();
        if output_count > output_capacity || vertex_count > scratch.vertices_capacity {
            return Err(GpuError::Internal(format!("the GPU tessellation: it made {output_count} triangles and {vertex_count} vertices, past its buffers' {output_capacity} and {}",
                    scratch.vertices_capacity
                ))
            .into());
        }
        let n_in = u64::from(input.vertex_count);
        // (offset in the source, bytes): the mesh, then each array of the lens data.
        let mut spans = vec![
            (0, vertex_count * VERTEX_BYTES),
            (
                0,
                vertex_count * record_bytes(request.settings.classes.terms().len()),
            ),
            (0, 4 * n_in),
            (0, triangle_count * TRIANGLE_BYTES),
            (0, output_count * OUTPUT_BYTES),
        ];
        let arrays = request.texgen.as_ref().map_or(0, TexgenRequest::arrays);
        let stride = 16 * u64::from(part.stride);
        spans.extend((0..arrays).map(|array| (array * stride, 16 * vertex_count)));
        let mut offsets = Vec::with_capacity(spans.len());
        let mut total = 0u64;
        for &(_, bytes) in &spans {
            offsets.push(total);
            total += bytes.next_multiple_of(16);
        }
        scratch.readback(gpu, total.max(16))?;
        let Some(readback) = scratch.readback.as_ref() else {
            return Err(GpuError::Internal(
                "the GPU tessellation: its readback buffer was not made".into(),
            )
            .into());
        };
        let data = DeviceLensPart::buffer_names(&part.name)[0].clone();
        let sources = [
            ("tessellation vertices", &scratch.vertices),
            ("tessellation records", &scratch.records),
            ("tessellation wanted", &scratch.wanted),
            ("tessellation triangles", &scratch.triangles),
            ("tessellation output", &scratch.output),
        ];
        let parts: Vec<(&str, &crate::gpu::Buffer, u64, u64)> = spans
            .iter()
            .enumerate()
            .map(|(i, &(from, bytes))| {
                let (name, buffer) = sources
                    .get(i)
                    .copied()
                    .unwrap_or((data.as_str(), &part.data));
                (name, buffer, from, bytes)
            })
            .collect();
        let mut builder = WorkBuilder::bound();
        let to = builder.buffer("tessellation readback", Some(readback));
        for (index, (&(name, buffer, from, bytes), &offset)) in
            parts.iter().zip(&offsets).enumerate()
        {
            let source = builder.buffer(name, Some(buffer));
            let uses = || vec![(source, Access::TransferRead), (to, Access::TransferWrite)];
            builder.pass(
                format_args!("read {index}"),
                WorkPassKind::Transfer,
                uses,
                || Command::Copy {
                    from: source,
                    to,
                    regions: vec![(from, offset, bytes)],
                },
            );
        }
        builder.pass(
            "read: host",
            WorkPassKind::HostRead,
            || vec![(to, Access::HostRead)],
            || Command::HostRead,
        );
        let work = builder.finish()?;
        let value = submit(gpu, submissions, &[&work])?;
        submissions.wait(value)?;
        let bytes = scratch.read_back();
        let slice = |i: usize| -> &[u32] {
            bytemuck::cast_slice(&bytes[offsets[i] as usize..(offsets[i] + parts[i].3) as usize])
        };
        let counters = resident::read_counts(part).counters;
        let tessellation = assemble(
            mesh,
            Readback {
                vertices: slice(0),
                records: slice(1),
                wanted: slice(2),
                triangles: slice(3),
                output: slice(4),
                classes: request.settings.classes.terms().len(),
            },
            &words,
            &counters,
        );
        let terms = request.texgen.as_ref().map(|texgen| {
            let arrays: Vec<&[[f32; 4]]> = (5..parts.len())
                .map(|i| bytemuck::cast_slice(slice(i)))
                .collect();
            texgen::term_vertices(texgen, &arrays)
        });
        Ok(GpuTessellation {
            submission_ms: 0.0,
            stage_ms: None,
            tessellation,
            counters,
            terms,
        })
    }
}

/// Refuses options the GPU tessellation cannot take: an invalid `t`, a depth cap past
/// [`GPU_MAX_DEPTH`].
fn check_options(options: &TessellationOptions) -> Result<(), TessellationError> {
    if options.validate().is_err() {
        return Err(TessellationError::InvalidThreshold(options.t));
    }
    if options.max_depth > GPU_MAX_DEPTH {
        return Err(crate::options::OptionError::new(
            crate::options::names::MAX_DEPTH,
            options.max_depth,
            "the GPU tessellation subdivides at most 30 levels deep; give 30 or less, or tessellate on the CPU",
        )
        .into());
    }
    Ok(())
}

/// The control words a tessellation of `input` starts from, and how many of them it writes:
/// the frame's budget word is the host's for the frame's first object (or where the host counts
/// the budget), else what the object before left on the device.
fn first_words(
    input: &InputMesh,
    request: &GpuTessellationRequest<'_>,
) -> ([u32; CONTROL_WORDS], usize) {
    let mut first = first_control(input);
    super::buffers::write_classes(&mut first, &request.settings.classes);
    let budget = t::CONTROL_FRAME_BUDGET as usize;
    if request.continue_budget {
        return (first, budget);
    }
    first[budget] = u32::try_from(request.options.max_vertices).unwrap_or(u32::MAX);
    (first, budget + 1)
}

/// The tessellation passes' constants for `request` over `scratch` and `input`.
fn tessellate_constants(
    request: &GpuTessellationRequest<'_>,
    scratch: &Scratch,
    input: &InputMesh,
) -> TessellateConstants {
    let camera = request.camera;
    TessellateConstants {
        view_proj: camera.view_proj.to_cols_array_2d(),
        eye: camera.eye.as_vec3().to_array(),
        t: request.options.t,
        cos_threshold: request.cos_threshold,
        max_depth: request.options.max_depth,
        vertex_capacity: scratch.vertices_capacity as u32,
        edge_capacity: scratch.edges_capacity as u32,
        triangle_capacity: scratch.triangles_capacity as u32,
        input_vertices: input.vertex_count,
        input_triangles: input.triangle_count,
        base_edges: input.edge_count,
        back_faces: u32::from(request.back_faces),
        ..bytemuck::Zeroable::zeroed()
    }
}

/// The control words a frame starts from: level 0 is the input triangles, its vertices the
/// input vertices.
fn first_control(input: &InputMesh) -> [u32; CONTROL_WORDS] {
    let mut words = [0u32; CONTROL_WORDS];
    let (vertices, triangles, edges) = (input.vertex_count, input.triangle_count, input.edge_count);
    let word = |w: u32| w as usize;
    words[word(t::CONTROL_LEVEL_HI)] = triangles;
    words[word(t::CONTROL_NEXT_HI)] = triangles;
    words[word(t::CONTROL_VERTEX_HI)] = vertices;
    words[word(t::CONTROL_VERTICES)] = vertices;
    words[word(t::CONTROL_NEXT_VERTICES)] = vertices;
    words[word(t::CONTROL_EDGES)] = edges;
    words[word(t::CONTROL_NEXT_EDGES)] = edges;
    words[word(t::CONTROL_SCAN_N)] = triangles;
    words[word(t::CONTROL_INPUT_VERTICES)] = vertices;
    let dispatches = [
        (t::CONTROL_DISPATCH_TRACE, vertices.div_ceil(t::WORKGROUP)),
        (
            t::CONTROL_DISPATCH_ELEMENTS,
            triangles.div_ceil(t::WORKGROUP),
        ),
        (
            t::CONTROL_DISPATCH_BLOCKS,
            triangles.div_ceil(t::SCAN_BLOCK),
        ),
    ];
    for (at, groups) in dispatches {
        words[word(at)..word(at) + 3].copy_from_slice(&[groups, 1, 1]);
    }
    words
}

/// How the queue's timestamps count: their valid bits and the nanoseconds of a tick.
struct Clock {
    valid_bits: u32,
    period: f32,
}

/// The stages' device time from a timed tessellation's timestamps: four per level (its trace
/// pass, then its split passes, each begun and ended), then four for the T-junction removal and
/// texgen.
fn stage_ms(ticks: &[u64], levels: u32, clock: Clock) -> GpuStageMs {
    let mask = if clock.valid_bits >= 64 {
        u64::MAX
    } else {
        (1u64 << clock.valid_bits) - 1
    };
    let ms = |from: usize| {
        let (a, b) = (ticks.get(from).copied(), ticks.get(from + 1).copied());
        a.zip(b).map_or(0.0, |(a, b)| {
            (b.wrapping_sub(a) & mask) as f64 * f64::from(clock.period) * 1e-6
        })
    };
    let mut stages = GpuStageMs::default();
    for level in 0..levels as usize {
        stages.trace += ms(4 * level);
        stages.tessellation += ms(4 * level + 2);
    }
    let last = 4 * levels as usize;
    stages.tessellation += ms(last);
    stages.texgen = ms(last + 2);
    stages
}
