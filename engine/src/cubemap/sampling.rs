//! Cube-map sampling in f64, step by step as the Vulkan specification describes it (chapter
//! "Image Operations": "Cube Map Derivative Transformation", "Scale Factor Operation, LOD
//! Operation and Image Level(s) Selection", "Texel Filtering", "Cube Map Edge Handling"), for the
//! sampler state the compositor uses: linear min/mag filter, `VK_SAMPLER_MIPMAP_MODE_LINEAR`,
//! seamless cube filtering, minLod 0, maxLod = levels − 1, no bias, no anisotropy.
//!
//! This is the reference the CPU frame model (`render::model`) samples through; it never rounds
//! to f32, so differences against a GPU measure the GPU's arithmetic, not this code's.
//!
//! Where the specification leaves a choice to the implementation, this module takes the choice
//! the specification recommends (and that Mesa's llvmpipe/lavapipe makes), and says so: a
//! bilinear footprint that falls off a face in both i and j (a cube corner) replaces the missing
//! texel by the average of the three texels that exist. [`CubeSample::corner`] reports it so that
//! comparisons can leave such samples out.
//!
//! Where the specification lets an implementation round or approximate, [`sample_cube_bounds`]
//! gives the range every conformant result lies in, from the device's [`FilterPrecision`]: the
//! LOD anywhere in [`cube_lod_range_on_face`] (the spec's allowed approximation of the scale
//! factor, coarse or fine derivatives, the LOD fraction resolved to `mipmapPrecisionBits`), and
//! bilinear weights snapped to `subTexelPrecisionBits`.

use glam::DVec3;

use super::CubeMap;
use super::face::{
    CubeFace, FaceCoordinates, face_coordinates_on, major_face, select_face, texel_source,
};

/// The spec's cube-map derivative transformation: the screen-space derivative `(∂s, ∂t)` of the
/// face coordinates of `coordinates`, given the derivative `d_direction` of the direction.
///
/// With `m = |rc| = normal·r` (so `∂m = normal·∂r`, which is the spec's derivative table),
/// `s = ½(sc/m + 1)` and the quotient rule give
/// `∂s = ½ (∂sc·m − sc·∂m) / m²` and `∂t = ½ (∂tc·m − tc·∂m) / m²`.
pub fn face_derivatives(coordinates: &FaceCoordinates, d_direction: DVec3) -> (f64, f64) {
    let (s_axis, t_axis, normal) = coordinates.face.axes();
    let d_sc = s_axis.dot(d_direction);
    let d_tc = t_axis.dot(d_direction);
    let d_major = normal.dot(d_direction);
    let m = coordinates.major;
    let m2 = m * m;
    (
        0.5 * (d_sc * m - coordinates.sc * d_major) / m2,
        0.5 * (d_tc * m - coordinates.tc * d_major) / m2,
    )
}

/// How `λ_base = log2 ρ` is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LodLog2 {
    /// The exact logarithm, as the spec writes it.
    #[default]
    Exact,
    /// Mesa llvmpipe/lavapipe's default: it skips the square root and takes
    /// `λ = ½·fast_log2(ρ²)` with the piecewise-linear `fast_log2(2^e·m) = e + m − 1`
    /// (m ∈ [1, 2)), exact at powers of two and up to ≈0.043 low in between (measured against
    /// lavapipe, Mesa 22.3: it reproduces its LODs to f32 precision).
    PiecewiseLinearOfSquare,
}

impl LodLog2 {
    /// `log2 ρ` evaluated this way from `ρ²`.
    pub fn log2_from_square(self, rho_squared: f64) -> f64 {
        match self {
            LodLog2::Exact => 0.5 * rho_squared.log2(),
            LodLog2::PiecewiseLinearOfSquare => {
                if rho_squared == f64::INFINITY {
                    return f64::INFINITY;
                }
                if rho_squared.is_nan() || rho_squared < f64::MIN_POSITIVE {
                    // 0, subnormal or NaN: level 0 after clamping.
                    return f64::NEG_INFINITY;
                }
                // Exponent and mantissa straight from the bits, so powers of two are exact.
                let exponent = ((rho_squared.to_bits() >> 52) & 0x7ff) as i64 - 1023;
                let mantissa = rho_squared / 2f64.powi(exponent as i32);
                0.5 * (exponent as f64 + mantissa - 1.0)
            }
        }
    }
}

/// The LOD λ for `direction` forced onto `face`, clamped to `[0, levels − 1]` (see [`cube_lod`]),
/// with `log2` evaluated as `log2` says.
pub fn cube_lod_on_face(
    face: CubeFace,
    cube_size: u32,
    levels: u32,
    direction: DVec3,
    ddx: DVec3,
    ddy: DVec3,
    log2: LodLog2,
) -> f64 {
    let coordinates = face_coordinates_on(face, direction);
    let (ds_dx, dt_dx) = face_derivatives(&coordinates, ddx);
    let (ds_dy, dt_dy) = face_derivatives(&coordinates, ddy);
    let size = f64::from(cube_size);
    // Scale factor operation: m_ux = |∂s/∂x|·w_base …; isotropic ρ = max(ρx, ρy) with the exact
    // ρx = sqrt(m_ux² + m_vx²) (the spec allows approximations; lavapipe computes this one
    // unless GALLIVM_PERF=rho_approx), kept squared until the logarithm.
    let rho_x2 = size * size * (ds_dx * ds_dx + dt_dx * dt_dx);
    let rho_y2 = size * size * (ds_dy * ds_dy + dt_dy * dt_dy);
    let lambda = log2.log2_from_square(rho_x2.max(rho_y2));
    // λ = clamp(λ_base, minLod = 0, maxLod = q); ρ = 0 (log2 = −∞) and NaN give level 0.
    let max_lod = f64::from(levels.max(1) - 1);
    if lambda > 0.0 {
        lambda.min(max_lod)
    } else {
        0.0
    }
}

/// The implicit LOD λ of a cube-map sample at `direction` whose screen-space derivatives are
/// `ddx = ∂r/∂x` and `ddy = ∂r/∂y`, for a cube of level-0 face size `cube_size` and `levels`
/// mip levels; clamped to `[0, levels − 1]` (sampler minLod 0, maxLod levels − 1, no bias).
///
/// `λ = log2 max(ρx, ρy)`, `ρx = cube_size·sqrt((∂s/∂x)² + (∂t/∂x)²)`, with `∂s/∂x` from the
/// cube-map derivative transformation ([`face_derivatives`]) on the face `direction` selects.
/// The exact logarithm; [`cube_lod_with`] takes lavapipe's approximation.
pub fn cube_lod(cube_size: u32, levels: u32, direction: DVec3, ddx: DVec3, ddy: DVec3) -> f64 {
    cube_lod_with(cube_size, levels, direction, ddx, ddy, LodLog2::Exact)
}

/// [`cube_lod`] with the logarithm evaluated as `log2` says.
pub fn cube_lod_with(
    cube_size: u32,
    levels: u32,
    direction: DVec3,
    ddx: DVec3,
    ddy: DVec3,
    log2: LodLog2,
) -> f64 {
    cube_lod_on_face(
        major_face(direction),
        cube_size,
        levels,
        direction,
        ddx,
        ddy,
        log2,
    )
}

/// The filtering precision a device reports, which bounds how far its filtered values may stray
/// from exact arithmetic (Vulkan requires at least 4 bits of each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FilterPrecision {
    /// `subTexelPrecisionBits`: bilinear fractions α, β snap to multiples of `2^-bits`.
    pub sub_texel_bits: u32,
    /// `mipmapPrecisionBits`: the LOD's fraction (the weight between two mip levels) is resolved
    /// to multiples of `2^-bits`.
    pub mipmap_bits: u32,
}

impl FilterPrecision {
    /// The loosest precision the Vulkan spec allows (4 bits of each: the minimum of
    /// `subTexelPrecisionBits` and `mipmapPrecisionBits` in the spec's "Required Limits" table),
    /// and the precision every conformant driver is held to whatever it reports.
    ///
    /// The spec says "The LOD must be computed with mipmapPrecisionBits of accuracy" (chapter
    /// "Image Operations", "Scale Factor Operation, LOD Operation and Image Level(s) Selection")
    /// and has sub-texel values "snap" to `subTexelPrecisionBits` (`VkPhysicalDeviceLimits`), so
    /// a driver's reported values bind it on paper. Conformance does not check them: the Khronos
    /// CTS verifies filtered results first at 6 LOD bits and 7 sub-texel bits and, failing that,
    /// again at 4 and 4, which passes with a quality warning. Measured: Mesa 25.0's lavapipe
    /// reports 6 mipmap bits while its LOD (½·log2 of ρ² by a piecewise-linear log2, unchanged
    /// since Mesa 22.3, which reported 4) is up to 0.043 low, 2.75 steps of 2^-6 where the bounds
    /// allow 2. A bound that must hold on any conformant driver therefore takes these bits.
    pub const SPEC_MINIMUM: FilterPrecision = FilterPrecision {
        sub_texel_bits: 4,
        mipmap_bits: 4,
    };

    /// The sub-texel grid step `2^-sub_texel_bits`, in texels.
    pub fn sub_texel_step(self) -> f64 {
        (-f64::from(self.sub_texel_bits)).exp2()
    }

    /// The LOD grid step `2^-mipmap_bits`.
    pub fn mipmap_step(self) -> f64 {
        (-f64::from(self.mipmap_bits)).exp2()
    }
}

/// Every LOD a conformant implementation may use for a sample at `direction` on `face`, as
/// `[λ_lo, λ_hi]` within `[0, levels − 1]`, for a cube of level-0 face size `cube_size`.
///
/// `derivatives` holds the `(∂r/∂x, ∂r/∂y)` pairs the implementation may take (coarse and fine:
/// the spec lets it choose). For each, the spec's "Scale Factor Operation" lets ρx be any `fx`
/// with `max(|m_ux|, |m_vx|) ≤ fx ≤ √2 (|m_ux| + |m_vx|)` (likewise y), so `λ_base = log2
/// max(fx, fy)` lies between the logarithms of those bounds. The range is then widened by
/// `2·2^-mipmap_bits` on each side: the spec asks for the LOD "computed with
/// mipmapPrecisionBits of accuracy" and then quantizes the fraction δ between levels to those
/// bits, a step each (this also covers approximate logarithms, such as lavapipe's
/// [`LodLog2::PiecewiseLinearOfSquare`], ≤ 0.043 low where lavapipe reports 4 bits). Last it is
/// clamped as minLod 0, maxLod `levels − 1` clamp it.
pub fn cube_lod_range_on_face(
    face: CubeFace,
    cube_size: u32,
    levels: u32,
    direction: DVec3,
    derivatives: &[(DVec3, DVec3)],
    precision: FilterPrecision,
) -> [f64; 2] {
    let coordinates = face_coordinates_on(face, direction);
    let size = f64::from(cube_size);
    let mut range = [f64::INFINITY, f64::NEG_INFINITY];
    for &(ddx, ddy) in derivatives {
        let (ds_dx, dt_dx) = face_derivatives(&coordinates, ddx);
        let (ds_dy, dt_dy) = face_derivatives(&coordinates, ddy);
        let [m_ux, m_vx, m_uy, m_vy] = [ds_dx, dt_dx, ds_dy, dt_dy].map(|d| (size * d).abs());
        let lower = m_ux.max(m_vx).max(m_uy).max(m_vy);
        let upper = std::f64::consts::SQRT_2 * (m_ux + m_vx).max(m_uy + m_vy);
        range[0] = range[0].min(lower.log2());
        range[1] = range[1].max(upper.log2());
    }
    let step = 2.0 * precision.mipmap_step();
    let max_lod = f64::from(levels.max(1) - 1);
    // As in cube_lod_on_face: below 0, −∞ and NaN clamp to level 0.
    let clamp = |lambda: f64| {
        if lambda > 0.0 {
            lambda.min(max_lod)
        } else {
            0.0
        }
    };
    [clamp(range[0] - step), clamp(range[1] + step)]
}

/// One texel of a cube map as f64.
fn texel(cube: &CubeMap, level: usize, face: CubeFace, i: u32, j: u32) -> [f64; 4] {
    let size = cube.level_size(level) as usize;
    let t = cube.levels[level][face.index()][j as usize * size + i as usize];
    [
        f64::from(t[0]),
        f64::from(t[1]),
        f64::from(t[2]),
        f64::from(t[3]),
    ]
}

/// A filtered cube-map value and whether its footprint used an implementation-defined corner
/// texel with a non-zero weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubeSample {
    /// Premultiplied RGBA.
    pub rgba: [f64; 4],
    /// A cube-corner texel (see [`texel_source`]) entered the filter with a non-zero weight and
    /// the three texels it is made from differ, so the value depends on the implementation's
    /// corner rule (here: the average of the three).
    pub corner: bool,
}

/// A level's bilinear footprint around a point: the four texels (seamless edge handling, a
/// missing cube-corner texel replaced by the average of the other three) and the point's
/// fractions α, β between them (spec "Texel Linear Filtering": `i0 = ⌊u − ½⌋`, `α = frac(u − ½)`,
/// `u = s·size_level`, likewise j and β).
struct Footprint {
    /// Order (i0,j0), (i1,j0), (i0,j1), (i1,j1).
    texels: [[f64; 4]; 4],
    /// The footprint entry that is a cube-corner texel whose three source texels differ (the
    /// spec then leaves its value to the implementation).
    corner: Option<usize>,
    alpha: f64,
    beta: f64,
}

impl Footprint {
    fn new(cube: &CubeMap, level: usize, coordinates: &FaceCoordinates) -> Footprint {
        let size = cube.level_size(level);
        let n = f64::from(size);
        let u = coordinates.s * n - 0.5;
        let v = coordinates.t * n - 0.5;
        let (i0, j0) = (u.floor(), v.floor());
        let (alpha, beta) = (u - i0, v - j0);
        let (i0, j0) = (i0 as i64, j0 as i64);
        let offsets = [(0, 0), (1, 0), (0, 1), (1, 1)];
        let mut values: [Option<[f64; 4]>; 4] = [None; 4];
        for (value, (di, dj)) in values.iter_mut().zip(offsets) {
            *value = texel_source(coordinates.face, size, i0 + di, j0 + dj)
                .map(|(face, i, j)| texel(cube, level, face, i, j));
        }
        let mut corner = None;
        let texels = std::array::from_fn(|k| match values[k] {
            Some(value) => value,
            None => {
                // The corner texel: the spec's recommended average of the three others (at most
                // one footprint texel can be a corner, so the others all exist). The spec binds
                // every implementation only where the three are equal: the result must then be
                // that value, so only unequal texels make the sample implementation-defined.
                let others: Vec<[f64; 4]> = values.iter().flatten().copied().collect();
                if others.iter().any(|other| *other != others[0]) {
                    corner = Some(k);
                }
                let mut sum = [0.0; 4];
                for other in &others {
                    for c in 0..4 {
                        sum[c] += other[c] / 3.0;
                    }
                }
                sum
            }
        });
        Footprint {
            texels,
            corner,
            alpha,
            beta,
        }
    }

    /// The bilinear value at fractions `(alpha, beta)` ∈ [0, 1]².
    fn filter(&self, alpha: f64, beta: f64) -> CubeSample {
        let weights = [
            (1.0 - alpha) * (1.0 - beta),
            alpha * (1.0 - beta),
            (1.0 - alpha) * beta,
            alpha * beta,
        ];
        let mut rgba = [0.0; 4];
        for (weight, value) in weights.iter().zip(&self.texels) {
            for c in 0..4 {
                rgba[c] += weight * value[c];
            }
        }
        CubeSample {
            rgba,
            corner: self.corner.is_some_and(|k| weights[k] > 0.0),
        }
    }

    /// Per channel, the range of the bilinear value over every `(α', β')` within `step` of the
    /// footprint's own fractions (clamped to [0, 1]): a value that is linear in α and in β takes
    /// its extremes over a rectangle at its corners. With `step = 2^-subTexelPrecisionBits` this
    /// contains every result with the fractions snapped to the sub-texel grid, whichever way an
    /// implementation rounds (the grid holds the integers, so a snapped point never leaves the
    /// footprint). `corner` is set if the corner texel gets weight anywhere in that rectangle.
    fn filter_bounds(&self, step: f64) -> ([[f64; 2]; 4], bool) {
        let alphas = [(self.alpha - step).max(0.0), (self.alpha + step).min(1.0)];
        let betas = [(self.beta - step).max(0.0), (self.beta + step).min(1.0)];
        let mut bounds = [[f64::INFINITY, f64::NEG_INFINITY]; 4];
        let mut corner = false;
        for alpha in alphas {
            for beta in betas {
                let sample = self.filter(alpha, beta);
                corner |= sample.corner;
                for (bound, value) in bounds.iter_mut().zip(sample.rgba) {
                    *bound = [bound[0].min(value), bound[1].max(value)];
                }
            }
        }
        (bounds, corner)
    }
}

/// Bilinear filtering within one mip level at the face coordinates of `coordinates`, with
/// seamless edge handling (spec "Texel Linear Filtering": `i0 = ⌊u − ½⌋`, `α = frac(u − ½)`,
/// `u = s·size_level`, likewise j and β).
pub fn sample_level_bilinear(
    cube: &CubeMap,
    level: usize,
    coordinates: &FaceCoordinates,
) -> CubeSample {
    let footprint = Footprint::new(cube, level, coordinates);
    footprint.filter(footprint.alpha, footprint.beta)
}

/// Trilinear sample of `cube` at `direction` with LOD `lambda` (clamped to `[0, levels − 1]`),
/// reporting corner use (see [`CubeSample`]).
///
/// Mipmap selection as the spec's LINEAR mode: `d = clamp(λ, 0, q)`, levels `⌊d⌋` and
/// `min(⌊d⌋ + 1, q)` blended by `δ = frac(d)`.
pub fn sample_cube(cube: &CubeMap, direction: DVec3, lambda: f64) -> CubeSample {
    let coordinates = select_face(direction);
    let q = cube.levels.len().saturating_sub(1);
    let d = if lambda > 0.0 {
        lambda.min(q as f64)
    } else {
        0.0
    };
    let hi = (d.floor() as usize).min(q);
    let lo = (hi + 1).min(q);
    let delta = d - hi as f64;
    let first = sample_level_bilinear(cube, hi, &coordinates);
    if lo == hi || delta == 0.0 {
        return first;
    }
    let second = sample_level_bilinear(cube, lo, &coordinates);
    let mut rgba = [0.0; 4];
    for (c, value) in rgba.iter_mut().enumerate() {
        *value = (1.0 - delta) * first.rgba[c] + delta * second.rgba[c];
    }
    CubeSample {
        rgba,
        corner: first.corner || second.corner,
    }
}

/// Trilinear, seamless sample of `cube` at `direction` (need not be normalized) with LOD
/// `lambda`; premultiplied RGBA. See [`sample_cube`].
pub fn sample_cube_trilinear(cube: &CubeMap, direction: DVec3, lambda: f64) -> [f64; 4] {
    sample_cube(cube, direction, lambda).rgba
}

/// The range of a trilinear cube sample over what a conformant implementation may do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubeSampleBounds {
    /// Per premultiplied RGBA channel, `[lo, hi]`.
    pub bounds: [[f64; 2]; 4],
    /// Some footprint in the range gives an implementation-defined cube-corner texel weight
    /// (see [`CubeSample::corner`]): the bounds assume the spec's recommended average there.
    pub corner: bool,
}

/// Per channel, the range of the trilinear sample of `cube` at `direction` over every LOD in
/// `lod_range` (see [`cube_lod_range_on_face`]) and bilinear fractions snapped to
/// `precision`'s sub-texel grid.
///
/// The value is piecewise linear in λ between integer levels, with each level's value anywhere in
/// its snapped-fraction range (`Footprint::filter_bounds`); so are the range's ends, and the hull
/// over λ is taken at `lod_range`'s ends and the integer levels between them.
pub fn sample_cube_bounds(
    cube: &CubeMap,
    direction: DVec3,
    lod_range: [f64; 2],
    precision: FilterPrecision,
) -> CubeSampleBounds {
    let coordinates = select_face(direction);
    let q = cube.levels.len().saturating_sub(1);
    let step = precision.sub_texel_step();
    let mut levels: Vec<Option<[[f64; 2]; 4]>> = vec![None; q + 1];
    let mut corner = false;
    let mut level_bounds = |level: usize| -> [[f64; 2]; 4] {
        *levels[level].get_or_insert_with(|| {
            let (bounds, level_corner) =
                Footprint::new(cube, level, &coordinates).filter_bounds(step);
            corner |= level_corner;
            bounds
        })
    };
    let clamp = |lambda: f64| {
        if lambda > 0.0 {
            lambda.min(q as f64)
        } else {
            0.0
        }
    };
    let (lo, hi) = (clamp(lod_range[0]), clamp(lod_range[1].max(lod_range[0])));
    let inner = (lo.floor() as usize + 1..=hi.ceil() as usize).filter(|&k| (k as f64) < hi);
    let mut bounds = [[f64::INFINITY, f64::NEG_INFINITY]; 4];
    for d in std::iter::once(lo)
        .chain(inner.map(|k| k as f64))
        .chain(std::iter::once(hi))
    {
        let first = (d.floor() as usize).min(q);
        let second = (first + 1).min(q);
        let delta = d - first as f64;
        let at_d = if second == first || delta == 0.0 {
            level_bounds(first)
        } else {
            let (a, b) = (level_bounds(first), level_bounds(second));
            std::array::from_fn(|c| {
                [
                    (1.0 - delta) * a[c][0] + delta * b[c][0],
                    (1.0 - delta) * a[c][1] + delta * b[c][1],
                ]
            })
        };
        for (bound, value) in bounds.iter_mut().zip(at_d) {
            *bound = [bound[0].min(value[0]), bound[1].max(value[1])];
        }
    }
    CubeSampleBounds { bounds, corner }
}

#[cfg(test)]
mod tests {
    use super::super::face::competing_faces;
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_cube(rng: &mut Pcg64, size: u32) -> CubeMap {
        let levels = (0..CubeMap::full_chain_levels(size))
            .map(|l| {
                let n = ((size >> l).max(1) as usize).pow(2);
                std::array::from_fn(|_| {
                    (0..n)
                        .map(|_| std::array::from_fn(|_| rng.gen_range(0.0f32..1.0)))
                        .collect()
                })
            })
            .collect();
        CubeMap { size, levels }
    }

    fn close(a: [f64; 4], b: [f64; 4], tolerance: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tolerance)
    }

    #[test]
    fn uniform_cube_samples_to_its_texel_everywhere_at_every_lod() {
        let mut rng = Pcg64::seed_from_u64(1);
        let texel = [0.25f32, 0.5, 0.125, 0.75];
        let expected = texel.map(f64::from);
        for size in [1, 2, 8, 32] {
            let cube = CubeMap::uniform(size, texel);
            for _ in 0..500 {
                let direction = DVec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                );
                let lambda = rng.gen_range(-1.0..7.0);
                let sample = sample_cube(&cube, direction, lambda);
                assert!(
                    close(sample.rgba, expected, 1e-12),
                    "{sample:?} at {direction}"
                );
            }
            // Cube corners and edges too: the corner rule keeps a uniform value uniform.
            for direction in [
                DVec3::ONE,
                DVec3::new(1.0, -1.0, 0.3),
                DVec3::new(-1.0, 0.0, 1.0),
            ] {
                let sample = sample_cube_trilinear(&cube, direction, 0.0);
                assert!(close(sample, expected, 1e-12));
            }
        }
    }

    #[test]
    fn face_selection_for_the_axes_and_ties() {
        let cases = [
            (DVec3::X, CubeFace::PositiveX),
            (DVec3::NEG_X, CubeFace::NegativeX),
            (DVec3::Y, CubeFace::PositiveY),
            (DVec3::NEG_Y, CubeFace::NegativeY),
            (DVec3::Z, CubeFace::PositiveZ),
            (DVec3::NEG_Z, CubeFace::NegativeZ),
            // Ties: z wins over y and x, y wins over x.
            (DVec3::new(1.0, 1.0, 1.0), CubeFace::PositiveZ),
            (DVec3::new(1.0, 0.5, -1.0), CubeFace::NegativeZ),
            (DVec3::new(-1.0, 1.0, 0.0), CubeFace::PositiveY),
            (DVec3::new(2.0, -2.0, 1.0), CubeFace::NegativeY),
        ];
        for (direction, face) in cases {
            assert_eq!(major_face(direction), face, "{direction}");
            let coordinates = select_face(direction);
            if direction.abs().max_element() == direction.abs().min_element() {
                continue;
            }
            if direction.length_squared() == 1.0 {
                // An axis hits its face's centre.
                assert_eq!((coordinates.s, coordinates.t), (0.5, 0.5));
            }
        }
    }

    #[test]
    fn face_coordinates_follow_the_spec_table() {
        // Each direction has |major| = 2, sc and tc worked out by hand from the spec's table
        // (sc, tc) = (−rz, −ry) for +X, (+rz, −ry) −X, (+rx, +rz) +Y, (+rx, −rz) −Y,
        // (+rx, −ry) +Z, (−rx, −ry) −Z; then s = ½(sc/2 + 1), t = ½(tc/2 + 1).
        let cases = [
            // +X: sc = −(−1) = 1, tc = −0.5 → s = 0.75, t = 0.375
            (DVec3::new(2.0, 0.5, -1.0), CubeFace::PositiveX, 0.75, 0.375),
            // −X: sc = −1, tc = −0.5 → s = 0.25, t = 0.375
            (
                DVec3::new(-2.0, 0.5, -1.0),
                CubeFace::NegativeX,
                0.25,
                0.375,
            ),
            // +Y: sc = 1, tc = −1 → s = 0.75, t = 0.25
            (DVec3::new(1.0, 2.0, -1.0), CubeFace::PositiveY, 0.75, 0.25),
            // −Y: sc = 1, tc = 1 → s = 0.75, t = 0.75
            (DVec3::new(1.0, -2.0, -1.0), CubeFace::NegativeY, 0.75, 0.75),
            // +Z: sc = 1, tc = −0.5 → s = 0.75, t = 0.375
            (DVec3::new(1.0, 0.5, 2.0), CubeFace::PositiveZ, 0.75, 0.375),
            // −Z: sc = −1, tc = −0.5 → s = 0.25, t = 0.375
            (DVec3::new(1.0, 0.5, -2.0), CubeFace::NegativeZ, 0.25, 0.375),
        ];
        for (direction, face, s, t) in cases {
            let coordinates = select_face(direction);
            assert_eq!(coordinates.face, face);
            assert_eq!((coordinates.s, coordinates.t), (s, t), "{face:?}");
            // And the inverse map returns the direction (scaled to |major| = 1).
            let back = face.direction(2.0 * s - 1.0, 2.0 * t - 1.0);
            assert!((back * 2.0 - direction).length() < 1e-15);
        }
    }

    #[test]
    fn edge_texels_come_from_the_neighbour_llvmpipe_names() {
        // llvmpipe's lp_build_cube_new_coords: next face when falling off each edge, per face
        // 0..6: x < 0 → 451110, x ≥ size → 540001, y < 0 → 225422, y ≥ size → 334533.
        let next = [
            [4, 5, 2, 3],
            [5, 4, 2, 3],
            [1, 0, 5, 4],
            [1, 0, 4, 5],
            [1, 0, 2, 3],
            [0, 1, 2, 3],
        ];
        let size = 8u32;
        let max = i64::from(size) - 1;
        for face in CubeFace::ALL {
            let row = next[face.index()];
            for k in 0..=max {
                let off = [(-1, k), (max + 1, k), (k, -1), (k, max + 1)];
                for (edge, (i, j)) in off.into_iter().enumerate() {
                    let (there, ti, tj) = texel_source(face, size, i, j).unwrap();
                    assert_eq!(there.index(), row[edge], "{face:?} edge {edge}");
                    // The neighbour texel lies on its face's border, and its centre is the
                    // closest one to the point just past our edge.
                    let border = ti == 0 || tj == 0 || ti as i64 == max || tj as i64 == max;
                    assert!(border);
                }
            }
        }
        // Spot checks of the coordinates against llvmpipe's "new xcoords / ycoords" table.
        // +X, x < 0 → +Z at (max, t).
        assert_eq!(
            texel_source(CubeFace::PositiveX, 8, -1, 3),
            Some((CubeFace::PositiveZ, 7, 3))
        );
        // +Y, x < 0 → −X at (t, 0).
        assert_eq!(
            texel_source(CubeFace::PositiveY, 8, -1, 3),
            Some((CubeFace::NegativeX, 3, 0))
        );
        // +Y, y < 0 → −Z at (max − s, 0).
        assert_eq!(
            texel_source(CubeFace::PositiveY, 8, 2, -1),
            Some((CubeFace::NegativeZ, 5, 0))
        );
        // −Y, y ≥ size → −Z at (max − s, max).
        assert_eq!(
            texel_source(CubeFace::NegativeY, 8, 2, 8),
            Some((CubeFace::NegativeZ, 5, 7))
        );
        // +Z, y ≥ size → −Y at (s, 0).
        assert_eq!(
            texel_source(CubeFace::PositiveZ, 8, 2, 8),
            Some((CubeFace::NegativeY, 2, 0))
        );
        // −X, x ≥ size → +Z at (0, t).
        assert_eq!(
            texel_source(CubeFace::NegativeX, 8, 8, 6),
            Some((CubeFace::PositiveZ, 0, 6))
        );
        // Corners have no source.
        assert_eq!(texel_source(CubeFace::PositiveZ, 8, -1, 8), None);
    }

    #[test]
    fn linear_ramp_samples_bilinearly_exact_inside_a_face() {
        let size = 16u32;
        let mut cube = CubeMap::uniform(size, [0.0; 4]);
        let n = size as usize;
        let ramp = |i: f64, j: f64| [0.1 + 0.01 * i, 0.2 + 0.02 * j, 0.01 * i + 0.03 * j, 0.5];
        for face in CubeFace::ALL {
            for j in 0..n {
                for i in 0..n {
                    cube.levels[0][face.index()][j * n + i] =
                        ramp(i as f64, j as f64).map(|v| v as f32);
                }
            }
        }
        let mut rng = Pcg64::seed_from_u64(2);
        for face in CubeFace::ALL {
            for _ in 0..200 {
                // Interior: u − ½ within [0, size − 1] keeps the footprint on the face.
                let u = rng.gen_range(0.5..(size as f64 - 0.5));
                let v = rng.gen_range(0.5..(size as f64 - 0.5));
                let (s, t) = (u / size as f64, v / size as f64);
                let direction = face.direction(2.0 * s - 1.0, 2.0 * t - 1.0) * 3.0;
                let sample = sample_cube(&cube, direction, 0.0);
                // The f32 texels are the ramp to within f32 rounding.
                let expected = ramp(u - 0.5, v - 0.5);
                assert!(
                    close(sample.rgba, expected, 1e-6),
                    "{face:?} {sample:?} {expected:?}"
                );
                assert!(!sample.corner);
            }
        }
    }

    #[test]
    fn trilinear_at_half_lod_averages_two_levels() {
        let mut rng = Pcg64::seed_from_u64(3);
        let cube = random_cube(&mut rng, 16);
        for _ in 0..100 {
            let face = CubeFace::ALL[rng.gen_range(0..6)];
            let direction =
                face.direction(rng.gen_range(-0.9..0.9), rng.gen_range(-0.9..0.9)) * 1.7;
            let coordinates = select_face(direction);
            let level0 = sample_level_bilinear(&cube, 0, &coordinates).rgba;
            let level1 = sample_level_bilinear(&cube, 1, &coordinates).rgba;
            let expected: [f64; 4] = std::array::from_fn(|c| 0.5 * (level0[c] + level1[c]));
            let got = sample_cube_trilinear(&cube, direction, 0.5);
            assert!(close(got, expected, 1e-14));
            // Beyond the last level the sample is the last level's (1×1) value.
            let last = sample_cube_trilinear(&cube, direction, 99.0);
            let q = cube.levels.len() - 1;
            assert!(close(
                last,
                sample_level_bilinear(&cube, q, &coordinates).rgba,
                0.0
            ));
        }
        // Independent bilinear check of level 1 at an interior point of +Z.
        let n1 = 8usize;
        let (u, v) = (3.25f64, 5.75f64); // level-1 texel coordinates
        let direction = CubeFace::PositiveZ.direction(2.0 * u / 8.0 - 1.0, 2.0 * v / 8.0 - 1.0);
        let texels = &cube.levels[1][CubeFace::PositiveZ.index()];
        let at = |i: usize, j: usize| texels[j * n1 + i].map(f64::from);
        let (a, b) = (u - 0.5 - 2.0, v - 0.5 - 5.0);
        let expected: [f64; 4] = std::array::from_fn(|c| {
            (1.0 - a) * (1.0 - b) * at(2, 5)[c]
                + a * (1.0 - b) * at(3, 5)[c]
                + (1.0 - a) * b * at(2, 6)[c]
                + a * b * at(3, 6)[c]
        });
        let got = sample_level_bilinear(&cube, 1, &select_face(direction)).rgba;
        assert!(close(got, expected, 1e-14));
    }

    #[test]
    fn sampling_exactly_on_a_face_edge_reads_both_faces_border_texels() {
        let mut rng = Pcg64::seed_from_u64(4);
        let size = 8u32;
        let n = size as usize;
        let mut cube = random_cube(&mut rng, size);
        let border = [0.3f32, 0.6, 0.9, 0.8];
        // The +X column s = 0 and the +Z column s = 1 meet along the edge x = z > 0.
        for j in 0..n {
            cube.levels[0][CubeFace::PositiveX.index()][j * n] = border;
            cube.levels[0][CubeFace::PositiveZ.index()][j * n + n - 1] = border;
        }
        let expected = border.map(f64::from);
        for y in [-0.5, -0.1, 0.0, 0.3, 0.6] {
            // On the edge: a tie, +Z selected, s = 1; the footprint's other half is +X's border.
            let on_edge = DVec3::new(1.0, y, 1.0);
            assert_eq!(major_face(on_edge), CubeFace::PositiveZ);
            let sample = sample_cube(&cube, on_edge, 0.0);
            assert!(close(sample.rgba, expected, 1e-7), "{y}: {sample:?}");
            // And the filter is continuous across the edge: just inside either face gives
            // (nearly) the same value.
            for z in [1.0 - 1e-9, 1.0 + 1e-9] {
                let near = sample_cube_trilinear(&cube, DVec3::new(1.0, y, z), 0.0);
                assert!(close(near, expected, 1e-7));
            }
        }
    }

    #[test]
    fn corner_footprints_are_reported_and_average_the_three_texels() {
        let size = 4u32;
        let mut cube = CubeMap::uniform(size, [0.0; 4]);
        let n = size as usize;
        // The corner x = y = z > 0: +X texel (s=0,t=0), +Y texel (s=1,t=1), +Z texel (s=1,t=0).
        cube.levels[0][CubeFace::PositiveX.index()][0] = [0.3, 0.0, 0.0, 0.3];
        cube.levels[0][CubeFace::PositiveY.index()][(n - 1) * n + n - 1] = [0.0, 0.6, 0.0, 0.6];
        cube.levels[0][CubeFace::PositiveZ.index()][n - 1] = [0.0, 0.0, 0.9, 0.9];
        let sample = sample_cube(&cube, DVec3::ONE, 0.0);
        assert!(sample.corner);
        // Exactly at the corner each of the four footprint texels weighs ¼; the corner texel is
        // the average of the three, so the result is their average.
        assert!(close(sample.rgba, [0.1, 0.2, 0.3, 0.6], 1e-7), "{sample:?}");
        // Away from corners no corner is reported, nor where the three texels agree (the spec
        // then fixes the result).
        assert!(!sample_cube(&cube, DVec3::new(0.1, 0.2, 1.0), 0.0).corner);
        assert!(!sample_cube(&CubeMap::uniform(4, [0.5; 4]), DVec3::ONE, 0.0).corner);
    }

    #[test]
    fn lod_from_known_derivatives_on_positive_z() {
        let size = 64u32;
        let levels = CubeMap::full_chain_levels(size);
        for k in 0..6 {
            // At the face centre s = ½(rx/rz + 1) so ∂s/∂x = ½ ∂rx/∂x: ∂rx = 2·2^k/size gives
            // ∂s/∂x = 2^k/size, ρ = 2^k, λ = k.
            let d = 2.0 * 2f64.powi(k) / f64::from(size);
            let lambda = cube_lod(size, levels, DVec3::Z, DVec3::new(d, 0.0, 0.0), DVec3::ZERO);
            assert!((lambda - f64::from(k)).abs() < 1e-12, "{k}: {lambda}");
            // The same along screen y through tc = −ry with |rc| = 4 (∂t = ½·∂tc/4), and the
            // larger of the two screen axes winning (ρ = max(ρx, ρy)).
            let lambda = cube_lod(
                size,
                levels,
                DVec3::Z * 4.0,
                DVec3::new(0.5 * d, 0.0, 0.0),
                DVec3::new(0.0, -4.0 * d, 0.0),
            );
            assert!((lambda - f64::from(k)).abs() < 1e-12, "{k}: {lambda}");
        }
        // Off centre the major axis' derivative enters: r = (0.5, 0, 1), ∂r = (0, 0, δ) gives
        // ∂s = ½(0·1 − 0.5·δ)/1 = −δ/4.
        let delta = 0.25;
        let lambda = cube_lod(
            size,
            levels,
            DVec3::new(0.5, 0.0, 1.0),
            DVec3::new(0.0, 0.0, delta),
            DVec3::ZERO,
        );
        assert!((lambda - (f64::from(size) * delta / 4.0).log2()).abs() < 1e-12);
        // Clamping: magnification gives 0, huge footprints the last level.
        assert_eq!(
            cube_lod(size, levels, DVec3::Z, DVec3::X * 1e-6, DVec3::ZERO),
            0.0
        );
        assert_eq!(
            cube_lod(size, levels, DVec3::Z, DVec3::X * 1e6, DVec3::ZERO),
            6.0
        );
        assert_eq!(
            cube_lod(size, levels, DVec3::Z, DVec3::ZERO, DVec3::ZERO),
            0.0
        );
    }

    #[test]
    fn piecewise_linear_log2_is_exact_at_powers_of_two_and_low_between() {
        let approximate = LodLog2::PiecewiseLinearOfSquare;
        for k in -3..8 {
            let rho = 2f64.powi(k);
            assert_eq!(approximate.log2_from_square(rho * rho), f64::from(k));
        }
        // ρ² = 1.5590 (ρ = 2^0.32035): ½(0 + 1.5590 − 1) = 0.2795, as lavapipe gave.
        let rho = 2f64.powf(0.32035);
        assert!((approximate.log2_from_square(rho * rho) - 0.27950).abs() < 1e-4);
        for x in [1.1, 1.5, 1.9, 3.0, 100.0] {
            let error = LodLog2::Exact.log2_from_square(x) - approximate.log2_from_square(x);
            assert!((0.0..0.044).contains(&error), "{x}: {error}");
        }
    }

    #[test]
    fn face_derivatives_match_finite_differences_on_every_face() {
        let mut rng = Pcg64::seed_from_u64(5);
        for _ in 0..2000 {
            let direction = DVec3::new(
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
            );
            let d = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let coordinates = select_face(direction);
            if coordinates.major < 0.2 {
                continue;
            }
            let h = 1e-6;
            let plus = face_coordinates_on(coordinates.face, direction + h * d);
            let minus = face_coordinates_on(coordinates.face, direction - h * d);
            let (ds, dt) = face_derivatives(&coordinates, d);
            let fd_s = (plus.s - minus.s) / (2.0 * h);
            let fd_t = (plus.t - minus.t) / (2.0 * h);
            assert!(
                (ds - fd_s).abs() < 1e-6 * (1.0 + ds.abs()),
                "{coordinates:?}"
            );
            assert!(
                (dt - fd_t).abs() < 1e-6 * (1.0 + dt.abs()),
                "{coordinates:?}"
            );
        }
    }

    /// Random derivative pairs (coarse-like and fine-like) around `direction`.
    fn random_derivatives(rng: &mut Pcg64, scale: f64) -> [(DVec3, DVec3); 2] {
        let mut vector = || {
            DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ) * scale
        };
        let (ddx, ddy) = (vector(), vector());
        let (ex, ey) = (vector() * 0.1, vector() * 0.1);
        [(ddx, ddy), (ddx + ex, ddy + ey)]
    }

    #[test]
    fn lod_range_holds_the_exact_and_lavapipe_lods_and_has_the_spec_width() {
        let mut rng = Pcg64::seed_from_u64(6);
        let size = 16u32;
        let levels = CubeMap::full_chain_levels(size);
        let precision = FilterPrecision {
            sub_texel_bits: 8,
            mipmap_bits: 4,
        };
        for _ in 0..2000 {
            let direction = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let scale = rng.gen_range(0.001..0.5);
            let derivatives = random_derivatives(&mut rng, scale);
            let face = major_face(direction);
            let range =
                cube_lod_range_on_face(face, size, levels, direction, &derivatives, precision);
            assert!(range[0] <= range[1]);
            for (ddx, ddy) in derivatives {
                for log2 in [LodLog2::Exact, LodLog2::PiecewiseLinearOfSquare] {
                    let lambda = cube_lod_on_face(face, size, levels, direction, ddx, ddy, log2);
                    assert!(
                        range[0] <= lambda && lambda <= range[1],
                        "{log2:?}: {lambda} outside {range:?}"
                    );
                }
            }
        }
        // One screen axis moving s only, at +Z's centre: ρ = m_ux exactly, so the range is
        // [log2 m_ux, log2 √2·m_ux] widened by 2·2^-4 on each side.
        let d = 2.0 * 4.0 / f64::from(size); // ∂s/∂x = 4/size, m_ux = 4
        let range = cube_lod_range_on_face(
            CubeFace::PositiveZ,
            size,
            levels,
            DVec3::Z,
            &[(DVec3::X * d, DVec3::ZERO)],
            precision,
        );
        assert!((range[0] - (2.0 - 0.125)).abs() < 1e-12, "{range:?}");
        assert!((range[1] - (2.5 + 0.125)).abs() < 1e-12, "{range:?}");
        // Clamped to [0, q].
        let range = cube_lod_range_on_face(
            CubeFace::PositiveZ,
            size,
            levels,
            DVec3::Z,
            &[(DVec3::X * 1e3, DVec3::ZERO)],
            precision,
        );
        assert_eq!(range, [f64::from(levels - 1); 2]);
    }

    #[test]
    fn bounds_of_a_uniform_cube_are_its_texel() {
        let mut rng = Pcg64::seed_from_u64(7);
        let texel = [0.25f32, 0.5, 0.125, 0.75];
        let cube = CubeMap::uniform(8, texel);
        for _ in 0..200 {
            let direction = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let lo = rng.gen_range(-1.0..4.0);
            let range = [lo, lo + rng.gen_range(0.0..2.0)];
            let bounds = sample_cube_bounds(&cube, direction, range, FilterPrecision::SPEC_MINIMUM);
            for (bound, value) in bounds.bounds.iter().zip(texel) {
                assert!((bound[0] - f64::from(value)).abs() < 1e-12, "{bounds:?}");
                assert!((bound[1] - f64::from(value)).abs() < 1e-12, "{bounds:?}");
            }
        }
    }

    /// Every value an implementation may produce, drawn by brute force: LODs across the range
    /// (the fraction snapped down or up to the mip grid), bilinear fractions snapped down or up
    /// to the sub-texel grid independently per level; each must lie in the bounds, and the
    /// bounds must be reached (no wider than the hull of the draws plus the sub-texel step's
    /// effect).
    #[test]
    fn brute_force_snapped_samples_stay_inside_the_bounds() {
        let mut rng = Pcg64::seed_from_u64(8);
        let cube = random_cube(&mut rng, 16);
        let q = cube.levels.len() - 1;
        for precision in [
            FilterPrecision::SPEC_MINIMUM,
            FilterPrecision {
                sub_texel_bits: 8,
                mipmap_bits: 8,
            },
        ] {
            let sub_step = precision.sub_texel_step();
            let mip_step = precision.mipmap_step();
            let mut widest: f64 = 0.0;
            for _ in 0..300 {
                let direction = DVec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                );
                let lo = rng.gen_range(-0.5..4.5);
                let range = [lo, lo + rng.gen_range(0.0..1.5)];
                let bounds = sample_cube_bounds(&cube, direction, range, precision);
                if bounds.corner {
                    continue;
                }
                // The nominal value at every λ in the range lies inside.
                let coordinates = select_face(direction);
                let mut hull = [[f64::INFINITY, f64::NEG_INFINITY]; 4];
                let integers = (0..=q)
                    .map(|k| k as f64)
                    .filter(|k| (range[0]..=range[1]).contains(k));
                let lambdas = (0..=64)
                    .map(|k| range[0] + (range[1] - range[0]) * f64::from(k) / 64.0)
                    .chain(integers);
                for lambda in lambdas {
                    let d = lambda.clamp(0.0, q as f64);
                    let first = (d.floor() as usize).min(q);
                    let second = (first + 1).min(q);
                    let delta_exact = d - first as f64;
                    for delta in [
                        delta_exact,
                        (delta_exact / mip_step).floor() * mip_step,
                        ((delta_exact / mip_step).ceil() * mip_step).min(1.0),
                    ] {
                        // Snapped λ must stay inside the range the caller widened for it.
                        let snapped = first as f64 + delta;
                        if delta != delta_exact && !(range[0]..=range[1]).contains(&snapped) {
                            continue;
                        }
                        let snap = |fraction: f64, up: bool| {
                            let grid = fraction / sub_step;
                            (if up { grid.ceil() } else { grid.floor() }) * sub_step
                        };
                        let a = Footprint::new(&cube, first, &coordinates);
                        let b = Footprint::new(&cube, second, &coordinates);
                        let ups: [bool; 4] = std::array::from_fn(|_| rng.gen_bool(0.5));
                        let va = a.filter(snap(a.alpha, ups[0]), snap(a.beta, ups[1])).rgba;
                        let vb = b.filter(snap(b.alpha, ups[2]), snap(b.beta, ups[3])).rgba;
                        for c in 0..4 {
                            let value = (1.0 - delta) * va[c] + delta * vb[c];
                            let [low, high] = bounds.bounds[c];
                            assert!(
                                low - 1e-12 <= value && value <= high + 1e-12,
                                "{precision:?} λ {lambda} δ {delta} channel {c}: {value} \
                                 outside {:?}",
                                bounds.bounds[c]
                            );
                            hull[c] = [hull[c][0].min(value), hull[c][1].max(value)];
                        }
                    }
                }
                for ([low, high], [drawn_low, drawn_high]) in bounds.bounds.into_iter().zip(hull) {
                    widest = widest.max(high - low);
                    // Tight: the draws span all but the part of each end that only unlucky
                    // snapping reaches (at most 2·step·spread ≤ 2·step with texels in [0, 1]).
                    let slack = 2.0 * sub_step + 1e-12;
                    assert!(
                        low >= drawn_low - slack && high <= drawn_high + slack,
                        "{precision:?} {range:?}: bounds [{low}, {high}], drawn \
                         [{drawn_low}, {drawn_high}]"
                    );
                }
            }
            assert!(widest > 0.0);
        }
    }

    #[test]
    fn competing_faces_detects_near_ties() {
        assert_eq!(
            competing_faces(DVec3::new(0.1, 0.2, 1.0), 1e-4),
            vec![CubeFace::PositiveZ]
        );
        assert_eq!(
            competing_faces(DVec3::new(-1.0, 0.2, 1.0 - 1e-6), 1e-4),
            vec![CubeFace::NegativeX, CubeFace::PositiveZ]
        );
    }
}
