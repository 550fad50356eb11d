//! What a frame's plan depends on, and nothing more: its size, its environment mesh count, and
//! per lens object its triangles, faces, terms and which layers are empty. Taken from a frame's
//! data ([`FrameShape::of`]) or made up for experiments ([`FrameShape::synthetic`]).

use std::sync::Arc;

use crate::cubemap::CubeMap;
use crate::render::{FrameInput, LensFaces};
use crate::trace::Term;

/// What the plan of one lens object depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct LensShape {
    /// Debug name.
    pub name: String,
    /// Number of triangles (0 → no passes); for a lens object resident on the device, which
    /// alone knows its count, its number of parts (each drawn by indirect draws).
    pub triangles: usize,
    /// Which faces are drawn: [`LensFaces::Both`] makes every lens pass cull nothing.
    pub faces: LensFaces,
    /// The terms present, in group order (refraction before reflection).
    pub terms: Vec<Term>,
    /// `empty[viewpoint][layer]`: the layer's cube map is all zeros, so its pass changes nothing.
    pub empty: Vec<Vec<bool>>,
    /// The parts of a lens object resident on the device (none for the rest), each with the
    /// compute work that makes it (the GPU tessellation), run in this frame before the lens
    /// passes; `None` once the work ran (a frame drawn again).
    pub parts: Vec<PartShape>,
}

/// One part of a lens object resident on the device.
#[derive(Clone, Debug, PartialEq)]
pub struct PartShape {
    /// Its name ([`crate::render::DeviceLensPart::buffer_names`] names its buffers).
    pub name: String,
    /// The work that makes it in this frame, or `None`.
    pub work: Option<Arc<crate::render::compute::WorkShape>>,
}

impl LensShape {
    /// Layers n.
    pub fn layer_count(&self) -> usize {
        self.empty.first().map_or(0, Vec::len)
    }
}

/// What a frame's plan depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameShape {
    /// Framebuffer size.
    pub width: u32,
    /// Framebuffer size.
    pub height: u32,
    /// Number of environment meshes (one draw each).
    pub environment_meshes: usize,
    /// The glossy objects' names (one draw each, in the glossy pass).
    pub glossy: Vec<String>,
    /// Lens objects.
    pub lenses: Vec<LensShape>,
    /// Viewpoint weights.
    pub viewpoint_weights: Vec<f32>,
}

impl FrameShape {
    /// `[viewpoint][layer]`: whether the layer's cube map is all zeros (its pass changes
    /// nothing and is not recorded).
    pub fn empty_layers(layers: &[Vec<Arc<CubeMap>>]) -> Vec<Vec<bool>> {
        layers
            .iter()
            .map(|cubes| cubes.iter().map(|cube| cube.is_all_zero()).collect())
            .collect()
    }

    /// The shape of a frame's data, with `empty` saying whether a cube map is all zeros
    /// ([`CubeMap::is_all_zero`], or the renderer's cached answer, which saves the scan).
    pub fn of(frame: &FrameInput, empty: impl Fn(&Arc<CubeMap>) -> bool) -> FrameShape {
        FrameShape {
            width: frame.width,
            height: frame.height,
            environment_meshes: frame
                .environment
                .iter()
                .filter(|m| !m.triangles.is_empty())
                .count(),
            glossy: frame.glossy.iter().map(|g| g.name.clone()).collect(),
            lenses: frame
                .lenses
                .iter()
                .map(|lens| {
                    let mut terms: Vec<Term> = lens.terms.iter().map(|t| t.term).collect();
                    terms.sort();
                    LensShape {
                        name: lens.name.clone(),
                        triangles: lens
                            .resident
                            .as_ref()
                            .map_or(lens.triangles.len(), |r| r.parts.len()),
                        parts: lens.resident.as_ref().map_or_else(Vec::new, |r| {
                            // All or none: a frame records every work of its parts, or none.
                            let pending = r.works.len() == r.parts.len()
                                && r.works.iter().all(|w| w.pending());
                            r.parts
                                .iter()
                                .zip(r.works.iter().map(Some).chain(std::iter::repeat(None)))
                                .map(|(part, work)| PartShape {
                                    name: part.name.clone(),
                                    work: work.filter(|_| pending).map(|w| w.shape.clone()),
                                })
                                .collect()
                        }),
                        faces: lens.faces,
                        terms,
                        empty: lens
                            .layers
                            .iter()
                            .map(|cubes| cubes.iter().map(&empty).collect())
                            .collect(),
                    }
                })
                .collect(),
            viewpoint_weights: frame.viewpoint_weights.clone(),
        }
    }

    /// Whether `self` and `other` have one plan: equal but for the viewpoints' weights, of
    /// which a plan sees only which are above zero ([`FrameShape::active_viewpoints`]).
    pub fn plans_alike(&self, other: &FrameShape) -> bool {
        let FrameShape {
            width,
            height,
            environment_meshes,
            glossy,
            lenses,
            viewpoint_weights,
        } = self;
        let active = |weights: &[f32]| weights.iter().map(|w| *w > 0.0).collect::<Vec<_>>();
        *width == other.width
            && *height == other.height
            && *environment_meshes == other.environment_meshes
            && *glossy == other.glossy
            && *lenses == other.lenses
            && active(viewpoint_weights) == active(&other.viewpoint_weights)
    }

    /// The viewpoint samples whose passes a lens object's plan holds: those with a weight above
    /// zero that the lens has a layered EM for, in order.
    pub fn active_viewpoints(&self, lens: &LensShape) -> Vec<usize> {
        self.viewpoint_weights
            .iter()
            .enumerate()
            .filter(|(v, w)| **w > 0.0 && *v < lens.empty.len())
            .map(|(v, _)| v)
            .collect()
    }

    /// The most layers a pass-count experiment may ask for: the multipass variant has no shader
    /// limit, but its plan grows as 2n passes per viewpoint, so the bound keeps a plan printable
    /// (256 layers, three viewpoints: about 1,500 passes) instead of letting one number exhaust
    /// memory.
    pub const MAX_EXPERIMENT_LAYERS: usize = 256;

    /// A synthetic shape for experiments (`lensmap passes`): one lens object with `layers` layers,
    /// `viewpoints` samples of equal weight and the given terms.
    pub fn synthetic(
        width: u32,
        height: u32,
        layers: usize,
        viewpoints: usize,
        terms: &[Term],
    ) -> FrameShape {
        let viewpoints = viewpoints.max(1);
        FrameShape {
            width,
            height,
            environment_meshes: 1,
            glossy: Vec::new(),
            lenses: vec![LensShape {
                name: "lens".into(),
                triangles: 1,
                faces: LensFaces::Front,
                terms: terms.to_vec(),
                empty: vec![vec![false; layers]; viewpoints],
                parts: Vec::new(),
            }],
            viewpoint_weights: vec![1.0 / viewpoints as f32; viewpoints],
        }
    }
}
