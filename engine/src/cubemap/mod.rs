//! Cube maps of premultiplied RGBA texels with full mip chains: the type the layered EMs are made
//! of ([`CubeMap`]), its faces in Vulkan's order and conventions ([`face`]), an f64 model of how
//! Vulkan samples it ([`sampling`]), and the one validator every reader of cube maps uses
//! ([`CubeMap::validate`]). Below both `layers/` (which makes and stores cube maps) and `render/`
//! (which uploads and samples them), so neither reaches into the other for them.

pub mod face;
pub mod sampling;

pub use face::CubeFace;

/// How far outside [0, 1] a texel's α may be (rounding in a solver) before a cube map is rejected.
pub const ALPHA_TOLERANCE: f32 = 1e-4;

/// A cube map of premultiplied RGBA (α·rgb, α) texels with a full mip chain.
///
/// Faces follow Vulkan's order (+X, −X, +Y, −Y, +Z, −Z) and its face-coordinate conventions
/// (Vulkan spec, "Cube Map Face Selection"); texels are row-major with row 0 at t = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeMap {
    /// Edge length of a level-0 face in texels (a power of two, ≥ 1).
    pub size: u32,
    /// `levels[l][face]` holds `(size >> l)²` texels; `levels.len() == log2(size) + 1`.
    pub levels: Vec<[Vec<[f32; 4]>; 6]>,
}

/// What is wrong with one texel.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum TexelProblem {
    /// A channel is NaN or infinite.
    #[error("channel {} is {value}", ['R', 'G', 'B', 'A'][*channel])]
    NonFinite {
        /// 0 = R … 3 = A.
        channel: usize,
        /// The value found.
        value: f32,
    },
    /// α is outside [0, 1] by more than [`ALPHA_TOLERANCE`].
    #[error("has alpha {value}, outside [0, 1] (tolerance {ALPHA_TOLERANCE})")]
    AlphaOutOfRange {
        /// The α found.
        value: f32,
    },
}

/// Why a cube map is not a valid layered-EM cube map; every variant says where.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CubeMapError {
    /// The level-0 edge is not a power of two ≥ 1.
    #[error("face size {size} is not a power of two ≥ 1")]
    NotPowerOfTwo {
        /// The size found.
        size: u32,
    },
    /// The level-0 edge differs from the one required (every layer of a frame or bake shares one).
    #[error("face size is {found}, but every cube map here must be {expected}×{expected}")]
    WrongSize {
        /// The size found.
        found: u32,
        /// The size required.
        expected: u32,
    },
    /// A level of the full chain is missing.
    #[error("mip level {level} is missing: a {size}² cube map needs all {levels} mip levels")]
    MissingLevel {
        /// The first missing level.
        level: usize,
        /// The face size.
        size: u32,
        /// Levels of the full chain.
        levels: u32,
    },
    /// There are more levels than the full chain has.
    #[error("mip level {level} is beyond the {levels} mip levels of a {size}² cube map")]
    ExtraLevel {
        /// The first level too many.
        level: usize,
        /// The face size.
        size: u32,
        /// Levels of the full chain.
        levels: u32,
    },
    /// A face of a level has the wrong number of texels.
    #[error("level {level} face {face:?} has {found} texels, expected {edge}×{edge}")]
    TexelCount {
        /// The level.
        level: usize,
        /// The face.
        face: CubeFace,
        /// Texels found.
        found: usize,
        /// The level's edge length.
        edge: u32,
    },
    /// A texel is not finite or its α is out of range.
    #[error("level {level} face {face:?} texel ({x}, {y}) {problem}")]
    Texel {
        /// The level.
        level: usize,
        /// The face.
        face: CubeFace,
        /// Column.
        x: usize,
        /// Row.
        y: usize,
        /// What is wrong.
        problem: TexelProblem,
    },
}

/// Checks one face's texels (row-major, `edge` per row): every channel finite, α within
/// [0, 1] ± [`ALPHA_TOLERANCE`]. Returns the first bad texel's column, row and problem.
pub fn check_face_texels(
    texels: &[[f32; 4]],
    edge: usize,
) -> Result<(), (usize, usize, TexelProblem)> {
    for (index, texel) in texels.iter().enumerate() {
        let at = (index % edge.max(1), index / edge.max(1));
        if let Some(channel) = texel.iter().position(|v| !v.is_finite()) {
            let value = texel[channel];
            return Err((at.0, at.1, TexelProblem::NonFinite { channel, value }));
        }
        let alpha = texel[3];
        if !(-ALPHA_TOLERANCE..=1.0 + ALPHA_TOLERANCE).contains(&alpha) {
            return Err((at.0, at.1, TexelProblem::AlphaOutOfRange { value: alpha }));
        }
    }
    Ok(())
}

impl CubeMap {
    /// Number of mip levels of a full chain for a face of `size` texels.
    pub fn full_chain_levels(size: u32) -> u32 {
        32 - size.max(1).leading_zeros()
    }

    /// Edge length of mip level `level`.
    pub fn level_size(&self, level: usize) -> u32 {
        (self.size >> level).max(1)
    }

    /// Whether every texel of every level is zero: a layer that adds nothing to a frame.
    pub fn is_all_zero(&self) -> bool {
        self.levels
            .iter()
            .flatten()
            .flatten()
            .all(|t| *t == [0.0; 4])
    }

    /// The one check every consumer of cube maps applies: a power-of-two size (equal to
    /// `expected_size` when given), exactly the full mip chain, `(size >> l)²` texels per face of
    /// level l, and every texel finite with α in [0, 1] (tolerance [`ALPHA_TOLERANCE`]), as
    /// premultiplied compositing needs. Reports the first problem found, located.
    pub fn validate(&self, expected_size: Option<u32>) -> Result<(), CubeMapError> {
        let size = self.size;
        if let Some(expected) = expected_size.filter(|&e| e != size) {
            return Err(CubeMapError::WrongSize {
                found: size,
                expected,
            });
        }
        if !size.is_power_of_two() {
            return Err(CubeMapError::NotPowerOfTwo { size });
        }
        let levels = Self::full_chain_levels(size);
        if self.levels.len() > levels as usize {
            return Err(CubeMapError::ExtraLevel {
                level: levels as usize,
                size,
                levels,
            });
        }
        for level in 0..levels as usize {
            let Some(faces) = self.levels.get(level) else {
                return Err(CubeMapError::MissingLevel {
                    level,
                    size,
                    levels,
                });
            };
            let edge = self.level_size(level);
            for (face, texels) in CubeFace::ALL.into_iter().zip(faces) {
                if texels.len() != (edge as usize).pow(2) {
                    return Err(CubeMapError::TexelCount {
                        level,
                        face,
                        found: texels.len(),
                        edge,
                    });
                }
                check_face_texels(texels, edge as usize).map_err(|(x, y, problem)| {
                    CubeMapError::Texel {
                        level,
                        face,
                        x,
                        y,
                        problem,
                    }
                })?;
            }
        }
        Ok(())
    }

    /// A cube map whose every texel of every level is `texel`.
    pub fn uniform(size: u32, texel: [f32; 4]) -> Self {
        let levels = (0..Self::full_chain_levels(size))
            .map(|l| {
                let n = ((size >> l).max(1) as usize).pow(2);
                std::array::from_fn(|_| vec![texel; n])
            })
            .collect();
        CubeMap { size, levels }
    }

    /// A cube map from its level-0 faces, with the rest of the chain made by 2×2 box filtering.
    /// Averaging premultiplied texels is exact (filtering commutes with premultiplication).
    pub fn from_level0(size: u32, faces: [Vec<[f32; 4]>; 6]) -> Self {
        let mut levels = vec![faces];
        let mut edge = size as usize;
        while edge > 1 {
            let half = edge / 2;
            let previous = &levels[levels.len() - 1];
            let next: [Vec<[f32; 4]>; 6] = std::array::from_fn(|face| {
                let src = &previous[face];
                (0..half * half)
                    .map(|i| {
                        let (x, y) = (2 * (i % half), 2 * (i / half));
                        let texels = [
                            src[y * edge + x],
                            src[y * edge + x + 1],
                            src[(y + 1) * edge + x],
                            src[(y + 1) * edge + x + 1],
                        ];
                        std::array::from_fn(|c| 0.25 * texels.iter().map(|t| t[c]).sum::<f32>())
                    })
                    .collect()
            });
            levels.push(next);
            edge = half;
        }
        CubeMap { size, levels }
    }

    /// A cube map whose level-0 texel is `f(direction through the texel centre)`, mips box-filtered.
    pub fn from_fn(size: u32, f: impl Fn(glam::DVec3) -> [f32; 4]) -> Self {
        let edge = size as usize;
        let faces = std::array::from_fn(|face| {
            let face = CubeFace::ALL[face];
            (0..edge * edge)
                .map(|i| {
                    let s = ((i % edge) as f64 + 0.5) / edge as f64;
                    let t = ((i / edge) as f64 + 0.5) / edge as f64;
                    f(face.direction(2.0 * s - 1.0, 2.0 * t - 1.0))
                })
                .collect()
        });
        CubeMap::from_level0(size, faces)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_validator_locates_each_kind_of_problem() {
        let good = CubeMap::uniform(4, [0.25, 0.25, 0.25, 0.5]);
        assert_eq!(good.validate(Some(4)), Ok(()));
        assert_eq!(
            good.validate(Some(8)),
            Err(CubeMapError::WrongSize {
                found: 4,
                expected: 8
            })
        );
        let mut odd = good.clone();
        odd.size = 6;
        assert_eq!(
            odd.validate(None),
            Err(CubeMapError::NotPowerOfTwo { size: 6 })
        );
        let mut short = good.clone();
        short.levels.pop();
        assert_eq!(
            short.validate(None),
            Err(CubeMapError::MissingLevel {
                level: 2,
                size: 4,
                levels: 3
            })
        );
        let mut long = good.clone();
        long.levels.push(long.levels[2].clone());
        assert!(matches!(
            long.validate(None),
            Err(CubeMapError::ExtraLevel { level: 3, .. })
        ));
        let mut count = good.clone();
        count.levels[1][3].pop();
        assert!(matches!(
            count.validate(None),
            Err(CubeMapError::TexelCount {
                level: 1,
                face: CubeFace::NegativeY,
                found: 3,
                edge: 2
            })
        ));
        let mut nan = good.clone();
        nan.levels[0][4][4 * 2 + 3][1] = f32::NAN;
        let error = nan.validate(None).unwrap_err();
        assert!(
            matches!(
                error,
                CubeMapError::Texel {
                    level: 0,
                    face: CubeFace::PositiveZ,
                    x: 3,
                    y: 2,
                    problem: TexelProblem::NonFinite { channel: 1, .. }
                }
            ),
            "{error}"
        );
        assert!(error.to_string().contains("channel G is NaN"), "{error}");
        let mut alpha = good.clone();
        alpha.levels[2][0][0][3] = 1.0 + 2.0 * ALPHA_TOLERANCE;
        assert!(matches!(
            alpha.validate(None),
            Err(CubeMapError::Texel {
                problem: TexelProblem::AlphaOutOfRange { .. },
                ..
            })
        ));
        let mut within = good;
        within.levels[2][0][0][3] = 1.0 + 0.5 * ALPHA_TOLERANCE;
        assert_eq!(within.validate(None), Ok(()));
    }
}
