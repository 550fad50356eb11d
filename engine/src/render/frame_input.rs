//! What one compositor frame is made of, as plain CPU data: the environment meshes, the lens
//! objects with their per-vertex shading terms and cube-map directions, and the viewpoint samples'
//! layered environment maps. The GPU renderer ([`super::Renderer`]) and the CPU f64 model
//! ([`super::model`]) both consume exactly this.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

use crate::cubemap::CubeMap;
use crate::lightmap::LightMap;
use crate::trace::Term;

/// Maximum number of viewpoint samples blended in one frame (the paper blends the two nearest).
pub const MAX_VIEWPOINTS: usize = 2;

/// Per-vertex data of one shading term of a lens object.
#[derive(Clone, Debug, PartialEq)]
pub struct TermVertices {
    /// Which term.
    pub term: Term,
    /// Per-vertex F·G (Fresnel product times attenuation), rgb, usually in [0, 1].
    pub fg: Vec<Vec3>,
    /// `directions[layer][vertex]`: the cube-map direction (shell hit − EM origin, not normalized).
    pub directions: Vec<Vec<Vec3>>,
}

/// Which faces of a lens object's triangles the compositor draws.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LensFaces {
    /// Front faces only (back faces culled): a closed lens mesh seen from outside, whose back
    /// faces are always hidden behind its front faces.
    #[default]
    Front,
    /// Both faces: an open lens mesh whose inside can be seen (through the gap between a
    /// teapot's lid and rim), with every triangle shaded, back-facing ones included.
    Both,
}

/// A lens object: a triangle mesh whose vertices carry both terms' shading data.
#[derive(Clone, Debug, PartialEq)]
pub struct LensObject {
    /// Debug name (pass labels).
    pub name: String,
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles, counter-clockwise seen from their front side.
    pub triangles: Vec<[u32; 3]>,
    /// Which faces are drawn: back-facing triangles are culled unless [`LensFaces::Both`].
    pub faces: LensFaces,
    /// The terms this object has: a mirror has only [`Term::Reflection`].
    pub terms: Vec<TermVertices>,
    /// `layers[viewpoint][layer]`: the layered EM of each viewpoint sample, nearest shell first.
    /// Every viewpoint has the same number of layers n, equal to each term's `directions.len()`.
    /// Shared (`Arc`): frames reuse the same maps, and the renderer keeps a map uploaded for as
    /// long as frames keep handing it the same `Arc`.
    pub layers: Vec<Vec<Arc<CubeMap>>>,
}

impl LensObject {
    /// Number of layers n of this object's layered EMs.
    pub fn layer_count(&self) -> usize {
        self.layers.first().map_or(0, Vec::len)
    }
}

/// An opaque environment mesh drawn before the lens objects with depth test and write. A
/// fragment shows its interpolated vertex colour times its light map's bilinear sample (1
/// without a light map).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMesh {
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex linear rgb colour (white for a light-mapped mesh whose map holds the radiance).
    pub colours: Vec<Vec3>,
    /// Counter-clockwise triangles (both sides are drawn).
    pub triangles: Vec<[u32; 3]>,
    /// The mesh's light map and its texture coordinates, if it has one.
    pub light_map: Option<MeshLightMap>,
}

/// A light map on an environment mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshLightMap {
    /// Per-vertex texture coordinates into `map`, in [0, 1]².
    pub uvs: Vec<Vec2>,
    /// The map: linear radiance, sampled bilinearly with clamp to edge, one level.
    pub map: LightMap,
}

/// Everything one compositor frame needs.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInput {
    /// Framebuffer width in pixels.
    pub width: u32,
    /// Framebuffer height in pixels.
    pub height: u32,
    /// World → Vulkan clip space (y down, depth 0..1).
    pub view_proj: Mat4,
    /// Opaque environment, drawn first. Shared (`Arc`) like the layered EMs: the renderer keeps a
    /// mesh's buffers for as long as frames keep handing it the same `Arc`.
    pub environment: Vec<Arc<EnvironmentMesh>>,
    /// Lens objects.
    pub lenses: Vec<LensObject>,
    /// Weight of each viewpoint sample (one or two entries, summing to 1). A zero weight skips
    /// that viewpoint's passes.
    pub viewpoint_weights: Vec<f32>,
}

impl FrameInput {
    /// Checks sizes, indices and values before anything reaches the GPU: every mesh index in
    /// range, every value finite, every layered EM the same size with a full chain and valid texels
    /// ([`CubeMap::validate`]), one layered EM per viewpoint weight and unique lens names.
    pub fn validate(&self) -> Result<(), super::RenderError> {
        self.validate_with(&|_| false)
    }

    /// [`FrameInput::validate`], except that the contents of the environment meshes and cube maps
    /// that `checked` knows (by the address of their `Arc`) are not scanned again: the renderer's
    /// upload cache checked them when it first uploaded them, so a frame that hands over the same
    /// maps and meshes pays only for its lens objects. Sizes and counts are still checked.
    pub fn validate_with(&self, checked: &dyn Fn(usize) -> bool) -> Result<(), super::RenderError> {
        let bad = |s: String| Err(super::RenderError::BadInput(s));
        if self.width == 0 || self.height == 0 {
            return bad(format!(
                "width×height is {}×{}; both must be ≥ 1",
                self.width, self.height
            ));
        }
        if self.viewpoint_weights.is_empty() || self.viewpoint_weights.len() > MAX_VIEWPOINTS {
            return bad(format!(
                "viewpoint_weights has {} entries; give 1 or {MAX_VIEWPOINTS}",
                self.viewpoint_weights.len()
            ));
        }
        if self
            .viewpoint_weights
            .iter()
            .any(|w| !w.is_finite() || *w < 0.0)
        {
            return bad(format!(
                "viewpoint_weights {:?} must be finite and ≥ 0",
                self.viewpoint_weights
            ));
        }
        if !self.view_proj.is_finite() {
            return bad(
                "view_proj has NaN or infinite entries; build it from a valid camera".into(),
            );
        }
        for (m, mesh) in self.environment.iter().enumerate() {
            if checked(Arc::as_ptr(mesh) as usize) {
                continue;
            }
            if mesh.colours.len() != mesh.positions.len() {
                return bad(format!(
                    "environment[{m}].colours has {} entries for {} positions; give one per vertex",
                    mesh.colours.len(),
                    mesh.positions.len()
                ));
            }
            check_mesh(
                &format!("environment[{m}]"),
                &mesh.positions,
                &mesh.triangles,
            )?;
            if mesh.colours.iter().any(|c| !c.is_finite()) {
                return bad(format!(
                    "environment[{m}].colours has NaN or infinite values"
                ));
            }
            if let Some(light_map) = &mesh.light_map {
                if light_map.uvs.len() != mesh.positions.len()
                    || light_map.uvs.iter().any(|uv| !uv.is_finite())
                {
                    return bad(format!(
                        "environment[{m}].light_map.uvs needs one finite uv per vertex ({} given for {})",
                        light_map.uvs.len(),
                        mesh.positions.len()
                    ));
                }
                if let Err(error) = light_map.map.validate() {
                    return bad(format!("environment[{m}].light_map.map: {error}"));
                }
            }
        }
        for (l, lens) in self.lenses.iter().enumerate() {
            let at = format!("lenses[{l}] ({})", lens.name);
            check_mesh(&at, &lens.positions, &lens.triangles)?;
            // Pass names and debug labels are made from lens names.
            if self.lenses[..l].iter().any(|other| other.name == lens.name) {
                return bad(format!(
                    "{at}.name is used by an earlier lens; give every lens object its own name"
                ));
            }
            let n = lens.layer_count();
            if n == 0 {
                return bad(format!(
                    "{at}.layers has no layers; give every viewpoint sample at least one layer (cube map)"
                ));
            }
            if lens.layers.len() != self.viewpoint_weights.len() {
                return bad(format!(
                    "{at}.layers has {} viewpoints but viewpoint_weights has {}; give one layered EM per viewpoint sample",
                    lens.layers.len(),
                    self.viewpoint_weights.len()
                ));
            }
            if lens.terms.is_empty() || lens.terms.len() > 2 {
                return bad(format!(
                    "{at}.terms has {} entries; give refraction and/or reflection",
                    lens.terms.len()
                ));
            }
            if lens.terms.len() == 2 && lens.terms[0].term == lens.terms[1].term {
                return bad(format!("{at}.terms names {:?} twice", lens.terms[0].term));
            }
            let size = lens
                .layers
                .first()
                .and_then(|v| v.first())
                .map_or(1, |c| c.size);
            for (v, cubes) in lens.layers.iter().enumerate() {
                if cubes.len() != n {
                    return bad(format!(
                        "{at}.layers[{v}] has {} layers, viewpoint 0 has {n}; every viewpoint needs the same n",
                        cubes.len()
                    ));
                }
                for (i, cube) in cubes.iter().enumerate() {
                    if checked(Arc::as_ptr(cube) as usize) {
                        if cube.size != size {
                            let error = crate::cubemap::CubeMapError::WrongSize {
                                found: cube.size,
                                expected: size,
                            };
                            return bad(format!("{at}.layers[{v}][{i}]: {error}"));
                        }
                        continue;
                    }
                    if let Err(error) = cube.validate(Some(size)) {
                        return bad(format!("{at}.layers[{v}][{i}]: {error}"));
                    }
                }
            }
            for term in &lens.terms {
                let t = format!("{at}.terms[{:?}]", term.term);
                if term.fg.len() != lens.positions.len() || term.fg.iter().any(|c| !c.is_finite()) {
                    return bad(format!(
                        "{t}.fg needs one finite rgb per vertex ({} given for {})",
                        term.fg.len(),
                        lens.positions.len()
                    ));
                }
                if term.directions.len() != n {
                    return bad(format!(
                        "{t}.directions has {} layers, the EMs have {n}",
                        term.directions.len()
                    ));
                }
                for (i, d) in term.directions.iter().enumerate() {
                    if d.len() != lens.positions.len() || d.iter().any(|v| !v.is_finite()) {
                        return bad(format!(
                            "{t}.directions[{i}] needs one finite direction per vertex"
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

fn check_mesh(
    at: &str,
    positions: &[glam::Vec3],
    triangles: &[[u32; 3]],
) -> Result<(), super::RenderError> {
    if positions.iter().any(|p| !p.is_finite()) {
        return Err(super::RenderError::BadInput(format!(
            "{at}.positions has NaN or infinite values"
        )));
    }
    if let Some(t) = triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= positions.len()))
    {
        return Err(super::RenderError::BadInput(format!(
            "{at}.triangles[{t}] indexes past the {} positions",
            positions.len()
        )));
    }
    Ok(())
}
