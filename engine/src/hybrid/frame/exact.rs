//! The frame with *perfect information at each vertex*: every lens object tessellated as a
//! frame on the CPU does it, but drawn as an opaque mesh whose vertex colours are the exact
//! two-term radiance there, interpolated across each triangle. What it misses against the
//! reference is what the tessellation's vertices cannot carry, whatever the layered EMs: the
//! error budget's tessellation share (`lensmap bench bake`).

use std::{sync::Arc, time::Instant};

use glam::DVec3;
use rayon::prelude::*;

use super::{
    HybridOptions, HybridStats, VertexTracer, assemble, assembled_ms, begin_frame,
    gpu_without_device,
    stage::{CpuLens, VertexBudget, tessellate_on_cpu},
    view::LensJob,
};
use crate::hybrid::tessellate::TessellationError;
use crate::{
    hybrid::scene::HybridScene, index::LensIndex, render::EnvironmentMesh, render::FrameInput,
    scene::Camera, trace::stats::TraceCounters,
};

/// The vertex-exact frame of `scene` for `camera`: each term's `F·G` times the reference
/// tracer's radiance along the vertex's outgoing ray, at every vertex of the tessellation a
/// frame with `options` makes on the CPU. Not kept by any frame cache.
pub fn vertex_exact_frame(
    scene: &HybridScene,
    camera: &Camera,
    options: &HybridOptions,
) -> Result<(FrameInput, HybridStats), TessellationError> {
    if options.tracer == VertexTracer::Gpu {
        return Err(gpu_without_device().into());
    }
    let start = Instant::now();
    let (view, blend, mut stats) = begin_frame(scene, camera, options)?;
    let mut budget = VertexBudget::new(options.tessellation.max_vertices);
    let mut exact = Vec::new();
    for lens in LensIndex::all(scene.trace().lenses.len()) {
        let job = LensJob::new(scene, lens, &view, options, &blend, &mut stats)?;
        let traced = tessellate_on_cpu(&job, &mut budget, &mut stats)?;
        exact.push(Arc::new(vertex_radiance_mesh(scene, lens, traced)));
    }
    let frame = assemble(scene, view, &blend, Vec::new(), exact, &mut stats);
    stats.assemble_ms = assembled_ms(start, &stats);
    Ok((frame, stats))
}

/// Lens object `lens`'s tessellated mesh as an opaque mesh coloured with the exact radiance at
/// each vertex; black where a vertex has no path.
fn vertex_radiance_mesh(scene: &HybridScene, lens: LensIndex, traced: CpuLens) -> EnvironmentMesh {
    let options = crate::trace::TraceOptions::default();
    let trace = scene.trace();
    let colours = traced
        .samples
        .par_iter()
        .map(|sample| {
            let mut counters = TraceCounters::default();
            let mut radiance = DVec3::ZERO;
            let paths = sample
                .iter()
                .flat_map(|s| s.sample.terms.iter().chain(&s.sample.classes).flatten());
            for path in paths {
                if path.fg != DVec3::ZERO {
                    radiance += path.fg
                        * trace.outgoing_radiance(
                            &path.outgoing,
                            lens.index(),
                            1,
                            &options,
                            &mut counters,
                        );
                }
            }
            radiance.as_vec3()
        })
        .collect();
    EnvironmentMesh {
        positions: traced.mesh.positions,
        colours,
        triangles: traced.mesh.triangles,
        light_map: None,
    }
}
