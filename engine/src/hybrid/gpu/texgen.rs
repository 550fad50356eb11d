//! Texture coordinate generation on the GPU (`shaders/wgsl/texgen.wgsl`), run in the
//! tessellation's submission over the vertices and records it left on the device: per term F·G
//! and per layer the cube-map direction, in f32, written in the lens pass's data layout
//! (positions, then per term F·G and the directions of each layer, `stride` vec4s apart, the
//! stride being the tessellation's vertex capacity so that the offsets are known when
//! recording).

use glam::{DVec3, Vec3};
use lensmap_shaders::TexgenConstants;

use crate::layers::LayerShell;
use crate::render::TermVertices;
use crate::trace::{Term, classes::ClassTerm};

/// What texgen needs of a lens object: its layer shells, nearest first, each with its EM origin,
/// and its terms: whether it has a refraction term (a glass object; the reflection term it
/// always has), or its path classes.
#[derive(Clone, Copy, Debug)]
pub struct TexgenRequest<'a> {
    /// The shells, nearest first.
    pub shells: &'a [LayerShell],
    /// Per shell, the EM origin its directions are taken from.
    pub em_origins: &'a [DVec3],
    /// Whether the refraction term is written (first).
    pub refraction: bool,
    /// The path-class terms written instead of the greedy terms, one per class in this order
    /// (empty: greedy); the tracer's records hold the same list.
    pub classes: &'a [ClassTerm],
}

impl TexgenRequest<'_> {
    /// The terms written, in order.
    pub(crate) fn terms(&self) -> Vec<Term> {
        if !self.classes.is_empty() {
            return self.classes.iter().copied().map(Term::Class).collect();
        }
        let mut terms = Vec::with_capacity(2);
        if self.refraction {
            terms.push(Term::Refraction);
        }
        terms.push(Term::Reflection);
        terms
    }

    /// Arrays of the lens data: the positions, then per term F·G and one per layer.
    pub(crate) fn arrays(&self) -> u64 {
        1 + self.terms().len() as u64 * (1 + self.shells.len() as u64)
    }

    /// The shells as texgen.wgsl reads them: four vec4 per layer.
    pub(super) fn shell_words(&self) -> Vec<[f32; 4]> {
        self.shells
            .iter()
            .zip(self.em_origins)
            .flat_map(|(shell, &origin)| shell_words(shell, origin))
            .collect()
    }

    /// The constants of the pass over a tessellation of `input_vertices` input vertices whose
    /// lens data arrays are `stride` vec4s apart.
    pub(super) fn constants(&self, input_vertices: u32, stride: u32) -> TexgenConstants {
        TexgenConstants {
            input_vertices,
            stride,
            layer_count: self.shells.len() as u32,
            refraction: u32::from(self.refraction),
        }
    }
}

/// Shell kinds (texgen.wgsl `SHELL_*`), which the shader reads from a float word.
const SPHERE: f32 = lensmap_shaders::texgen::SHELL_SPHERE as f32;
const ELLIPSOID: f32 = lensmap_shaders::texgen::SHELL_ELLIPSOID as f32;
const BOX: f32 = lensmap_shaders::texgen::SHELL_BOX as f32;
const CYLINDER: f32 = lensmap_shaders::texgen::SHELL_CYLINDER as f32;
const QUAD: f32 = lensmap_shaders::texgen::SHELL_QUAD as f32;

/// One shell as four vec4: (centre, kind), (a, a_w), (b, b_w), (EM origin, 0).
fn shell_words(shell: &LayerShell, em_origin: DVec3) -> [[f32; 4]; 4] {
    let v = |d: DVec3, w: f64| d.as_vec3().extend(w as f32).to_array();
    let (centre, kind, a, b) = match *shell {
        LayerShell::Sphere { centre, radius } => (centre, SPHERE, v(DVec3::ZERO, radius), [0.0; 4]),
        LayerShell::Ellipsoid { centre, radii } => (centre, ELLIPSOID, v(radii, 0.0), [0.0; 4]),
        LayerShell::Box {
            centre,
            half_extents,
        } => (centre, BOX, v(half_extents, 0.0), [0.0; 4]),
        LayerShell::Cylinder {
            centre,
            axis,
            radius,
            half_height,
        } => (
            centre,
            CYLINDER,
            v(axis, radius),
            v(DVec3::ZERO, half_height.unwrap_or(-1.0)),
        ),
        LayerShell::Quad {
            centre,
            normal,
            u_axis,
            half_extents,
            ..
        } => (
            centre,
            QUAD,
            v(
                normal,
                crate::layers::shell::QUAD_FORCED_DISTANCE_FACTOR * half_extents.length(),
            ),
            v(u_axis, 0.0),
        ),
    };
    [
        centre.as_vec3().extend(kind).to_array(),
        a,
        b,
        v(em_origin, 0.0),
    ]
}

/// The terms' vertex data from the lens data as read back: `arrays[i]` is array i's first
/// `vertex_count` vec4s (the positions first).
pub(super) fn term_vertices(
    request: &TexgenRequest<'_>,
    arrays: &[&[[f32; 4]]],
) -> Vec<TermVertices> {
    let layers = request.shells.len();
    let vec3s = |a: &[[f32; 4]]| a.iter().map(|w| Vec3::new(w[0], w[1], w[2])).collect();
    request
        .terms()
        .into_iter()
        .enumerate()
        .map(|(slot, term)| {
            let base = 1 + slot * (1 + layers);
            TermVertices {
                term,
                fg: vec3s(arrays[base]),
                directions: (0..layers).map(|l| vec3s(arrays[base + 1 + l])).collect(),
            }
        })
        .collect()
}
