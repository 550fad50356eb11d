//! Cube-map faces as Vulkan defines them (chapter "Image Operations": "Cube Map Face Selection
//! and Transformations", "Cube Map Edge Handling"): the six faces in layer order, the face a
//! direction selects and its face coordinates, and where a texel beyond a face's edge is read from.
//!
//! Where the specification leaves a choice to the implementation, this module takes the choice
//! the specification recommends (and that Mesa's llvmpipe/lavapipe makes), and says so:
//! face-selection ties resolve z over y and x, then y over x.

use glam::DVec3;

/// One face of a cube map, numbered as Vulkan numbers cube-map layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CubeFace {
    /// Layer 0, major axis +x.
    PositiveX = 0,
    /// Layer 1, major axis −x.
    NegativeX = 1,
    /// Layer 2, major axis +y.
    PositiveY = 2,
    /// Layer 3, major axis −y.
    NegativeY = 3,
    /// Layer 4, major axis +z.
    PositiveZ = 4,
    /// Layer 5, major axis −z.
    NegativeZ = 5,
}

impl CubeFace {
    /// All faces in layer order.
    pub const ALL: [CubeFace; 6] = [
        CubeFace::PositiveX,
        CubeFace::NegativeX,
        CubeFace::PositiveY,
        CubeFace::NegativeY,
        CubeFace::PositiveZ,
        CubeFace::NegativeZ,
    ];

    /// The face's layer number (0..6), the index into [`super::CubeMap::levels`]`[level]`.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The spec's face table as three unit vectors `(s_axis, t_axis, normal)` such that for a
    /// direction r on this face `sc = s_axis·r`, `tc = t_axis·r` and `|rc| = normal·r`.
    ///
    /// Writing the table as a linear map makes the derivative table fall out of it: the spec's
    /// `∂rc/∂x` for a negative face is `−∂r/∂x`, i.e. the derivative of `|rc| = normal·r`.
    pub fn axes(self) -> (DVec3, DVec3, DVec3) {
        match self {
            // sc = −rz, tc = −ry, rc = rx
            CubeFace::PositiveX => (DVec3::NEG_Z, DVec3::NEG_Y, DVec3::X),
            // sc = +rz, tc = −ry, rc = rx
            CubeFace::NegativeX => (DVec3::Z, DVec3::NEG_Y, DVec3::NEG_X),
            // sc = +rx, tc = +rz, rc = ry
            CubeFace::PositiveY => (DVec3::X, DVec3::Z, DVec3::Y),
            // sc = +rx, tc = −rz, rc = ry
            CubeFace::NegativeY => (DVec3::X, DVec3::NEG_Z, DVec3::NEG_Y),
            // sc = +rx, tc = −ry, rc = rz
            CubeFace::PositiveZ => (DVec3::X, DVec3::NEG_Y, DVec3::Z),
            // sc = −rx, tc = −ry, rc = rz
            CubeFace::NegativeZ => (DVec3::NEG_X, DVec3::NEG_Y, DVec3::NEG_Z),
        }
    }

    /// The direction through the point `(sc, tc)` of this face's plane at unit distance, i.e.
    /// the inverse of the face table: `face_coordinates_on(self, direction(sc, tc))` gives back
    /// `sc, tc` for `sc, tc ∈ [−1, 1]`.
    pub fn direction(self, sc: f64, tc: f64) -> DVec3 {
        let (s_axis, t_axis, normal) = self.axes();
        normal + sc * s_axis + tc * t_axis
    }
}

/// A direction expressed on one cube face: the spec's `sc, tc, |rc|` and the face coordinates
/// `s = ½(sc/|rc| + 1)`, `t = ½(tc/|rc| + 1)` in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceCoordinates {
    /// The face.
    pub face: CubeFace,
    /// The spec's `sc` (not divided by the major axis).
    pub sc: f64,
    /// The spec's `tc` (not divided by the major axis).
    pub tc: f64,
    /// `|rc|`, the magnitude of the major-axis component (> 0 for a non-zero direction).
    pub major: f64,
    /// Face coordinate s in [0, 1] (left to right along the face's rows).
    pub s: f64,
    /// Face coordinate t in [0, 1] (row 0 at t = 0).
    pub t: f64,
}

/// The face Vulkan selects for `direction`: the largest-magnitude component, ties resolved as
/// the spec recommends (z over y and x, then y over x), the sign taken from the sign bit (so −0
/// selects the negative face, as llvmpipe does; it only matters for the zero vector).
pub fn major_face(direction: DVec3) -> CubeFace {
    let a = direction.abs();
    if a.z >= a.x && a.z >= a.y {
        if direction.z.is_sign_negative() {
            CubeFace::NegativeZ
        } else {
            CubeFace::PositiveZ
        }
    } else if a.y >= a.x {
        if direction.y.is_sign_negative() {
            CubeFace::NegativeY
        } else {
            CubeFace::PositiveY
        }
    } else if direction.x.is_sign_negative() {
        CubeFace::NegativeX
    } else {
        CubeFace::PositiveX
    }
}

/// `direction` on the face Vulkan selects for it ([`major_face`]).
pub fn select_face(direction: DVec3) -> FaceCoordinates {
    face_coordinates_on(major_face(direction), direction)
}

/// `direction` expressed on a given `face` (its plane extended beyond the face's square, so s
/// and t leave [0, 1] for directions the face does not own). Used for the selected face, and for
/// the competing face where selection is a tie.
pub fn face_coordinates_on(face: CubeFace, direction: DVec3) -> FaceCoordinates {
    let (s_axis, t_axis, normal) = face.axes();
    let sc = s_axis.dot(direction);
    let tc = t_axis.dot(direction);
    let major = normal.dot(direction);
    FaceCoordinates {
        face,
        sc,
        tc,
        major,
        s: 0.5 * (sc / major + 1.0),
        t: 0.5 * (tc / major + 1.0),
    }
}

/// Where a texel `(i, j)` of a `size × size` level of `face` is read from, following the spec's
/// cube-map edge handling: inside the face, itself; beyond exactly one edge, the adjacent texel
/// of the neighbouring face; beyond both (a corner), `None`.
///
/// Rather than transcribing the spec's 24-entry table, the neighbour is found geometrically,
/// which is what the table encodes: the texel centre's face coordinate beyond the edge is folded
/// over the edge onto the neighbouring face (the same distance past the edge becomes the same
/// distance into the neighbour), and the folded point is looked up by face selection. All the
/// numbers involved are dyadic, so the lookup is exact. A unit test checks the result against
/// llvmpipe's table.
pub fn texel_source(face: CubeFace, size: u32, i: i64, j: i64) -> Option<(CubeFace, u32, u32)> {
    let n = i64::from(size);
    let i_out = !(0..n).contains(&i);
    let j_out = !(0..n).contains(&j);
    match (i_out, j_out) {
        // The indices are in 0..size here, so they fit in u32.
        (false, false) => Some((face, i as u32, j as u32)),
        (true, true) => None,
        _ => {
            let nf = size as f64;
            let sc = 2.0 * (i as f64 + 0.5) / nf - 1.0;
            let tc = 2.0 * (j as f64 + 0.5) / nf - 1.0;
            let beyond = (sc.abs().max(tc.abs()) - 1.0).max(0.0);
            let (_, _, normal) = face.axes();
            let folded = face.direction(sc.clamp(-1.0, 1.0), tc.clamp(-1.0, 1.0)) - beyond * normal;
            let there = select_face(folded);
            let to_index = |coordinate: f64| -> u32 {
                ((coordinate * nf).floor() as i64).clamp(0, n - 1) as u32
            };
            Some((there.face, to_index(there.s), to_index(there.t)))
        }
    }
}

/// The faces whose major-axis magnitude is within `relative_tolerance` of the largest one: more
/// than one means face selection for `direction` is (nearly) a tie, and a GPU computing in f32
/// may pick another face than the exact selection.
pub fn competing_faces(direction: DVec3, relative_tolerance: f64) -> Vec<CubeFace> {
    let a = direction.abs();
    let largest = a.max_element();
    let threshold = largest * (1.0 - relative_tolerance);
    let mut faces = Vec::with_capacity(3);
    let per_axis = [
        (a.x, direction.x, CubeFace::PositiveX, CubeFace::NegativeX),
        (a.y, direction.y, CubeFace::PositiveY, CubeFace::NegativeY),
        (a.z, direction.z, CubeFace::PositiveZ, CubeFace::NegativeZ),
    ];
    for (magnitude, component, positive, negative) in per_axis {
        if magnitude >= threshold && magnitude > 0.0 {
            faces.push(if component.is_sign_negative() {
                negative
            } else {
                positive
            });
        }
    }
    faces
}
