//! What one compositor frame is made of, as plain CPU data: the environment meshes, the lens
//! objects with their per-vertex shading terms and cube-map directions, and the viewpoint samples'
//! layered environment maps. The GPU renderer ([`super::Renderer`]) and the CPU f64 model
//! ([`super::model`]) both consume exactly this.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

use super::RenderError;
use crate::cubemap::CubeMap;
use crate::gpu::Buffer;
use crate::lightmap::LightMap;
use crate::trace::Term;

/// Maximum number of viewpoint samples blended in one frame: the three samples of the spherical
/// triangle that holds the camera direction (two on an edge, or along a circle, one at a sample).
/// The single pass samples that many cube-map arrays at once (`const MAX_VIEWPOINTS` in
/// `shaders/wgsl/lens.wgsl`, checked equal at compile time).
pub const MAX_VIEWPOINTS: usize = 3;

const _: () = assert!(MAX_VIEWPOINTS == lensmap_shaders::MAX_VIEWPOINTS as usize);

/// The most shading terms one lens object carries: the most classes a path-class set holds
/// ([`crate::trace::classes::MAX_CLASSES`]). The multipass variant records V·n layer passes
/// per term; the single pass takes the two greedy terms.
pub const MAX_TERMS: usize = crate::trace::classes::MAX_CLASSES;

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
    /// The last this many of `triangles` are drawn without layer 0 (its sample taken as
    /// (0, 0, 0, 0), the identity of every blend): the convex-hull split of a lens object layered
    /// by bounce, whose layer 0 is the local layer these triangles cannot show. 0 for others.
    pub hull_triangles: usize,
    /// The terms this object has: a mirror has only [`Term::Reflection`].
    pub terms: Vec<TermVertices>,
    /// `layers[viewpoint][layer]`: the layered EM of each viewpoint sample, nearest shell first.
    /// Every viewpoint has the same number of layers n, equal to each term's `directions.len()`.
    /// (A resident object's terms name its terms, with no per-vertex data.)
    /// Shared (`Arc`): frames reuse the same maps, and the renderer keeps a map uploaded for as
    /// long as frames keep handing it the same `Arc`.
    pub layers: Vec<Vec<Arc<CubeMap>>>,
    /// Where the mesh and the per-vertex data are on the device instead: a lens object
    /// tessellated on the GPU and drawn from the tessellation's own buffers, with no per-vertex
    /// data on the host (`positions`, `triangles` and the terms' vectors are then empty, and
    /// `hull_triangles` 0). `None`: the host data above is uploaded.
    pub resident: Option<ResidentLens>,
}

impl LensObject {
    /// Number of layers n of this object's layered EMs.
    pub fn layer_count(&self) -> usize {
        self.layers.first().map_or(0, Vec::len)
    }

    /// Whether it has no triangle to draw (a resident object may have some: only the device
    /// knows how many).
    pub fn is_empty(&self) -> bool {
        self.resident
            .as_ref()
            .map_or(self.triangles.is_empty(), |r| r.parts.is_empty())
    }
}

/// A lens object's mesh and per-vertex data where the GPU tessellation leaves them: one part per
/// scene object, each drawn by indirect draws whose arguments the GPU wrote.
#[derive(Clone)]
pub struct ResidentLens {
    /// The parts, each a scene object's tessellation, drawn in order.
    pub parts: Vec<Arc<DeviceLensPart>>,
    /// The compute work that makes the parts, whose passes the frame's graph declares before
    /// its lens passes (only the first time the frame is drawn): one per part, or none where the
    /// parts were made already. Its handles stay valid until the frame's submission completes
    /// (its maker's promise).
    pub works: Vec<Arc<super::compute::ComputeWork>>,
}

impl PartialEq for ResidentLens {
    /// The same buffers (a frame that hands over the same parts draws the same data).
    fn eq(&self, other: &ResidentLens) -> bool {
        self.parts.len() == other.parts.len()
            && self
                .parts
                .iter()
                .zip(&other.parts)
                .all(|(a, b)| Arc::ptr_eq(a, b))
    }
}

impl std::fmt::Debug for ResidentLens {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ResidentLens")
            .field("parts", &self.parts.len())
            .field("works", &self.works.len())
            .finish()
    }
}

/// One scene object's tessellation on the device, as the lens passes draw it.
pub struct DeviceLensPart {
    /// Its name in plans: its buffers are [`DeviceLensPart::buffer_names`] of it.
    pub name: String,
    /// The lens pass's data (positions, then per term F·G and each layer's directions), arrays
    /// `stride` vec4s apart, in the order of the lens object's terms.
    pub data: Buffer,
    /// Three indices per triangle, the convex-hull split's last.
    pub indices: Buffer,
    /// Three `VkDrawIndexedIndirectCommand`s: every triangle, the non-hull ones, the hull's
    /// ([`INDIRECT_ALL`], [`INDIRECT_REST`], [`INDIRECT_HULL`]).
    pub args: Buffer,
    /// vec4s between consecutive arrays of `data` (the tessellation's vertex capacity).
    pub stride: u32,
    /// The host copy of the tessellation's counts, written by the GPU with the part and read
    /// once the frame that drew it is done (off the frame's critical path).
    pub counts: Buffer,
}

impl DeviceLensPart {
    /// The names in plans of the buffers of part `name` that the lens passes read (its data,
    /// indices and draw arguments), and that the work making it writes.
    pub fn buffer_names(name: &str) -> [String; 3] {
        [
            format!("{name} data"),
            format!("{name} indices"),
            format!("{name} draws"),
        ]
    }
}

/// Byte offsets of the indirect draws in [`DeviceLensPart::args`].
pub const INDIRECT_ALL: u64 = 0;
/// See [`INDIRECT_ALL`].
pub const INDIRECT_REST: u64 = 20;
/// See [`INDIRECT_ALL`].
pub const INDIRECT_HULL: u64 = 40;

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
    /// Glossy objects, drawn after the environment by reflection-space IBR.
    pub glossy: Vec<super::glossy::GlossyDraw>,
    /// Lens objects.
    pub lenses: Vec<LensObject>,
    /// Weight of each viewpoint sample (1 to [`MAX_VIEWPOINTS`] entries, summing to 1). A zero
    /// weight skips that viewpoint's passes.
    pub viewpoint_weights: Vec<f32>,
}

impl FrameInput {
    /// Checks sizes, indices and values before anything reaches the GPU: every mesh index in
    /// range, every value finite, every layered EM the same size with a full chain and valid texels
    /// ([`CubeMap::validate`]), one layered EM per viewpoint weight and unique lens names.
    pub fn validate(&self) -> Result<(), RenderError> {
        self.validate_unless_checked(&|_| false)
    }

    /// [`FrameInput::validate`], except that the contents of the environment meshes and cube maps
    /// that `checked` knows (by the address of their `Arc`) are not scanned again: the renderer's
    /// upload cache checked them when it first uploaded them, so a frame that hands over the same
    /// maps and meshes pays only for its lens objects. Sizes and counts are still checked.
    pub(super) fn validate_unless_checked(
        &self,
        checked: &dyn Fn(usize) -> bool,
    ) -> Result<(), RenderError> {
        self.validate_frame()?;
        for (m, mesh) in self.environment.iter().enumerate() {
            if !checked(Arc::as_ptr(mesh) as usize) {
                mesh.validate(m)?;
            }
        }
        for (g, glossy) in self.glossy.iter().enumerate() {
            glossy.validate(g, checked)?;
        }
        for (l, lens) in self.lenses.iter().enumerate() {
            let at = format!("lenses[{l}] ({})", lens.name);
            check_mesh(&at, &lens.positions, &lens.triangles)?;
            if lens.hull_triangles > lens.triangles.len() {
                return bad(format!(
                    "{at}.hull_triangles is {} but the lens has {} triangles; give at most that \
                     many (the last ones are drawn without layer 0)",
                    lens.hull_triangles,
                    lens.triangles.len()
                ));
            }
            // Pass names and debug labels are made from lens names.
            if self.lenses[..l].iter().any(|other| other.name == lens.name) {
                return bad(format!(
                    "{at}.name is used by an earlier lens; give every lens object its own name"
                ));
            }
            lens.validate(&at, self.viewpoint_weights.len(), checked)?;
        }
        Ok(())
    }

    /// The frame's size, viewpoint weights and view-projection.
    fn validate_frame(&self) -> Result<(), RenderError> {
        if self.width == 0 || self.height == 0 {
            return bad(format!(
                "width×height is {}×{}; both must be ≥ 1",
                self.width, self.height
            ));
        }
        if self.viewpoint_weights.is_empty() || self.viewpoint_weights.len() > MAX_VIEWPOINTS {
            return bad(format!(
                "viewpoint_weights has {} entries; give 1 to {MAX_VIEWPOINTS}, one per blended viewpoint sample",
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
        Ok(())
    }
}

impl EnvironmentMesh {
    /// Environment mesh `m`'s sizes, indices and values, and its light map's.
    fn validate(&self, m: usize) -> Result<(), RenderError> {
        if self.colours.len() != self.positions.len() {
            return bad(format!(
                "environment[{m}].colours has {} entries for {} positions; give one per vertex",
                self.colours.len(),
                self.positions.len()
            ));
        }
        check_mesh(
            &format!("environment[{m}]"),
            &self.positions,
            &self.triangles,
        )?;
        if self.colours.iter().any(|c| !c.is_finite()) {
            return bad(format!(
                "environment[{m}].colours has NaN or infinite values"
            ));
        }
        if let Some(light_map) = &self.light_map {
            if light_map.uvs.len() != self.positions.len()
                || light_map.uvs.iter().any(|uv| !uv.is_finite())
            {
                return bad(format!(
                    "environment[{m}].light_map.uvs needs one finite uv per vertex ({} given for {})",
                    light_map.uvs.len(),
                    self.positions.len()
                ));
            }
            if let Err(error) = light_map.map.validate() {
                return bad(format!("environment[{m}].light_map.map: {error}"));
            }
        }
        Ok(())
    }
}

impl LensObject {
    /// The lens object named `at` in messages, its mesh checked: its layered EMs (one per
    /// viewpoint weight, `viewpoints` of them; the contents of those `checked` knows are not
    /// scanned) and its terms.
    fn validate(
        &self,
        at: &str,
        viewpoints: usize,
        checked: &dyn Fn(usize) -> bool,
    ) -> Result<(), RenderError> {
        if self.resident.is_some()
            && (!self.positions.is_empty() || !self.triangles.is_empty() || self.hull_triangles > 0)
        {
            return bad(format!(
                "{at} is resident on the device and has host positions or triangles too; give one or the other"
            ));
        }
        let n = self.layer_count();
        if n == 0 {
            return bad(format!(
                "{at}.layers has no layers; give every viewpoint sample at least one layer (cube map)"
            ));
        }
        if self.layers.len() != viewpoints {
            return bad(format!(
                "{at}.layers has {} viewpoints but viewpoint_weights has {viewpoints}; give one layered EM per viewpoint sample",
                self.layers.len(),
            ));
        }
        if self.terms.is_empty() || self.terms.len() > MAX_TERMS {
            return bad(format!(
                "{at}.terms has {} entries; give 1 to {MAX_TERMS} (refraction and/or reflection, or path classes)",
                self.terms.len()
            ));
        }
        for (i, term) in self.terms.iter().enumerate() {
            if self.terms[..i].iter().any(|t| t.term == term.term) {
                return bad(format!(
                    "{at}.terms names {} twice; give each term once",
                    term.term.name()
                ));
            }
        }
        self.validate_layers(at, checked)?;
        for term in &self.terms {
            let t = format!("{at}.terms[{}]", term.term.name());
            if term.fg.len() != self.positions.len() || term.fg.iter().any(|c| !c.is_finite()) {
                return bad(format!(
                    "{t}.fg needs one finite rgb per vertex ({} given for {})",
                    term.fg.len(),
                    self.positions.len()
                ));
            }
            if term.directions.len() != n {
                return bad(format!(
                    "{t}.directions has {} layers, the EMs have {n}",
                    term.directions.len()
                ));
            }
            for (i, d) in term.directions.iter().enumerate() {
                if d.len() != self.positions.len() || d.iter().any(|v| !v.is_finite()) {
                    return bad(format!(
                        "{t}.directions[{i}] needs one finite direction per vertex"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Every viewpoint's layered EM: n layers each, every cube map the size of the first, and
    /// valid texels (not scanned again for the maps `checked` knows).
    fn validate_layers(
        &self,
        at: &str,
        checked: &dyn Fn(usize) -> bool,
    ) -> Result<(), RenderError> {
        let n = self.layer_count();
        let size = self
            .layers
            .first()
            .and_then(|v| v.first())
            .map_or(1, |c| c.size);
        for (v, cubes) in self.layers.iter().enumerate() {
            if cubes.len() != n {
                return bad(format!(
                    "{at}.layers[{v}] has {} layers, viewpoint 0 has {n}; every viewpoint needs the same n",
                    cubes.len()
                ));
            }
            for (i, cube) in cubes.iter().enumerate() {
                let result = if checked(Arc::as_ptr(cube) as usize) {
                    if cube.size == size {
                        Ok(())
                    } else {
                        Err(crate::cubemap::CubeMapError::WrongSize {
                            found: cube.size,
                            expected: size,
                        })
                    }
                } else {
                    cube.validate(Some(size))
                };
                if let Err(error) = result {
                    return bad(format!("{at}.layers[{v}][{i}]: {error}"));
                }
            }
        }
        Ok(())
    }
}

/// A refusal of bad frame input, `message` naming the field and the fix.
fn bad(message: String) -> Result<(), RenderError> {
    Err(RenderError::BadInput(message))
}

/// A mesh's positions are finite and its triangles index them.
fn check_mesh(at: &str, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(), RenderError> {
    if positions.iter().any(|p| !p.is_finite()) {
        return bad(format!("{at}.positions has NaN or infinite values"));
    }
    if let Some(t) = triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= positions.len()))
    {
        return bad(format!(
            "{at}.triangles[{t}] indexes past the {} positions",
            positions.len()
        ));
    }
    Ok(())
}
