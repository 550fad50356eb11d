//! The CPU tessellator's result ([`Tessellation`]) rebuilt from the GPU tessellation's buffers
//! as read back ([`super::tessellate`]).

use glam::{DVec3, Vec2, Vec3};
use lensmap_shaders::tessellate as t;

use super::buffers::record_bytes;
use crate::hybrid::paths::{TermPath, VertexPaths};
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
    /// Path-class terms each record holds (0: the two greedy terms).
    pub(super) classes: usize,
}

/// The stop reason of a state word (tessellate.wgsl `STOP_*`).
fn stop_reason(state: u32) -> StopReason {
    // The stop reason is the state word's low four bits.
    match state & 0xf {
        t::STOP_BACK_FACING => StopReason::BackFacing,
        t::STOP_DEGENERATE => StopReason::Degenerate,
        t::STOP_OCCLUDED => StopReason::Occluded,
        t::STOP_OFF_SCREEN => StopReason::OffScreen,
        t::STOP_SMALL => StopReason::Small,
        t::STOP_MAX_DEPTH => StopReason::MaxDepth,
        t::STOP_BUDGET => StopReason::Budget,
        _ => StopReason::Similar,
    }
}

/// One vertex as the GPU traced it.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuVertex {
    /// Both greedy terms' paths, or each path class's (f32 values widened).
    pub paths: VertexPaths,
    /// Whether the eye sees the vertex.
    pub visible: bool,
    /// Screen position in subpixels, when it has one.
    pub screen: Option<Vec2>,
}

/// One vertex record's words (vertex_paths.wgsl `write_term`) of `classes` path-class terms (0:
/// the two greedy terms) as a [`GpuVertex`].
pub(super) fn decode(w: &[u32], classes: usize) -> GpuVertex {
    let f = |i: usize| f32::from_bits(w[i]);
    let v3 = |i: usize| DVec3::new(f64::from(f(i)), f64::from(f(i + 1)), f64::from(f(i + 2)));
    let term = |slot: usize| {
        let base = 12 * slot;
        (f(base + 11) != 0.0).then(|| TermPath {
            fg: v3(base),
            outgoing: crate::trace::Ray {
                origin: v3(base + 4),
                direction: v3(base + 8),
            },
            topology: (w[base + 3], w[base + 7]),
        })
    };
    let at = 12 * classes.max(2);
    let screen = (f(at + 2) != 0.0).then(|| Vec2::new(f(at), f(at + 1)));
    let paths = match classes {
        0 => VertexPaths {
            terms: [term(0), term(1)],
            classes: Vec::new(),
        },
        _ => VertexPaths {
            terms: [None, None],
            classes: (0..classes).map(term).collect(),
        },
    };
    GpuVertex {
        paths,
        visible: f(at + 3) != 0.0,
        screen,
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
    let record_words = (record_bytes(read.classes) / 4) as usize;
    let evaluations = read
        .records
        .chunks_exact(record_words)
        .enumerate()
        .map(|(i, record)| {
            let traced = i >= n_in || read.wanted.get(i).is_some_and(|&w| w != 0);
            traced.then(|| {
                let vertex = decode(record, read.classes);
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
        front_facing_triangles: words[t::STAT_FRONT as usize] as usize,
        back_facing_triangles: words[t::STAT_BACK as usize] as usize,
        output_triangles: triangles.len(),
        output_vertices: vertex_count,
        vertices_evaluated: counters.primary_rays as usize,
        midpoints_created: words[t::STAT_CREATED as usize] as usize,
        midpoints_reused: words[t::STAT_REQUESTS as usize]
            .saturating_sub(words[t::STAT_CREATED as usize]) as usize,
        splits_1_to_2: words[t::STAT_SPLITS as usize] as usize,
        splits_1_to_3: words[t::STAT_SPLITS as usize + 1] as usize,
        splits_1_to_4: words[t::STAT_SPLITS as usize + 2] as usize,
        max_depth_reached: words[t::STAT_MAX_DEPTH_REACHED as usize],
        stopped_at_max_depth: words[t::STAT_AT_MAX_DEPTH as usize] as usize,
        stopped_by_budget: words[t::STAT_BUDGET as usize] as usize,
        occluded_leaves: words[t::STAT_OCCLUDED as usize] as usize,
        t_junction_leaves: words[t::STAT_T_JUNCTION_LEAVES as usize] as usize,
        t_junction_vertices: words[t::STAT_T_JUNCTION_VERTICES as usize] as usize,
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
