//! Layer shells: the simple surfaces on which the layers of a layered environment map live, and
//! the intersection of a lens object's outgoing rays with them.
//!
//! The hybrid-rendering paper places each layer on a *geometric impostor* (§4.2, "Layer Quads";
//! §5, "Multipass Rendering with Layered EM Indexing"): a sphere for most layers, a cylinder for
//! a ring of columns, a quadrilateral for a sparsely occupied layer. At run time the texture index
//! of a vertex for a layer is the point where its outgoing ray meets that layer's shell, minus the
//! EM origin ([`LayerShell::texture_direction`]), used unnormalized as a cube-map direction.
//!
//! Conventions: world space, metres. Ray directions need not be unit length; a hit's `t` is the
//! ray parameter (`point = origin + t·direction`), so it is a distance in metres only for a unit
//! direction.
//!
//! **Closed shells** (sphere, cylinder, box, ellipsoid) are solid convex regions. A ray whose
//! origin lies inside or on the shell returns its *exit* point, the single point where it leaves
//! the region going outward (`t ≥ 0`; `t = 0` when the origin is on the surface and the ray heads
//! out). A ray whose origin lies strictly outside returns the *first* point where it meets the
//! shell in front of it (`t > 0`, the entry point), or `None` if it passes by. A tangent ray
//! touches in one point and returns it when the rounding of the touch test says it touches;
//! nothing returns NaN. A ray that never leaves the region (along the axis of an infinite
//! cylinder) returns `None`: its hit is at infinity, and [`LayerShell::texture_direction_for_ray`]
//! turns that into the ray direction.
//!
//! **The quad impostor** is an unbounded plane for intersection purposes; its extent only scales
//! how far the enforcement of §4.2 pushes rays that would miss it (see [`LayerShell::Quad`]).

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::identity::{Canonical, Encoder};
use crate::trace::fresnel::{Real, Vector3};

/// "Very far from the impostor center" (§4.2): a forced quad hit lies at this multiple of the
/// quad's half-diagonal `|half_extents|` from its centre.
///
/// Seen from an EM origin at distance D from the quad centre, the forced point's direction
/// differs from the ray's tangential direction by about `D / (1000·|half_extents|)` radians, which
/// is below a texel of any cube map up to 256² when D is a few quad extents.
pub const QUAD_FORCED_DISTANCE_FACTOR: f64 = 1000.0;

/// How far from unit length a shell's axis or normal may be (and how far from orthogonal a quad's
/// axes may be, as a dot product) before [`LayerShell::validate`] rejects it.
pub const AXIS_TOLERANCE: f64 = 1e-6;

/// The geometry of one layer of a layered environment map.
///
/// Serialized (in a bake's `manifest.json`) as a JSON object tagged by `"kind"`
/// (`"sphere"`, `"cylinder"`, `"box"`, `"ellipsoid"`, `"quad"`), vectors as `[x, y, z]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum LayerShell {
    /// A sphere: the classic EM shell.
    Sphere {
        /// Centre in metres.
        centre: DVec3,
        /// Radius in metres, > 0.
        radius: f64,
    },
    /// A circular cylinder around a line through `centre` along `axis`, with flat caps at
    /// `±half_height` along the axis from the centre, or unbounded along the axis when
    /// `half_height` is `None` (JSON: the field left out). The paper uses one for a ring of
    /// columns around the lens object.
    Cylinder {
        /// A point on the axis (the middle of a capped cylinder), metres.
        centre: DVec3,
        /// Unit axis direction.
        axis: DVec3,
        /// Radius in metres, > 0.
        radius: f64,
        /// Half the height in metres (> 0), or `None` for an infinite cylinder.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        half_height: Option<f64>,
    },
    /// An axis-aligned box (a room's walls, floor and ceiling).
    Box {
        /// Centre in metres.
        centre: DVec3,
        /// Half the edge lengths along x, y, z in metres, each > 0.
        half_extents: DVec3,
    },
    /// An axis-aligned ellipsoid.
    Ellipsoid {
        /// Centre in metres.
        centre: DVec3,
        /// Semi-axis lengths along x, y, z in metres, each > 0.
        radii: DVec3,
    },
    /// The quadrilateral impostor of §4.2, for a sparsely occupied layer.
    ///
    /// A ray meets the quad's (unbounded) plane at `t ≥ 0` when it can; the rectangle
    /// `centre + a·u_axis + b·v_axis, |a| ≤ half_extents.x, |b| ≤ half_extents.y` only says where
    /// the layer's content is. A ray that would miss the plane (parallel to it, or pointing away)
    /// is *forced* onto it as the paper describes: the normal component of its direction is
    /// removed and the remaining tangential direction û is scaled to the far distance
    /// `R = QUAD_FORCED_DISTANCE_FACTOR·|half_extents|`, giving the point `centre + R·û`. A ray
    /// that meets the plane farther than R from the centre is pulled back along the plane to
    /// distance R in the same way (`centre + R·(hit − centre)/|hit − centre|`), so the hit point
    /// is a continuous function of the ray direction across the edge between meeting and missing
    /// the plane. Both are flagged [`ShellHit::forced`]. A ray pointing exactly along the normal
    /// away from the plane has no tangential direction; it is forced to `centre + R·u_axis`.
    ///
    /// Texture parameterization: like every shell, a cube map indexed by `hit − EM origin`
    /// (§4.2: "texture maps for spherical shells or quads are computed using the same method").
    Quad {
        /// Centre of the rectangle in metres.
        centre: DVec3,
        /// Unit normal of the plane (either side; its sign does not change any result).
        normal: DVec3,
        /// Unit in-plane axis of the rectangle's first extent, orthogonal to `normal`.
        u_axis: DVec3,
        /// Unit in-plane axis of the rectangle's second extent, orthogonal to `normal` and `u_axis`.
        v_axis: DVec3,
        /// Half the rectangle's extents along `u_axis` and `v_axis` in metres, each > 0.
        half_extents: DVec2,
    },
}

impl Canonical for LayerShell {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            LayerShell::Sphere { centre, radius } => encoder.tag(0).value(centre).value(radius),
            LayerShell::Cylinder {
                centre,
                axis,
                radius,
                half_height,
            } => encoder
                .tag(1)
                .value(centre)
                .value(axis)
                .value(radius)
                .value(half_height),
            LayerShell::Box {
                centre,
                half_extents,
            } => encoder.tag(2).value(centre).value(half_extents),
            LayerShell::Ellipsoid { centre, radii } => encoder.tag(3).value(centre).value(radii),
            LayerShell::Quad {
                centre,
                normal,
                u_axis,
                v_axis,
                half_extents,
            } => encoder
                .tag(4)
                .value(centre)
                .value(normal)
                .value(u_axis)
                .value(v_axis)
                .value(half_extents),
        };
    }
}

/// Where a ray meets a shell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellHit {
    /// The hit point in metres, always finite.
    pub point: DVec3,
    /// The ray parameter of the hit, `point = origin + t·direction`, finite and ≥ 0. For a forced
    /// quad hit the point is not on the ray; `t` is then `|point − origin| / |direction|`.
    pub t: f64,
    /// `true` when the quad enforcement of §4.2 moved the point off the ray (quads only).
    pub forced: bool,
}

/// A shell whose parameters cannot describe a surface.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field} {problem}")]
pub struct ShellError {
    /// The offending field, e.g. `radius`.
    pub field: &'static str,
    /// What is wrong with it and what would be right.
    pub problem: String,
}

impl LayerShell {
    /// A quad impostor with centre, unit `normal` and half extents, its in-plane axes chosen
    /// deterministically from the normal (`normal` is normalized here; it must be non-zero).
    pub fn quad_facing(centre: DVec3, normal: DVec3, half_extents: DVec2) -> LayerShell {
        let normal = normal.normalize();
        let (u_axis, v_axis) = normal.any_orthonormal_pair();
        LayerShell::Quad {
            centre,
            normal,
            u_axis,
            v_axis,
            half_extents,
        }
    }

    /// The shell's kind as written in JSON (`"sphere"`, …).
    pub fn kind(&self) -> &'static str {
        match self {
            LayerShell::Sphere { .. } => "sphere",
            LayerShell::Cylinder { .. } => "cylinder",
            LayerShell::Box { .. } => "box",
            LayerShell::Ellipsoid { .. } => "ellipsoid",
            LayerShell::Quad { .. } => "quad",
        }
    }

    /// The shell's centre in metres.
    pub fn centre(&self) -> DVec3 {
        match *self {
            LayerShell::Sphere { centre, .. }
            | LayerShell::Cylinder { centre, .. }
            | LayerShell::Box { centre, .. }
            | LayerShell::Ellipsoid { centre, .. }
            | LayerShell::Quad { centre, .. } => centre,
        }
    }

    /// Checks that every number is finite, lengths are positive and axes are unit (and, for a
    /// quad, mutually orthogonal) within [`AXIS_TOLERANCE`].
    pub fn validate(&self) -> Result<(), ShellError> {
        check_finite_vector("centre", self.centre())?;
        match *self {
            LayerShell::Sphere { radius, .. } => check_positive("radius", radius),
            LayerShell::Cylinder {
                axis,
                radius,
                half_height,
                ..
            } => {
                check_unit("axis", axis)?;
                check_positive("radius", radius)?;
                half_height.map_or(Ok(()), |h| check_positive("half_height", h))
            }
            LayerShell::Box { half_extents, .. } => {
                check_positive_vector("half_extents", half_extents)
            }
            LayerShell::Ellipsoid { radii, .. } => check_positive_vector("radii", radii),
            LayerShell::Quad {
                normal,
                u_axis,
                v_axis,
                half_extents,
                ..
            } => {
                check_unit("normal", normal)?;
                check_unit("u_axis", u_axis)?;
                check_unit("v_axis", v_axis)?;
                check_orthogonal("u_axis", u_axis, "normal", normal)?;
                check_orthogonal("v_axis", v_axis, "normal", normal)?;
                check_orthogonal("v_axis", v_axis, "u_axis", u_axis)?;
                check_positive("half_extents.x", half_extents.x)?;
                check_positive("half_extents.y", half_extents.y)
            }
        }
    }

    /// Whether `point` (metres) lies strictly inside the shell's solid: for a sphere its distance
    /// to the centre is below the radius; for a cylinder its distance to the axis is below the
    /// radius and, when capped, its distance along the axis from the centre below `half_height`;
    /// for a box each coordinate's distance from the centre is below its half extent; for an
    /// ellipsoid `Σ ((p − centre)ᵢ / radiiᵢ)² < 1`. A point on the surface is not inside.
    ///
    /// A quad is open (a plane with no inside): always `false`. A point that is not finite is
    /// never inside.
    pub fn contains(&self, point: DVec3) -> bool {
        if !point.is_finite() {
            return false;
        }
        match *self {
            LayerShell::Sphere { centre, radius } => {
                point.distance_squared(centre) < radius * radius
            }
            LayerShell::Cylinder {
                centre,
                axis,
                radius,
                half_height,
            } => {
                let offset = point - centre;
                let along = offset.dot(axis);
                let radial = offset - axis * along;
                radial.length_squared() < radius * radius
                    && half_height.is_none_or(|h| along.abs() < h)
            }
            LayerShell::Box {
                centre,
                half_extents,
            } => (point - centre).abs().cmplt(half_extents).all(),
            LayerShell::Ellipsoid { centre, radii } => {
                ((point - centre) / radii).length_squared() < 1.0
            }
            LayerShell::Quad { .. } => false,
        }
    }

    /// Where the ray `origin + t·direction` meets the shell: for a closed shell the exit point
    /// when the origin is inside or on it, else the first hit in front; for a quad the plane hit
    /// or the forced point (see the module docs and [`LayerShell::Quad`]).
    ///
    /// `None` when the ray misses a closed shell, never leaves an infinite cylinder, or when
    /// `origin` or `direction` is not finite or `direction` is zero.
    pub fn intersect(&self, origin: DVec3, direction: DVec3) -> Option<ShellHit> {
        self.intersect_in::<f64>(origin, direction)
    }

    /// [`LayerShell::intersect`] computed in precision `R` (the shell and the ray rounded to it;
    /// the hit stored in f64, which holds it exactly): f64 is `intersect`; f32 measures what
    /// single precision would cost.
    pub fn intersect_in<R: Real>(&self, origin: DVec3, direction: DVec3) -> Option<ShellHit> {
        let vector = <R::Vec3 as Vector3>::of;
        let (origin, direction) = (vector(origin), vector(direction));
        if !origin.is_finite() || !direction.is_finite() || direction == R::Vec3::ZERO {
            return None;
        }
        if let LayerShell::Quad {
            centre,
            normal,
            u_axis,
            half_extents,
            ..
        } = *self
        {
            let far = R::of(QUAD_FORCED_DISTANCE_FACTOR) * R::of(half_extents.length());
            return Some(intersect_quad(
                vector(centre),
                vector(normal),
                vector(u_axis),
                far,
                origin,
                direction,
            ));
        }
        let Span { near, far } = self.closed_interval(origin, direction)?;
        if far < R::ZERO {
            return None;
        }
        // Inside or on the surface (near ≤ 0 ≤ far): the exit. Outside: the entry.
        let t = if near > R::ZERO { near } else { far };
        let point = origin + direction * t;
        (t.is_finite() && point.is_finite()).then_some(ShellHit {
            point: point.to_dvec3(),
            t: t.to_f64(),
            forced: false,
        })
    }

    /// The cube-map direction of a hit: `hit − em_origin`, not normalized (the convention of the
    /// bake format, `layers/bake.rs`, and of the compositor's cube-map lookups), for every shell
    /// kind including the quad.
    pub fn texture_direction(&self, em_origin: DVec3, hit: DVec3) -> DVec3 {
        hit - em_origin
    }

    /// The cube-map direction for the ray `origin + t·direction`: [`Self::texture_direction`] of
    /// its hit, or `direction` itself when the ray meets no finite point of the shell (a shell at
    /// infinity in that direction, the limit of the hits of nearby rays).
    pub fn texture_direction_for_ray(
        &self,
        em_origin: DVec3,
        origin: DVec3,
        direction: DVec3,
    ) -> DVec3 {
        self.texture_direction_for_ray_in::<f64>(em_origin, origin, direction)
    }

    /// [`LayerShell::texture_direction_for_ray`] computed in precision `R` (see
    /// [`LayerShell::intersect_in`]); the direction is the difference of the hit and the EM
    /// origin in `R`.
    pub fn texture_direction_for_ray_in<R: Real>(
        &self,
        em_origin: DVec3,
        origin: DVec3,
        direction: DVec3,
    ) -> DVec3 {
        let vector = <R::Vec3 as Vector3>::of;
        match self.intersect_in::<R>(origin, direction) {
            Some(hit) => (vector(hit.point) - vector(em_origin)).to_dvec3(),
            None => vector(direction).to_dvec3(),
        }
    }

    /// The parameter interval `[near, far]` over which the line `origin + t·direction` lies in the
    /// closed solid (±∞ where it never leaves), or `None` when it misses. Not for quads.
    fn closed_interval<V: Vector3>(&self, origin: V, direction: V) -> Option<Span<V::Scalar>> {
        let (vector, scalar) = (V::of, <V::Scalar as Real>::of);
        match *self {
            LayerShell::Sphere { centre, radius } => {
                let radius = scalar(radius);
                sphere_interval(origin - vector(centre), direction, radius * radius)
            }
            LayerShell::Ellipsoid { centre, radii } => {
                let radii = vector(radii);
                sphere_interval(
                    (origin - vector(centre)) / radii,
                    direction / radii,
                    <V::Scalar as Real>::ONE,
                )
            }
            LayerShell::Box {
                centre,
                half_extents,
            } => {
                let offset = (origin - vector(centre)).components();
                let direction = direction.components();
                let half = vector(half_extents).components();
                let x = slab_interval(offset[0], direction[0], half[0])?;
                let y = slab_interval(offset[1], direction[1], half[1])?;
                let z = slab_interval(offset[2], direction[2], half[2])?;
                x.overlap(y)?.overlap(z)
            }
            LayerShell::Cylinder {
                centre,
                axis,
                radius,
                half_height,
            } => {
                let (axis, radius) = (vector(axis), scalar(radius));
                let offset = origin - vector(centre);
                let along = offset.dot(axis);
                let direction_along = direction.dot(axis);
                let radial = sphere_interval(
                    offset - axis * along,
                    direction - axis * direction_along,
                    radius * radius,
                )?;
                match half_height {
                    None => Some(radial),
                    Some(h) => radial.overlap(slab_interval(along, direction_along, scalar(h))?),
                }
            }
            LayerShell::Quad { .. } => None,
        }
    }
}

/// The interval of `t` where `|offset + t·direction|² ≤ radius_sq` (offset = origin − centre).
///
/// The discriminant is computed from the line's closest approach to the centre rather than as
/// `b² − a·c`, which cancels catastrophically for grazing rays; the two roots come from the
/// numerically stable pair `q / a`, `c / q`.
fn sphere_interval<V: Vector3>(
    offset: V,
    direction: V,
    radius_sq: V::Scalar,
) -> Option<Span<V::Scalar>> {
    let zero = <V::Scalar as Real>::ZERO;
    let a = direction.length_squared();
    if a == zero {
        // Parallel to the axis of a cylinder: inside for ever or never.
        return (offset.length_squared() <= radius_sq).then_some(Span::EVERYWHERE);
    }
    let b = offset.dot(direction);
    let closest = offset - direction * (b / a);
    let discriminant = a * (radius_sq - closest.length_squared());
    if discriminant.is_nan() || discriminant < zero {
        return None;
    }
    let c = offset.length_squared() - radius_sq;
    let q = -(b + b.signum() * discriminant.sqrt());
    if q == zero {
        // b = 0 and a tangent touch: the double root −b/a = 0.
        return Some(Span {
            near: zero,
            far: zero,
        });
    }
    let (t0, t1) = (q / a, c / q);
    Some(Span::between(t0, t1))
}

/// The interval of `t` where `|offset + t·direction| ≤ half` along one axis.
fn slab_interval<R: Real>(offset: R, direction: R, half: R) -> Option<Span<R>> {
    if direction == R::ZERO {
        return (offset.abs() <= half).then_some(Span::EVERYWHERE);
    }
    let t0 = (-half - offset) / direction;
    let t1 = (half - offset) / direction;
    Some(Span::between(t0, t1))
}

/// A closed interval `[near, far]` of the line parameter `t`.
#[derive(Clone, Copy, Debug)]
struct Span<R> {
    near: R,
    far: R,
}

impl<R: Real> Span<R> {
    /// The whole line.
    const EVERYWHERE: Span<R> = Span {
        near: R::NEG_INFINITY,
        far: R::INFINITY,
    };

    /// The interval between `a` and `b`, in either order.
    fn between(a: R, b: R) -> Span<R> {
        Span {
            near: a.min(b),
            far: a.max(b),
        }
    }

    /// The intersection with `other`, `None` when empty.
    fn overlap(self, other: Span<R>) -> Option<Span<R>> {
        let near = self.near.max(other.near);
        let far = self.far.min(other.far);
        (near <= far).then_some(Span { near, far })
    }
}

/// The quad's plane hit, or the §4.2 forced point at distance `far` from the centre.
fn intersect_quad<V: Vector3>(
    centre: V,
    normal: V,
    u_axis: V,
    far: V::Scalar,
    origin: V,
    direction: V,
) -> ShellHit {
    let zero = <V::Scalar as Real>::ZERO;
    let forced_at = |in_plane: V| {
        let point = centre + in_plane.try_normalize().unwrap_or(u_axis) * far;
        ShellHit {
            point: point.to_dvec3(),
            t: ((point - origin).length() / direction.length()).to_f64(),
            forced: true,
        }
    };
    let denominator = direction.dot(normal);
    if denominator != zero {
        let t = (centre - origin).dot(normal) / denominator;
        if t >= zero && t.is_finite() {
            let point = origin + direction * t;
            let offset = point - centre;
            if !offset.is_finite() {
                return forced_at(direction - normal * denominator);
            }
            if offset.length() <= far {
                return ShellHit {
                    point: point.to_dvec3(),
                    t: t.to_f64(),
                    forced: false,
                };
            }
            // Beyond the far distance: pulled back along the plane (continuity with the forced
            // rays beyond the horizon). The offset is in the plane up to rounding; project it.
            return forced_at(offset - normal * offset.dot(normal));
        }
    }
    // Parallel to the plane or pointing away from it: keep only the tangential component.
    forced_at(direction - normal * denominator)
}

fn check_finite_vector(field: &'static str, value: DVec3) -> Result<(), ShellError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ShellError {
            field,
            problem: format!("is {value} (must be finite)"),
        })
    }
}

fn check_positive(field: &'static str, value: f64) -> Result<(), ShellError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ShellError {
            field,
            problem: format!("is {value} (must be a finite length > 0 m)"),
        })
    }
}

fn check_positive_vector(field: &'static str, value: DVec3) -> Result<(), ShellError> {
    if value.is_finite() && value.min_element() > 0.0 {
        Ok(())
    } else {
        Err(ShellError {
            field,
            problem: format!("is {value} (each component must be a finite length > 0 m)"),
        })
    }
}

fn check_unit(field: &'static str, value: DVec3) -> Result<(), ShellError> {
    if value.is_finite() && (value.length() - 1.0).abs() <= AXIS_TOLERANCE {
        Ok(())
    } else {
        Err(ShellError {
            field,
            problem: format!(
                "is {value} of length {} (must be a unit vector)",
                value.length()
            ),
        })
    }
}

fn check_orthogonal(
    field: &'static str,
    value: DVec3,
    other_name: &str,
    other: DVec3,
) -> Result<(), ShellError> {
    let dot = value.dot(other);
    if dot.abs() <= AXIS_TOLERANCE {
        Ok(())
    } else {
        Err(ShellError {
            field,
            problem: format!("is not orthogonal to {other_name} (dot product {dot})"),
        })
    }
}

#[cfg(test)]
mod tests;

/// [`LayerShell::contains`] against each shell's defining inequality, with points chosen on
/// either side of every bound.
#[cfg(test)]
mod contains_tests {
    use glam::{DVec2, DVec3};

    use super::LayerShell;

    #[test]
    fn sphere_contains_points_closer_than_its_radius() {
        let shell = LayerShell::Sphere {
            centre: DVec3::new(1.0, -2.0, 0.5),
            radius: 3.0,
        };
        let centre = shell.centre();
        assert!(shell.contains(centre));
        assert!(shell.contains(centre + DVec3::new(2.9, 0.0, 0.0)));
        assert!(shell.contains(centre + DVec3::new(1.7, 1.7, 1.7))); // |·| ≈ 2.94
        assert!(!shell.contains(centre + DVec3::new(1.8, 1.8, 1.8))); // |·| ≈ 3.12
        assert!(
            !shell.contains(centre + DVec3::new(0.0, 0.0, -3.0)),
            "on the surface"
        );
        assert!(!shell.contains(centre + DVec3::new(0.0, 3.1, 0.0)));
    }

    #[test]
    fn capped_cylinder_bounds_radius_and_height() {
        // Axis along (1, 1, 0)/√2 through (0, 1, 0), radius 2, half height 1.5.
        let axis = DVec3::new(1.0, 1.0, 0.0).normalize();
        let radial = DVec3::new(1.0, -1.0, 0.0).normalize();
        let centre = DVec3::new(0.0, 1.0, 0.0);
        let shell = LayerShell::Cylinder {
            centre,
            axis,
            radius: 2.0,
            half_height: Some(1.5),
        };
        let at = |along: f64, out: f64, z: f64| centre + axis * along + radial * out + DVec3::Z * z;
        assert!(shell.contains(centre));
        assert!(shell.contains(at(1.4, 1.9, 0.0)));
        assert!(shell.contains(at(-1.4, 0.0, -1.9)));
        assert!(!shell.contains(at(1.6, 0.0, 0.0)), "past the cap");
        assert!(!shell.contains(at(-1.6, 0.0, 0.0)), "past the other cap");
        assert!(!shell.contains(at(0.0, 2.1, 0.0)), "outside the radius");
        assert!(!shell.contains(at(0.0, 1.5, 1.5)), "radial distance 2.12");
    }

    #[test]
    fn uncapped_cylinder_bounds_only_the_radius() {
        let shell = LayerShell::Cylinder {
            centre: DVec3::new(0.0, 0.0, 2.0),
            axis: DVec3::Y,
            radius: 1.0,
            half_height: None,
        };
        assert!(shell.contains(DVec3::new(0.5, 1e6, 2.5)));
        assert!(shell.contains(DVec3::new(-0.7, -3e3, 2.7)));
        assert!(
            !shell.contains(DVec3::new(0.8, 0.0, 2.8)),
            "radial distance 1.13"
        );
        assert!(!shell.contains(DVec3::new(0.0, 5.0, 3.0)), "on the surface");
    }

    #[test]
    fn box_bounds_each_axis() {
        let shell = LayerShell::Box {
            centre: DVec3::new(1.0, 2.0, 3.0),
            half_extents: DVec3::new(1.0, 2.0, 3.0),
        };
        assert!(shell.contains(DVec3::new(1.9, 3.9, 5.9)));
        assert!(shell.contains(DVec3::new(0.1, 0.1, 0.1)));
        assert!(!shell.contains(DVec3::new(2.1, 2.0, 3.0)));
        assert!(!shell.contains(DVec3::new(1.0, -0.1, 3.0)));
        assert!(!shell.contains(DVec3::new(1.0, 2.0, 6.1)));
        assert!(!shell.contains(DVec3::new(2.0, 2.0, 3.0)), "on a face");
    }

    #[test]
    fn ellipsoid_is_the_scaled_unit_ball() {
        let shell = LayerShell::Ellipsoid {
            centre: DVec3::new(0.0, 1.0, 0.0),
            radii: DVec3::new(4.0, 1.0, 2.0),
        };
        assert!(shell.contains(DVec3::new(3.9, 1.0, 0.0)));
        assert!(!shell.contains(DVec3::new(0.0, 2.1, 0.0)));
        // (2/4)² + (0.7/1)² + (1/2)² = 0.99 inside; (0.75)² + 0 + (1.4/2)² = 1.0525 outside.
        assert!(shell.contains(DVec3::new(2.0, 1.7, 1.0)));
        assert!(!shell.contains(DVec3::new(3.0, 1.0, 1.4)));
        // Inside the sphere of the largest radius but outside the ellipsoid.
        assert!(!shell.contains(DVec3::new(0.0, 1.0, 3.0)));
    }

    #[test]
    fn quad_is_open_and_contains_nothing() {
        let shell = LayerShell::quad_facing(DVec3::ZERO, DVec3::Z, DVec2::new(2.0, 2.0));
        assert!(!shell.contains(DVec3::ZERO), "its centre, on the plane");
        assert!(!shell.contains(DVec3::new(0.5, 0.5, -0.1)), "behind it");
        assert!(!shell.contains(DVec3::new(0.5, 0.5, 0.1)), "in front of it");
    }

    #[test]
    fn points_that_are_not_finite_are_outside() {
        let infinite = LayerShell::Cylinder {
            centre: DVec3::ZERO,
            axis: DVec3::Y,
            radius: 1.0,
            half_height: None,
        };
        let sphere = LayerShell::Sphere {
            centre: DVec3::ZERO,
            radius: 1.0,
        };
        for shell in [infinite, sphere] {
            assert!(!shell.contains(DVec3::new(0.0, f64::NAN, 0.0)));
            assert!(!shell.contains(DVec3::new(0.0, f64::INFINITY, 0.0)));
        }
    }
}
