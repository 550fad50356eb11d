//! The Newell teapot from its 32 bicubic Bézier patches, tessellated into a welded triangle mesh
//! with smooth, finite normals.
//!
//! Source of the data: Martin Newell's 1975 teapot (University of Utah), 306 control points and
//! 28 patches, plus the 4 bottom patches Frank Crow added (F. Crow, "The Origins of the Teapot",
//! IEEE CG&A 7(1), 1987). The table below is that classic set exactly as it is commonly
//! distributed (for example in the K-3D and Aqsis sources), z up, 1-based patch indices; the mesh
//! is rotated to this project's y-up frame: (x, y, z)_data → (x, z, −y).

use glam::{Vec2, Vec3};

use super::mesh::TriangleMesh;
use super::shapes::{SurfacePoint, Winding, parametric_grid};

/// Number of Bézier patches in the classic teapot.
pub const PATCH_COUNT: usize = 32;

/// The 306 control points, z up, in the data's units (the teapot is 6.43 wide and 3.15 tall).
const CONTROL_POINTS: [[f32; 3]; 306] = [
    [1.4, 0.0, 2.4],
    [1.4, -0.784, 2.4],
    [0.784, -1.4, 2.4],
    [0.0, -1.4, 2.4],
    [1.3375, 0.0, 2.53125],
    [1.3375, -0.749, 2.53125],
    [0.749, -1.3375, 2.53125],
    [0.0, -1.3375, 2.53125],
    [1.4375, 0.0, 2.53125],
    [1.4375, -0.805, 2.53125],
    [0.805, -1.4375, 2.53125],
    [0.0, -1.4375, 2.53125],
    [1.5, 0.0, 2.4],
    [1.5, -0.84, 2.4],
    [0.84, -1.5, 2.4],
    [0.0, -1.5, 2.4],
    [-0.784, -1.4, 2.4],
    [-1.4, -0.784, 2.4],
    [-1.4, 0.0, 2.4],
    [-0.749, -1.3375, 2.53125],
    [-1.3375, -0.749, 2.53125],
    [-1.3375, 0.0, 2.53125],
    [-0.805, -1.4375, 2.53125],
    [-1.4375, -0.805, 2.53125],
    [-1.4375, 0.0, 2.53125],
    [-0.84, -1.5, 2.4],
    [-1.5, -0.84, 2.4],
    [-1.5, 0.0, 2.4],
    [-1.4, 0.784, 2.4],
    [-0.784, 1.4, 2.4],
    [0.0, 1.4, 2.4],
    [-1.3375, 0.749, 2.53125],
    [-0.749, 1.3375, 2.53125],
    [0.0, 1.3375, 2.53125],
    [-1.4375, 0.805, 2.53125],
    [-0.805, 1.4375, 2.53125],
    [0.0, 1.4375, 2.53125],
    [-1.5, 0.84, 2.4],
    [-0.84, 1.5, 2.4],
    [0.0, 1.5, 2.4],
    [0.784, 1.4, 2.4],
    [1.4, 0.784, 2.4],
    [0.749, 1.3375, 2.53125],
    [1.3375, 0.749, 2.53125],
    [0.805, 1.4375, 2.53125],
    [1.4375, 0.805, 2.53125],
    [0.84, 1.5, 2.4],
    [1.5, 0.84, 2.4],
    [1.75, 0.0, 1.875],
    [1.75, -0.98, 1.875],
    [0.98, -1.75, 1.875],
    [0.0, -1.75, 1.875],
    [2.0, 0.0, 1.35],
    [2.0, -1.12, 1.35],
    [1.12, -2.0, 1.35],
    [0.0, -2.0, 1.35],
    [2.0, 0.0, 0.9],
    [2.0, -1.12, 0.9],
    [1.12, -2.0, 0.9],
    [0.0, -2.0, 0.9],
    [-0.98, -1.75, 1.875],
    [-1.75, -0.98, 1.875],
    [-1.75, 0.0, 1.875],
    [-1.12, -2.0, 1.35],
    [-2.0, -1.12, 1.35],
    [-2.0, 0.0, 1.35],
    [-1.12, -2.0, 0.9],
    [-2.0, -1.12, 0.9],
    [-2.0, 0.0, 0.9],
    [-1.75, 0.98, 1.875],
    [-0.98, 1.75, 1.875],
    [0.0, 1.75, 1.875],
    [-2.0, 1.12, 1.35],
    [-1.12, 2.0, 1.35],
    [0.0, 2.0, 1.35],
    [-2.0, 1.12, 0.9],
    [-1.12, 2.0, 0.9],
    [0.0, 2.0, 0.9],
    [0.98, 1.75, 1.875],
    [1.75, 0.98, 1.875],
    [1.12, 2.0, 1.35],
    [2.0, 1.12, 1.35],
    [1.12, 2.0, 0.9],
    [2.0, 1.12, 0.9],
    [2.0, 0.0, 0.45],
    [2.0, -1.12, 0.45],
    [1.12, -2.0, 0.45],
    [0.0, -2.0, 0.45],
    [1.5, 0.0, 0.225],
    [1.5, -0.84, 0.225],
    [0.84, -1.5, 0.225],
    [0.0, -1.5, 0.225],
    [1.5, 0.0, 0.15],
    [1.5, -0.84, 0.15],
    [0.84, -1.5, 0.15],
    [0.0, -1.5, 0.15],
    [-1.12, -2.0, 0.45],
    [-2.0, -1.12, 0.45],
    [-2.0, 0.0, 0.45],
    [-0.84, -1.5, 0.225],
    [-1.5, -0.84, 0.225],
    [-1.5, 0.0, 0.225],
    [-0.84, -1.5, 0.15],
    [-1.5, -0.84, 0.15],
    [-1.5, 0.0, 0.15],
    [-2.0, 1.12, 0.45],
    [-1.12, 2.0, 0.45],
    [0.0, 2.0, 0.45],
    [-1.5, 0.84, 0.225],
    [-0.84, 1.5, 0.225],
    [0.0, 1.5, 0.225],
    [-1.5, 0.84, 0.15],
    [-0.84, 1.5, 0.15],
    [0.0, 1.5, 0.15],
    [1.12, 2.0, 0.45],
    [2.0, 1.12, 0.45],
    [0.84, 1.5, 0.225],
    [1.5, 0.84, 0.225],
    [0.84, 1.5, 0.15],
    [1.5, 0.84, 0.15],
    [-1.6, 0.0, 2.025],
    [-1.6, -0.3, 2.025],
    [-1.5, -0.3, 2.25],
    [-1.5, 0.0, 2.25],
    [-2.3, 0.0, 2.025],
    [-2.3, -0.3, 2.025],
    [-2.5, -0.3, 2.25],
    [-2.5, 0.0, 2.25],
    [-2.7, 0.0, 2.025],
    [-2.7, -0.3, 2.025],
    [-3.0, -0.3, 2.25],
    [-3.0, 0.0, 2.25],
    [-2.7, 0.0, 1.8],
    [-2.7, -0.3, 1.8],
    [-3.0, -0.3, 1.8],
    [-3.0, 0.0, 1.8],
    [-1.5, 0.3, 2.25],
    [-1.6, 0.3, 2.025],
    [-2.5, 0.3, 2.25],
    [-2.3, 0.3, 2.025],
    [-3.0, 0.3, 2.25],
    [-2.7, 0.3, 2.025],
    [-3.0, 0.3, 1.8],
    [-2.7, 0.3, 1.8],
    [-2.7, 0.0, 1.575],
    [-2.7, -0.3, 1.575],
    [-3.0, -0.3, 1.35],
    [-3.0, 0.0, 1.35],
    [-2.5, 0.0, 1.125],
    [-2.5, -0.3, 1.125],
    [-2.65, -0.3, 0.9375],
    [-2.65, 0.0, 0.9375],
    [-2.0, -0.3, 0.9],
    [-1.9, -0.3, 0.6],
    [-1.9, 0.0, 0.6],
    [-3.0, 0.3, 1.35],
    [-2.7, 0.3, 1.575],
    [-2.65, 0.3, 0.9375],
    [-2.5, 0.3, 1.125],
    [-1.9, 0.3, 0.6],
    [-2.0, 0.3, 0.9],
    [1.7, 0.0, 1.425],
    [1.7, -0.66, 1.425],
    [1.7, -0.66, 0.6],
    [1.7, 0.0, 0.6],
    [2.6, 0.0, 1.425],
    [2.6, -0.66, 1.425],
    [3.1, -0.66, 0.825],
    [3.1, 0.0, 0.825],
    [2.3, 0.0, 2.1],
    [2.3, -0.25, 2.1],
    [2.4, -0.25, 2.025],
    [2.4, 0.0, 2.025],
    [2.7, 0.0, 2.4],
    [2.7, -0.25, 2.4],
    [3.3, -0.25, 2.4],
    [3.3, 0.0, 2.4],
    [1.7, 0.66, 0.6],
    [1.7, 0.66, 1.425],
    [3.1, 0.66, 0.825],
    [2.6, 0.66, 1.425],
    [2.4, 0.25, 2.025],
    [2.3, 0.25, 2.1],
    [3.3, 0.25, 2.4],
    [2.7, 0.25, 2.4],
    [2.8, 0.0, 2.475],
    [2.8, -0.25, 2.475],
    [3.525, -0.25, 2.49375],
    [3.525, 0.0, 2.49375],
    [2.9, 0.0, 2.475],
    [2.9, -0.15, 2.475],
    [3.45, -0.15, 2.5125],
    [3.45, 0.0, 2.5125],
    [2.8, 0.0, 2.4],
    [2.8, -0.15, 2.4],
    [3.2, -0.15, 2.4],
    [3.2, 0.0, 2.4],
    [3.525, 0.25, 2.49375],
    [2.8, 0.25, 2.475],
    [3.45, 0.15, 2.5125],
    [2.9, 0.15, 2.475],
    [3.2, 0.15, 2.4],
    [2.8, 0.15, 2.4],
    [0.0, 0.0, 3.15],
    [0.0, -0.002, 3.15],
    [0.002, 0.0, 3.15],
    [0.8, 0.0, 3.15],
    [0.8, -0.45, 3.15],
    [0.45, -0.8, 3.15],
    [0.0, -0.8, 3.15],
    [0.0, 0.0, 2.85],
    [0.2, 0.0, 2.7],
    [0.2, -0.112, 2.7],
    [0.112, -0.2, 2.7],
    [0.0, -0.2, 2.7],
    [-0.002, 0.0, 3.15],
    [-0.45, -0.8, 3.15],
    [-0.8, -0.45, 3.15],
    [-0.8, 0.0, 3.15],
    [-0.112, -0.2, 2.7],
    [-0.2, -0.112, 2.7],
    [-0.2, 0.0, 2.7],
    [0.0, 0.002, 3.15],
    [-0.8, 0.45, 3.15],
    [-0.45, 0.8, 3.15],
    [0.0, 0.8, 3.15],
    [-0.2, 0.112, 2.7],
    [-0.112, 0.2, 2.7],
    [0.0, 0.2, 2.7],
    [0.45, 0.8, 3.15],
    [0.8, 0.45, 3.15],
    [0.112, 0.2, 2.7],
    [0.2, 0.112, 2.7],
    [0.4, 0.0, 2.55],
    [0.4, -0.224, 2.55],
    [0.224, -0.4, 2.55],
    [0.0, -0.4, 2.55],
    [1.3, 0.0, 2.55],
    [1.3, -0.728, 2.55],
    [0.728, -1.3, 2.55],
    [0.0, -1.3, 2.55],
    [1.3, 0.0, 2.4],
    [1.3, -0.728, 2.4],
    [0.728, -1.3, 2.4],
    [0.0, -1.3, 2.4],
    [-0.224, -0.4, 2.55],
    [-0.4, -0.224, 2.55],
    [-0.4, 0.0, 2.55],
    [-0.728, -1.3, 2.55],
    [-1.3, -0.728, 2.55],
    [-1.3, 0.0, 2.55],
    [-0.728, -1.3, 2.4],
    [-1.3, -0.728, 2.4],
    [-1.3, 0.0, 2.4],
    [-0.4, 0.224, 2.55],
    [-0.224, 0.4, 2.55],
    [0.0, 0.4, 2.55],
    [-1.3, 0.728, 2.55],
    [-0.728, 1.3, 2.55],
    [0.0, 1.3, 2.55],
    [-1.3, 0.728, 2.4],
    [-0.728, 1.3, 2.4],
    [0.0, 1.3, 2.4],
    [0.224, 0.4, 2.55],
    [0.4, 0.224, 2.55],
    [0.728, 1.3, 2.55],
    [1.3, 0.728, 2.55],
    [0.728, 1.3, 2.4],
    [1.3, 0.728, 2.4],
    [0.0, 0.0, 0.0],
    [1.5, 0.0, 0.15],
    [1.5, 0.84, 0.15],
    [0.84, 1.5, 0.15],
    [0.0, 1.5, 0.15],
    [1.5, 0.0, 0.075],
    [1.5, 0.84, 0.075],
    [0.84, 1.5, 0.075],
    [0.0, 1.5, 0.075],
    [1.425, 0.0, 0.0],
    [1.425, 0.798, 0.0],
    [0.798, 1.425, 0.0],
    [0.0, 1.425, 0.0],
    [-0.84, 1.5, 0.15],
    [-1.5, 0.84, 0.15],
    [-1.5, 0.0, 0.15],
    [-0.84, 1.5, 0.075],
    [-1.5, 0.84, 0.075],
    [-1.5, 0.0, 0.075],
    [-0.798, 1.425, 0.0],
    [-1.425, 0.798, 0.0],
    [-1.425, 0.0, 0.0],
    [-1.5, -0.84, 0.15],
    [-0.84, -1.5, 0.15],
    [0.0, -1.5, 0.15],
    [-1.5, -0.84, 0.075],
    [-0.84, -1.5, 0.075],
    [0.0, -1.5, 0.075],
    [-1.425, -0.798, 0.0],
    [-0.798, -1.425, 0.0],
    [0.0, -1.425, 0.0],
    [0.84, -1.5, 0.15],
    [1.5, -0.84, 0.15],
    [0.84, -1.5, 0.075],
    [1.5, -0.84, 0.075],
    [0.798, -1.425, 0.0],
    [1.425, -0.798, 0.0],
];

/// 32 patches of 4×4 control points, 1-based indices into [`CONTROL_POINTS`], row-major (four
/// rows of four). Patches 0–3: rim, 4–11: body, 12–15: handle, 16–19: spout, 20–27: lid,
/// 28–31: bottom.
const PATCHES: [[u16; 16]; PATCH_COUNT] = [
    [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16],
    [4, 17, 18, 19, 8, 20, 21, 22, 12, 23, 24, 25, 16, 26, 27, 28],
    [
        19, 29, 30, 31, 22, 32, 33, 34, 25, 35, 36, 37, 28, 38, 39, 40,
    ],
    [31, 41, 42, 1, 34, 43, 44, 5, 37, 45, 46, 9, 40, 47, 48, 13],
    [
        13, 14, 15, 16, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60,
    ],
    [
        16, 26, 27, 28, 52, 61, 62, 63, 56, 64, 65, 66, 60, 67, 68, 69,
    ],
    [
        28, 38, 39, 40, 63, 70, 71, 72, 66, 73, 74, 75, 69, 76, 77, 78,
    ],
    [
        40, 47, 48, 13, 72, 79, 80, 49, 75, 81, 82, 53, 78, 83, 84, 57,
    ],
    [
        57, 58, 59, 60, 85, 86, 87, 88, 89, 90, 91, 92, 93, 94, 95, 96,
    ],
    [
        60, 67, 68, 69, 88, 97, 98, 99, 92, 100, 101, 102, 96, 103, 104, 105,
    ],
    [
        69, 76, 77, 78, 99, 106, 107, 108, 102, 109, 110, 111, 105, 112, 113, 114,
    ],
    [
        78, 83, 84, 57, 108, 115, 116, 85, 111, 117, 118, 89, 114, 119, 120, 93,
    ],
    [
        121, 122, 123, 124, 125, 126, 127, 128, 129, 130, 131, 132, 133, 134, 135, 136,
    ],
    [
        124, 137, 138, 121, 128, 139, 140, 125, 132, 141, 142, 129, 136, 143, 144, 133,
    ],
    [
        133, 134, 135, 136, 145, 146, 147, 148, 149, 150, 151, 152, 69, 153, 154, 155,
    ],
    [
        136, 143, 144, 133, 148, 156, 157, 145, 152, 158, 159, 149, 155, 160, 161, 69,
    ],
    [
        162, 163, 164, 165, 166, 167, 168, 169, 170, 171, 172, 173, 174, 175, 176, 177,
    ],
    [
        165, 178, 179, 162, 169, 180, 181, 166, 173, 182, 183, 170, 177, 184, 185, 174,
    ],
    [
        174, 175, 176, 177, 186, 187, 188, 189, 190, 191, 192, 193, 194, 195, 196, 197,
    ],
    [
        177, 184, 185, 174, 189, 198, 199, 186, 193, 200, 201, 190, 197, 202, 203, 194,
    ],
    [
        204, 204, 204, 204, 207, 208, 209, 210, 211, 211, 211, 211, 212, 213, 214, 215,
    ],
    [
        204, 204, 204, 204, 210, 217, 218, 219, 211, 211, 211, 211, 215, 220, 221, 222,
    ],
    [
        204, 204, 204, 204, 219, 224, 225, 226, 211, 211, 211, 211, 222, 227, 228, 229,
    ],
    [
        204, 204, 204, 204, 226, 230, 231, 207, 211, 211, 211, 211, 229, 232, 233, 212,
    ],
    [
        212, 213, 214, 215, 234, 235, 236, 237, 238, 239, 240, 241, 242, 243, 244, 245,
    ],
    [
        215, 220, 221, 222, 237, 246, 247, 248, 241, 249, 250, 251, 245, 252, 253, 254,
    ],
    [
        222, 227, 228, 229, 248, 255, 256, 257, 251, 258, 259, 260, 254, 261, 262, 263,
    ],
    [
        229, 232, 233, 212, 257, 264, 265, 234, 260, 266, 267, 238, 263, 268, 269, 242,
    ],
    [
        270, 270, 270, 270, 279, 280, 281, 282, 275, 276, 277, 278, 271, 272, 273, 274,
    ],
    [
        270, 270, 270, 270, 282, 289, 290, 291, 278, 286, 287, 288, 274, 283, 284, 285,
    ],
    [
        270, 270, 270, 270, 291, 298, 299, 300, 288, 295, 296, 297, 285, 292, 293, 294,
    ],
    [
        270, 270, 270, 270, 300, 305, 306, 279, 297, 303, 304, 275, 294, 301, 302, 271,
    ],
];

/// Groups of patches that share edges and are welded together; different groups only touch or
/// intersect (handle and spout pierce the body), so their normals are kept apart.
const WELD_GROUPS: [&[usize]; 4] = [
    &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 28, 29, 30, 31],
    &[12, 13, 14, 15],
    &[16, 17, 18, 19],
    &[20, 21, 22, 23, 24, 25, 26, 27],
];

/// Distance in data units below which two tessellated vertices are the same vertex.
const WELD_TOLERANCE: f32 = 1e-5;

/// Cubic Bernstein basis and its derivative at `t`.
fn bernstein(t: f32) -> ([f32; 4], [f32; 4]) {
    let s = 1.0 - t;
    (
        [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t],
        [
            -3.0 * s * s,
            3.0 * s * s - 6.0 * t * s,
            6.0 * t * s - 3.0 * t * t,
            3.0 * t * t,
        ],
    )
}

/// Control point `index` (1-based) rotated to y up.
fn control_point(index: u16) -> Vec3 {
    let [x, y, z] = CONTROL_POINTS[usize::from(index) - 1];
    Vec3::new(x, z, -y)
}

/// Position and the unnormalized normal ∂P/∂u × ∂P/∂v of `patch` at (u, v), y up; u runs along
/// a row of control points, v across rows. That cross product points out of the teapot.
fn evaluate(patch: usize, u: f32, v: f32) -> (Vec3, Vec3) {
    let (bu, du) = bernstein(u);
    let (bv, dv) = bernstein(v);
    let (mut position, mut tangent_u, mut tangent_v) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    for row in 0..4 {
        for column in 0..4 {
            let p = control_point(PATCHES[patch][4 * row + column]);
            position += bu[column] * bv[row] * p;
            tangent_u += du[column] * bv[row] * p;
            tangent_v += bu[column] * dv[row] * p;
        }
    }
    (position, tangent_u.cross(tangent_v))
}

/// The unit outward normal of `patch` at (u, v). Where the patch collapses to a point (the lid
/// knob's tip and the bottom's centre) the cross product vanishes; the normal is then the limit
/// taken a small step into the patch.
fn unit_normal(patch: usize, u: f32, v: f32) -> Vec3 {
    const STEP: f32 = 1e-3;
    let (_, normal) = evaluate(patch, u, v);
    if let Some(n) = normal.try_normalize().filter(|_| normal.length() > 1e-6) {
        return n;
    }
    let v_inside = if v < 0.5 { v + STEP } else { v - STEP };
    let u_inside = if u < 0.5 { u + STEP } else { u - STEP };
    let (_, normal) = evaluate(patch, u, v_inside);
    normal
        .try_normalize()
        .or_else(|| evaluate(patch, u_inside, v).1.try_normalize())
        .unwrap_or(Vec3::Y)
}

/// One patch tessellated on a `level × level` grid (not yet welded); uv = the patch parameters.
fn tessellate_patch(patch: usize, level: u32) -> TriangleMesh {
    parametric_grid(level, level, Winding::Parametric, |u, v| SurfacePoint {
        position: evaluate(patch, u, v).0,
        normal: unit_normal(patch, u, v),
        uv: Vec2::new(u, v),
    })
}

/// A named part of the teapot (the patch groups of the classic data).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TeapotPart {
    /// The lip around the opening (patches 0–3).
    Rim,
    /// The body (patches 4–11).
    Body,
    /// The handle (patches 12–15).
    Handle,
    /// The spout (patches 16–19).
    Spout,
    /// The lid with its knob (patches 20–27).
    Lid,
    /// The bottom (patches 28–31, added by Crow).
    Bottom,
}

impl TeapotPart {
    /// Every part.
    pub const ALL: [TeapotPart; 6] = [
        TeapotPart::Rim,
        TeapotPart::Body,
        TeapotPart::Handle,
        TeapotPart::Spout,
        TeapotPart::Lid,
        TeapotPart::Bottom,
    ];

    /// The part's name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            TeapotPart::Rim => "rim",
            TeapotPart::Body => "body",
            TeapotPart::Handle => "handle",
            TeapotPart::Spout => "spout",
            TeapotPart::Lid => "lid",
            TeapotPart::Bottom => "bottom",
        }
    }

    /// The part with that scene-file name.
    pub fn from_name(name: &str) -> Option<TeapotPart> {
        TeapotPart::ALL.into_iter().find(|part| part.name() == name)
    }

    /// The part's patch indices.
    fn patches(self) -> std::ops::Range<usize> {
        match self {
            TeapotPart::Rim => 0..4,
            TeapotPart::Body => 4..12,
            TeapotPart::Handle => 12..16,
            TeapotPart::Spout => 16..20,
            TeapotPart::Lid => 20..28,
            TeapotPart::Bottom => 28..32,
        }
    }
}

/// The whole Newell teapot, y up, in the data's units: x ∈ [−3, 3.43] (handle to spout),
/// y ∈ [0, 3.15], z ∈ [−2, 2]. See [`teapot_parts`].
pub fn teapot(level: u32) -> TriangleMesh {
    teapot_parts(level, &TeapotPart::ALL)
}

/// The chosen parts of the Newell teapot. Each of their patches is split into `level × level`
/// quads (`level` ≥ 1; 8 gives about 4k triangles for the whole teapot); coincident vertices
/// are welded within each connected part (rim + body + bottom, handle, spout, lid), collapsed
/// triangles at the poles removed, and normals are the averaged analytic patch normals, so they
/// are smooth and finite everywhere. No texture coordinates.
pub fn teapot_parts(level: u32, parts: &[TeapotPart]) -> TriangleMesh {
    let level = level.max(1);
    let chosen: Vec<usize> = parts.iter().flat_map(|part| part.patches()).collect();
    let mut mesh = TriangleMesh::default();
    for group in WELD_GROUPS {
        let mut piece = TriangleMesh::default();
        for &patch in group.iter().filter(|p| chosen.contains(p)) {
            piece.append(&tessellate_patch(patch, level));
        }
        if piece.triangles.is_empty() {
            continue;
        }
        piece.weld(WELD_TOLERANCE);
        mesh.append(&piece);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_32_patches_of_valid_indices() {
        assert_eq!(PATCHES.len(), 32);
        assert!(
            PATCHES
                .iter()
                .flatten()
                .all(|&i| (1..=CONTROL_POINTS.len()).contains(&usize::from(i)))
        );
        let mut grouped: Vec<usize> = WELD_GROUPS.iter().flat_map(|g| g.iter().copied()).collect();
        grouped.sort_unstable();
        assert_eq!(grouped, (0..PATCH_COUNT).collect::<Vec<_>>());
        let mut parted: Vec<usize> = TeapotPart::ALL.iter().flat_map(|p| p.patches()).collect();
        parted.sort_unstable();
        assert_eq!(parted, (0..PATCH_COUNT).collect::<Vec<_>>());
    }

    #[test]
    fn parts_add_up_to_the_whole() {
        let whole = teapot(4);
        let lid = teapot_parts(4, &[TeapotPart::Lid]);
        let rest = teapot_parts(
            4,
            &[
                TeapotPart::Rim,
                TeapotPart::Body,
                TeapotPart::Handle,
                TeapotPart::Spout,
                TeapotPart::Bottom,
            ],
        );
        assert_eq!(
            lid.triangle_count() + rest.triangle_count(),
            whole.triangle_count()
        );
        let (lo, _) = lid.bounds().unwrap_or_default();
        assert!(lo.y > 2.39, "the lid sits on top: {lo}");
        assert_eq!(TeapotPart::from_name("spout"), Some(TeapotPart::Spout));
    }

    #[test]
    fn bounding_box_is_the_classic_teapot() {
        let mesh = teapot(16);
        let (lo, hi) = mesh.bounds().unwrap_or_default();
        // Classic extents: handle at x = −3, spout tip ≈ 3.43, lid knob 3.15, body radius 2.
        assert!((lo.x + 3.0).abs() < 0.01, "{lo}");
        assert!((hi.x - 3.434).abs() < 0.01, "{hi}");
        assert!(lo.y.abs() < 1e-6 && (hi.y - 3.15).abs() < 1e-6, "{lo} {hi}");
        assert!(
            (lo.z + 2.0).abs() < 1e-3 && (hi.z - 2.0).abs() < 1e-3,
            "{lo} {hi}"
        );
    }

    #[test]
    fn normals_are_finite_unit_and_agree_with_the_winding() {
        for level in [1, 2, 3, 8, 13] {
            let mesh = teapot(level);
            assert_eq!(mesh.check(), Ok(()), "level {level}");
            if level < 3 {
                // Too coarse for smooth normals to agree with every facet (the handle's
                // cross-section is two triangles, the spout's folded lip a few); only
                // finiteness is meaningful.
                assert!(mesh.normals.iter().all(|n| n.is_finite()));
                continue;
            }
            assert!(mesh.triangle_count() > 32 * level as usize * level as usize);
            for n in &mesh.normals {
                assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5);
            }
            let agreeing = (0..mesh.triangle_count())
                .filter(|&t| {
                    let vertex: Vec3 = mesh.triangles[t]
                        .iter()
                        .map(|&i| mesh.normals[i as usize])
                        .sum();
                    mesh.triangle_normal(t).dot(vertex) > 0.0
                })
                .count();
            assert_eq!(agreeing, mesh.triangle_count(), "level {level}");
        }
    }

    #[test]
    fn normals_point_out_of_the_body() {
        // On the body (|x|, |z| within the pot, away from spout and handle), the outward normal
        // points away from the vertical axis; on the lid and bottom it points up and down.
        let mesh = teapot(8);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let radial = Vec3::new(p.x, 0.0, p.z);
            if p.y > 0.2 && p.y < 2.3 && p.x.abs() < 1.5 {
                assert!(n.dot(radial) > 0.0, "body normal {n} at {p}");
            }
            if p.y < 1e-6 {
                assert!(n.y < -0.99, "bottom normal {n} at {p}");
            }
            if p.y > 3.15 - 1e-6 {
                assert!(n.y > 0.99, "lid tip normal {n} at {p}");
            }
        }
    }

    #[test]
    fn welded_teapot_is_mirror_symmetric() {
        // The data is symmetric about the data's y = 0 plane, here z = 0.
        let mesh = teapot(6);
        let key = |p: Vec3| {
            (
                (p.x * 1e4).round() as i64,
                (p.y * 1e4).round() as i64,
                (p.z * 1e4).round() as i64,
            )
        };
        let set: std::collections::HashSet<_> = mesh.positions.iter().map(|&p| key(p)).collect();
        for p in &mesh.positions {
            assert!(
                set.contains(&key(Vec3::new(p.x, p.y, -p.z))),
                "{p} has no mirror image"
            );
        }
    }
}
