//! The compositor: the frame's pass graph ([`plan`]), its recording on the GPU ([`frame`]) and the
//! CPU f64 model of the same arithmetic ([`model`]) that tests compare against.

pub mod cube_sampling;
pub mod frame;
mod frame_input;
pub mod model;
pub mod plan;
pub mod synthetic;

pub use frame::{FrameTimings, RenderedImage, Renderer, UploadedFrame};
pub use frame_input::*;
pub use plan::{FrameShape, TargetFormat, Variant};

/// Errors from uploading or rendering a frame.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The frame's data is inconsistent; the message names the field and the fix.
    #[error("frame input: {0}")]
    BadInput(String),
    /// The GPU failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}

impl FrameInput {
    /// Checks sizes, indices and values before anything reaches the GPU.
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |s: String| Err(RenderError::BadInput(s));
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
                    check_cube(&format!("{at}.layers[{v}][{i}]"), cube, size)?;
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
) -> Result<(), RenderError> {
    if positions.iter().any(|p| !p.is_finite()) {
        return Err(RenderError::BadInput(format!(
            "{at}.positions has NaN or infinite values"
        )));
    }
    if let Some(t) = triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= positions.len()))
    {
        return Err(RenderError::BadInput(format!(
            "{at}.triangles[{t}] indexes past the {} positions",
            positions.len()
        )));
    }
    Ok(())
}

fn check_cube(at: &str, cube: &CubeMap, size: u32) -> Result<(), RenderError> {
    let bad = |s: String| Err(RenderError::BadInput(s));
    if cube.size != size || !cube.size.is_power_of_two() {
        return bad(format!(
            "{at}.size is {}; every layer needs the same power-of-two size ({size})",
            cube.size
        ));
    }
    if cube.levels.len() != CubeMap::full_chain_levels(cube.size) as usize {
        return bad(format!(
            "{at} has {} mip levels; a {}² cube needs the full chain of {}",
            cube.levels.len(),
            cube.size,
            CubeMap::full_chain_levels(cube.size)
        ));
    }
    for (l, faces) in cube.levels.iter().enumerate() {
        let texels = (cube.level_size(l) as usize).pow(2);
        for (f, face) in faces.iter().enumerate() {
            if face.len() != texels {
                return bad(format!(
                    "{at}.levels[{l}][{f}] has {} texels, expected {texels}",
                    face.len()
                ));
            }
            if face.iter().flatten().any(|v| !v.is_finite()) {
                return bad(format!("{at}.levels[{l}][{f}] has NaN or infinite texels"));
            }
        }
    }
    Ok(())
}
