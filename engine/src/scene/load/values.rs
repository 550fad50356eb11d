//! The loader's checks of plain values: finite numbers, positive sizes, points within the
//! scene's reach, colours, counts and the triangle budget of a built-in shape.

use glam::Vec3;

use super::{Loader, MAX_RADIANCE, MAX_SCENE_METRES, MAX_SHAPE_TRIANGLES, Result};
use crate::scene::mesh::TriangleMesh;

impl Loader<'_> {
    pub(super) fn finite(&self, field: &str, value: f32) -> Result<f32> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is not a finite number"),
                "give a finite number",
            ))
        }
    }

    pub(super) fn positive(&self, field: &str, value: f32, unit: &str) -> Result<f32> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is not a positive number"),
                format!("give a value > 0 ({unit})"),
            ))
        }
    }

    pub(super) fn finite_vec3(&self, field: &str, value: [f32; 3]) -> Result<Vec3> {
        let v = Vec3::from_array(value);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(
                field,
                format!("{value:?} has a non-finite component"),
                "give three finite numbers",
            ))
        }
    }

    /// A finite position within [`MAX_SCENE_METRES`] of the origin.
    pub(super) fn point(&self, field: &str, value: [f32; 3]) -> Result<Vec3> {
        let v = self.finite_vec3(field, value)?;
        self.within_scene(field, v)?;
        Ok(v)
    }

    /// `position` lies within [`MAX_SCENE_METRES`] of the origin along every axis.
    pub(super) fn within_scene(&self, field: &str, position: Vec3) -> Result<()> {
        if position.abs().max_element() <= MAX_SCENE_METRES {
            Ok(())
        } else {
            Err(self.error(
                field,
                format!(
                    "{position} lies {:.3e} m from the origin along an axis, farther than {MAX_SCENE_METRES:e} m",
                    position.abs().max_element()
                ),
                format!("keep the scene within {MAX_SCENE_METRES:e} m of the origin (units are metres)"),
            ))
        }
    }

    /// Every finite vertex of `mesh` within [`MAX_SCENE_METRES`] of the origin; `what` says
    /// whose vertices they are. Non-finite vertices are left to [`TriangleMesh::check`].
    pub(super) fn mesh_within_scene(
        &self,
        field: &str,
        mesh: &TriangleMesh,
        what: &str,
    ) -> Result<()> {
        let far = |p: &Vec3| p.is_finite() && p.abs().max_element() > MAX_SCENE_METRES;
        match mesh.positions.iter().position(far) {
            None => Ok(()),
            Some(vertex) => Err(self.error(
                field,
                format!(
                    "{what} vertex {vertex} (0-based) lies {:.3e} m from the origin along an axis, farther than {MAX_SCENE_METRES:e} m",
                    mesh.positions[vertex].abs().max_element()
                ),
                format!("keep the scene within {MAX_SCENE_METRES:e} m of the origin (units are metres): use smaller sizes, scale or translate"),
            )),
        }
    }

    /// A linear rgb colour ≥ 0, and ≤ `max` when given (an albedo or reflectance), else ≤
    /// [`MAX_RADIANCE`] (a radiance or intensity).
    pub(super) fn colour(&self, field: &str, value: [f32; 3], max: Option<f32>) -> Result<Vec3> {
        let v = Vec3::from_array(value);
        let limit = max.unwrap_or(MAX_RADIANCE);
        let in_range = v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= limit;
        if in_range {
            return Ok(v);
        }
        let fix = match max {
            Some(max) => format!("give three numbers in [0, {max}] (linear rgb)"),
            None => format!("give three finite numbers in [0, {MAX_RADIANCE:e}] (linear rgb)"),
        };
        Err(self.error(field, format!("{value:?} is out of range"), fix))
    }

    /// Checks a built-in shape's triangle count against [`MAX_SHAPE_TRIANGLES`] before it is
    /// built; `field` names the count that sets it.
    pub(super) fn triangle_budget(&self, field: &str, triangles: u64) -> Result<()> {
        if triangles <= MAX_SHAPE_TRIANGLES {
            Ok(())
        } else {
            Err(self.error(
                field,
                format!("makes {triangles} triangles, more than the {MAX_SHAPE_TRIANGLES} one shape may have"),
                "give fewer subdivisions or segments",
            ))
        }
    }

    pub(super) fn count(&self, field: &str, value: u32, min: u32, max: u32) -> Result<u32> {
        if (min..=max).contains(&value) {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is out of range"),
                format!("give a whole number in [{min}, {max}]"),
            ))
        }
    }
}
