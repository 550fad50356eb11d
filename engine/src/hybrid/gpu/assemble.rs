//! The CPU tessellator's result ([`Tessellation`]) rebuilt from the GPU tessellation's buffers
//! as read back ([`super::tessellate`]).

use glam::{Vec2, Vec3};

use super::tessellate::control;
use super::{RECORD_BYTES, decode};
use crate::hybrid::paths::VertexPaths;
use crate::hybrid::tessellate::{
    StopReason, Tessellation, TessellationStats, TriangleRecord, VertexEvaluation, VertexOrigin,
};
use crate::scene::TriangleMesh;
use crate::trace::stats::TraceCounters;

/// The GPU's buffers as read back, as words.
pub(super) struct Readback<'a> {
    pub(super) vertices: &'a [u32],
    pub(super) records: &'a [u32],
    pub(super) wanted: &'a [u32],
    pub(super) triangles: &'a [u32],
    pub(super) output: &'a [u32],
}

/// The stop reason of a state word (tessellate.wgsl `STOP_*`).
fn stop_reason(state: u32) -> StopReason {
    match state & 15 {
        1 => StopReason::BackFacing,
        2 => StopReason::Degenerate,
        3 => StopReason::Occluded,
        4 => StopReason::OffScreen,
        6 => StopReason::Small,
        7 => StopReason::MaxDepth,
        8 => StopReason::Budget,
        _ => StopReason::Similar,
    }
}

/// The CPU tessellator's result from the GPU's buffers.
pub(super) fn assemble(
    mesh: &TriangleMesh,
    read: Readback<'_>,
    words: &[u32],
    counters: &TraceCounters,
) -> Tessellation<VertexPaths> {
    let n_in = mesh.positions.len();
    let vertex_count = read.vertices.len() / 8;
    let f = |w: u32| f32::from_bits(w);
    let mut positions = Vec::with_capacity(vertex_count);
    let mut normals = Vec::with_capacity(vertex_count);
    let mut origins = Vec::with_capacity(vertex_count);
    for (i, v) in read.vertices.chunks_exact(8).enumerate() {
        positions.push(Vec3::new(f(v[0]), f(v[1]), f(v[2])));
        normals.push(Vec3::new(f(v[4]), f(v[5]), f(v[6])));
        origins.push(if i < n_in {
            VertexOrigin::Input(i as u32)
        } else {
            VertexOrigin::Midpoint([v[3], v[7]])
        });
    }
    let mut uvs = Vec::new();
    if mesh.uvs.len() == n_in && n_in > 0 {
        uvs.extend_from_slice(&mesh.uvs);
        for origin in &origins[n_in..] {
            // A midpoint's ends come before it, so their uvs are there.
            let uv = match *origin {
                VertexOrigin::Midpoint([lo, hi]) => {
                    (uvs.get(lo as usize).copied().unwrap_or(Vec2::ZERO)
                        + uvs.get(hi as usize).copied().unwrap_or(Vec2::ZERO))
                        * 0.5
                }
                VertexOrigin::Input(i) => mesh.uvs[i as usize],
            };
            uvs.push(uv);
        }
    }
    let record_words = (RECORD_BYTES / 4) as usize;
    let evaluations = read
        .records
        .chunks_exact(record_words)
        .enumerate()
        .map(|(i, record)| {
            let traced = i >= n_in || read.wanted.get(i).is_some_and(|&w| w != 0);
            traced.then(|| {
                let vertex = decode(record);
                VertexEvaluation {
                    sample: vertex.paths,
                    visible: vertex.visible,
                }
            })
        })
        .collect();
    let leaf = |t: u32| {
        let at = 8 * t as usize;
        let head = &read.triangles[at..at + 4];
        let state = read.triangles[at + 7];
        TriangleRecord {
            source: head[3],
            leaf: [head[0], head[1], head[2]],
            depth: state >> 8,
            stop: stop_reason(state),
        }
    };
    let (triangles, records): (Vec<[u32; 3]>, Vec<TriangleRecord>) = read
        .output
        .chunks_exact(4)
        .map(|o| ([o[0], o[1], o[2]], leaf(o[3])))
        .unzip();
    let stats = TessellationStats {
        input_triangles: mesh.triangles.len(),
        front_facing_triangles: words[control::FRONT] as usize,
        back_facing_triangles: words[control::BACK] as usize,
        output_triangles: triangles.len(),
        output_vertices: vertex_count,
        vertices_evaluated: counters.primary_rays as usize,
        midpoints_created: words[control::CREATED] as usize,
        midpoints_reused: words[control::REQUESTS].saturating_sub(words[control::CREATED]) as usize,
        splits_1_to_2: words[control::SPLITS] as usize,
        splits_1_to_3: words[control::SPLITS + 1] as usize,
        splits_1_to_4: words[control::SPLITS + 2] as usize,
        max_depth_reached: words[control::MAX_DEPTH_REACHED],
        stopped_at_max_depth: words[control::AT_MAX_DEPTH] as usize,
        stopped_by_budget: words[control::BUDGET] as usize,
        occluded_leaves: words[control::OCCLUDED] as usize,
        t_junction_leaves: words[control::T_JUNCTION_LEAVES] as usize,
        t_junction_vertices: words[control::T_JUNCTION_VERTICES] as usize,
    };
    Tessellation {
        mesh: TriangleMesh {
            positions,
            normals,
            uvs,
            triangles,
        },
        origins,
        evaluations,
        triangles: records,
        stats,
    }
}
