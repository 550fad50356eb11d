//! Texture coordinate generation (hybrid-rendering paper §5): each lens vertex's outgoing ray per
//! shading term against each layer shell of its lens object gives the cube-map direction into
//! that layer's EM, and the term's F·G weights it.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{
    paths::{TermPath, VertexPaths, VertexPrecision},
    scene::LensLayers,
    tessellate::VertexEvaluation,
    viewpoints::ViewpointBlend,
};
use crate::{
    render::{LensFaces, LensObject, TermVertices},
    trace::{Interface, Term, classes::ClassTerm, world::TraceScene},
};

/// A lens object's tessellated mesh and the faces its passes draw.
pub(super) struct LensMesh {
    /// Vertex positions, metres.
    pub positions: Vec<Vec3>,
    /// Triangles, indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// The faces its passes draw.
    pub faces: LensFaces,
    /// Its last this many triangles are drawn without the local layer (the convex-hull split).
    pub hull_triangles: usize,
}

/// Texture coordinates: each vertex's outgoing ray per term against each layer shell gives the
/// cube-map direction `hit − EM origin` (computed in `precision`); F·G per term. The terms are
/// the two greedy ones, or one per class of `classes` (the oracle's list) where it is not empty.
/// Vertices with no path of a term (back-facing only, no refraction at the first interface, a
/// path of another class) get F·G = 0 and the direction of their reflection (of their first
/// class that has a path, under classes), so that a triangle's lookups stay near its lit
/// vertices'.
#[allow(clippy::too_many_arguments)]
pub(super) fn texgen(
    trace: &TraceScene,
    lens: usize,
    layers: &LensLayers,
    mesh: LensMesh,
    samples: &[Option<VertexEvaluation<VertexPaths>>],
    classes: &[ClassTerm],
    blend: &ViewpointBlend,
    precision: VertexPrecision,
) -> LensObject {
    let LensMesh {
        positions,
        triangles,
        faces,
        hull_triangles,
    } = mesh;
    let terms: Vec<Term> = if !classes.is_empty() {
        classes.iter().copied().map(Term::Class).collect()
    } else if has_refraction(trace, lens) {
        vec![Term::Refraction, Term::Reflection]
    } else {
        vec![Term::Reflection]
    };
    let fallback_direction =
        |position: Vec3, em_origin: DVec3| (position.as_dvec3() - em_origin).normalize_or(DVec3::Z);
    let unlit = |p: &TermPath| TermPath {
        fg: DVec3::ZERO,
        ..*p
    };
    let term_vertices = terms
        .iter()
        .enumerate()
        .map(|(k, &term)| {
            let path = |v: usize| {
                samples[v]
                    .as_ref()
                    .map(|e| &e.sample)
                    .and_then(|s| match term {
                        Term::Class(_) => s
                            .classes
                            .get(k)
                            .copied()
                            .flatten()
                            .or_else(|| s.classes.iter().flatten().next().map(unlit)),
                        _ => s.get(term).copied().or(s.get(Term::Reflection).map(unlit)),
                    })
            };
            let fg = (0..positions.len())
                .map(|v| path(v).map_or(Vec3::ZERO, |p| p.fg.as_vec3()))
                .collect();
            // Every (vertex, shell) is independent: in parallel, collected in order.
            let directions = layers
                .shells
                .iter()
                .zip(&layers.em_origins)
                .map(|(shell, &em_origin)| {
                    (0..positions.len())
                        .into_par_iter()
                        .map(|v| match path(v) {
                            Some(p) => {
                                let (origin, direction) = (p.outgoing.origin, p.outgoing.direction);
                                match precision {
                                    VertexPrecision::F64 => shell
                                        .texture_direction_for_ray(em_origin, origin, direction),
                                    VertexPrecision::F32 => shell
                                        .texture_direction_for_ray_in::<f32>(
                                            em_origin, origin, direction,
                                        ),
                                }
                                .as_vec3()
                            }
                            None => fallback_direction(positions[v], em_origin).as_vec3(),
                        })
                        .collect()
                })
                .collect();
            TermVertices {
                term,
                fg,
                directions,
            }
        })
        .collect();
    let mesh = LensMesh {
        positions,
        triangles,
        faces,
        hull_triangles,
    };
    lens_object(
        trace.lenses[lens].name.clone(),
        layers,
        mesh,
        term_vertices,
        blend,
    )
}

/// Whether lens object `lens` has a refraction term: some object of it is glass.
pub(super) fn has_refraction(trace: &TraceScene, lens: usize) -> bool {
    trace.lenses[lens].objects.iter().any(|&o| {
        trace
            .interface(o)
            .is_some_and(|i| matches!(i, Interface::Dielectric { .. }))
    })
}

/// The lens object of `mesh` with its terms' vertex data and the layered EMs of the viewpoint
/// samples `blend` uses.
pub(super) fn lens_object(
    name: String,
    layers: &LensLayers,
    mesh: LensMesh,
    terms: Vec<TermVertices>,
    blend: &ViewpointBlend,
) -> LensObject {
    LensObject {
        name,
        positions: mesh.positions,
        triangles: mesh.triangles,
        faces: mesh.faces,
        hull_triangles: mesh.hull_triangles,
        terms,
        layers: blend
            .samples
            .iter()
            .map(|(sample, _)| layers.maps[(*sample).min(layers.maps.len() - 1)].clone())
            .collect(),
        resident: None,
    }
}

/// The terms of a lens object whose per-vertex data the GPU holds ([`TexgenRequest`]'s, in the
/// order its data holds them), with no vertex data: one empty direction list per layer.
pub(super) fn resident_terms(request: &super::gpu::TexgenRequest<'_>) -> Vec<TermVertices> {
    request
        .terms()
        .into_iter()
        .map(|term| TermVertices {
            term,
            fg: Vec::new(),
            directions: vec![Vec::new(); request.shells.len()],
        })
        .collect()
}
