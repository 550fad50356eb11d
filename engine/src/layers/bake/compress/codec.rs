//! The arithmetic of compressed cube maps, without files: texels as ordered integers, MIP levels
//! as residuals from the decimated finest level ([`Planes::intra`]), samples as differences from
//! their predecessor ([`Planes::delta_from`]), and the byte planes handed to zstd ([`pack`]).
//!
//! Every step is exact integer arithmetic on `i32` (wrapping), or f32 arithmetic whose order is
//! written out here ([`decimate`]), so a decoder reproduces the encoder's predictions bit for bit
//! and the lossless setting returns the very bits it was given.

use crate::cubemap::CubeMap;

/// The most low mantissa bits a lossy setting may drop (f32 has 23): 20 keeps 3.
pub const MAX_DROPPED_MANTISSA_BITS: u32 = 20;

/// An f32 as an integer that orders like the float (−0.0 just below +0.0): the bit pattern,
/// with the magnitude bits of negative values flipped. Its own inverse is [`from_ordered`].
pub fn ordered(value: f32) -> i32 {
    let bits = value.to_bits() as i32;
    bits ^ ((bits >> 31) & 0x7fff_ffff)
}

/// The f32 whose [`ordered`] integer is `integer` (any `i32` is one f32's, NaNs included).
pub fn from_ordered(integer: i32) -> f32 {
    f32::from_bits((integer ^ ((integer >> 31) & 0x7fff_ffff)) as u32)
}

/// `integer` with its `dropped` low bits rounded away (to nearest, ties up): the lossy step.
/// Identity when `dropped` is 0.
fn quantize(integer: i32, dropped: u32) -> i32 {
    if dropped == 0 {
        return integer;
    }
    ((i64::from(integer) + (1 << (dropped - 1))) >> dropped) as i32
}

/// The integer a quantized value stands for (inverse of [`quantize`] up to the dropped bits).
fn dequantize(quantized: i32, dropped: u32) -> i32 {
    quantized.wrapping_shl(dropped)
}

/// The f32 a texel value decodes to once `dropped` mantissa bits are dropped: what a bake
/// compressed with that setting reads back. Identity when `dropped` is 0.
pub fn lossy_value(value: f32, dropped: u32) -> f32 {
    from_ordered(dequantize(quantize(ordered(value), dropped), dropped))
}

/// The level below `face` (edge `edge`, row-major RGBA): each texel the mean of a 2×2 block,
/// computed as `((a + b) + (c + d)) · 0.25` per channel in f32 with `a b` the block's top row.
/// The order is part of the format: encoder and decoder predict with this very function.
pub fn decimate(face: &[[f32; 4]], edge: usize) -> Vec<[f32; 4]> {
    let half = edge / 2;
    (0..half * half)
        .map(|i| {
            let (x, y) = (2 * (i % half), 2 * (i / half));
            let [a, b, c, d] = [
                face[y * edge + x],
                face[y * edge + x + 1],
                face[(y + 1) * edge + x],
                face[(y + 1) * edge + x + 1],
            ];
            std::array::from_fn(|k| ((a[k] + b[k]) + (c[k] + d[k])) * 0.25)
        })
        .collect()
}

/// One cube map as integers: per level (finest first), per face (Vulkan order), per channel
/// (R G B A), the face's texels row by row. What each integer means depends on the stage: see
/// [`Planes::intra`] and [`Planes::delta_from`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Planes {
    /// The cube map's edge length.
    pub size: u32,
    /// The integers, `4 · 6 · Σ_l (size >> l)²` of them.
    pub values: Vec<i32>,
}

/// The number of integers of a cube map of edge `size` with its full mip chain, `None` past
/// `usize`.
pub fn plane_len(size: u32) -> Option<usize> {
    (0..CubeMap::full_chain_levels(size)).try_fold(0usize, |sum, level| {
        let edge = (size >> level).max(1) as usize;
        sum.checked_add(edge.checked_mul(edge)?.checked_mul(24)?)
    })
}

/// Appends `face`'s texels to `values` channel by channel, each through `map`.
fn push_face(values: &mut Vec<i32>, face: &[[f32; 4]], map: impl Fn(usize, usize) -> i32) {
    for channel in 0..4 {
        values.extend((0..face.len()).map(|texel| map(texel, channel)));
    }
}

impl Planes {
    /// The intra-coded integers of `cube` (a full chain) with `dropped` low mantissa bits
    /// dropped: level 0 is each value's quantized [`ordered`] integer; level l ≥ 1 is the
    /// difference (wrapping) between its quantized integer and that of the matching texel of
    /// level 0, as decoded, decimated l times ([`decimate`]): the PEM paper's residuals from the
    /// decimated finest level.
    pub fn intra(cube: &CubeMap, dropped: u32) -> Planes {
        let mut values = Vec::with_capacity(plane_len(cube.size).unwrap_or(0));
        let code = |v: f32| quantize(ordered(v), dropped);
        let mut predicted: [Vec<[f32; 4]>; 6] = std::array::from_fn(|face| {
            cube.levels[0][face]
                .iter()
                .map(|t| t.map(|v| lossy_value(v, dropped)))
                .collect()
        });
        for face in &cube.levels[0] {
            push_face(&mut values, face, |texel, channel| {
                code(face[texel][channel])
            });
        }
        let mut edge = cube.size as usize;
        for faces in &cube.levels[1..] {
            predicted = std::array::from_fn(|face| decimate(&predicted[face], edge));
            edge /= 2;
            for (face, prediction) in faces.iter().zip(&predicted) {
                push_face(&mut values, face, |texel, channel| {
                    code(face[texel][channel]).wrapping_sub(code(prediction[texel][channel]))
                });
            }
        }
        Planes {
            size: cube.size,
            values,
        }
    }

    /// The cube map these intra-coded integers ([`Planes::intra`]) stand for, `dropped` being
    /// the setting they were coded with. `None` when there are not [`plane_len`] of them.
    pub fn to_cube_map(&self, dropped: u32) -> Option<CubeMap> {
        if Some(self.values.len()) != plane_len(self.size) {
            return None;
        }
        let decode = |integer: i32| from_ordered(dequantize(integer, dropped));
        let mut rest = self.values.as_slice();
        let mut take_face = |edge: usize, value: &dyn Fn(usize, usize, i32) -> f32| {
            let (face, tail) = rest.split_at(4 * edge * edge);
            rest = tail;
            let texels = edge * edge;
            (0..texels)
                .map(|t| std::array::from_fn(|c| value(t, c, face[c * texels + t])))
                .collect::<Vec<[f32; 4]>>()
        };
        let size = self.size as usize;
        let finest: [Vec<[f32; 4]>; 6] =
            std::array::from_fn(|_| take_face(size, &|_, _, integer| decode(integer)));
        let mut predicted = finest.clone();
        let mut levels = vec![finest];
        let mut edge = size;
        while edge > 1 {
            predicted = std::array::from_fn(|face| decimate(&predicted[face], edge));
            edge /= 2;
            let level: [Vec<[f32; 4]>; 6] = std::array::from_fn(|face| {
                take_face(edge, &|t, c, residual| {
                    let base = quantize(ordered(predicted[face][t][c]), dropped);
                    decode(base.wrapping_add(residual))
                })
            });
            levels.push(level);
        }
        Some(CubeMap {
            size: self.size,
            levels,
        })
    }

    /// These integers minus `reference`'s (wrapping), value by value: a sample coded against
    /// its predecessor. `None` when the two are of different sizes.
    pub fn delta_from(&self, reference: &Planes) -> Option<Planes> {
        self.zip_with(reference, i32::wrapping_sub)
    }

    /// The integers whose [`Planes::delta_from`] `reference` is `self`.
    pub fn add_reference(&self, reference: &Planes) -> Option<Planes> {
        self.zip_with(reference, i32::wrapping_add)
    }

    fn zip_with(&self, other: &Planes, f: impl Fn(i32, i32) -> i32) -> Option<Planes> {
        (self.size == other.size && self.values.len() == other.values.len()).then(|| Planes {
            size: self.size,
            values: self
                .values
                .iter()
                .zip(&other.values)
                .map(|(&a, &b)| f(a, b))
                .collect(),
        })
    }
}

/// The bytes zstd compresses: each integer zigzag-coded (small magnitudes become small
/// unsigned numbers), then split into four byte planes (every integer's low byte first, then
/// every second byte, …), so the mostly-zero high bytes of small residuals lie together.
pub fn pack(values: &[i32]) -> Vec<u8> {
    let n = values.len();
    let mut bytes = vec![0u8; 4 * n];
    for (i, &value) in values.iter().enumerate() {
        let zigzag = ((value << 1) ^ (value >> 31)) as u32;
        for (plane, byte) in zigzag.to_le_bytes().into_iter().enumerate() {
            bytes[plane * n + i] = byte;
        }
    }
    bytes
}

/// The integers [`pack`] made `bytes` from; `None` unless the length is a multiple of 4.
pub fn unpack(bytes: &[u8]) -> Option<Vec<i32>> {
    if !bytes.len().is_multiple_of(4) {
        return None;
    }
    let n = bytes.len() / 4;
    Some(
        (0..n)
            .map(|i| {
                let zigzag = u32::from_le_bytes([
                    bytes[i],
                    bytes[n + i],
                    bytes[2 * n + i],
                    bytes[3 * n + i],
                ]);
                ((zigzag >> 1) as i32) ^ -((zigzag & 1) as i32)
            })
            .collect(),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A cube map of a smooth premultiplied pattern that drifts with `t` (a viewpoint sample's
    /// parameter), plus noise in every level, with the odd value a coder may trip on: −0.0,
    /// subnormals, negative colour, α exactly 0 and 1. Levels are not decimations of level 0.
    pub(crate) fn drifting_cube(rng: &mut Pcg64, size: u32, t: f32) -> CubeMap {
        let levels = (0..CubeMap::full_chain_levels(size))
            .map(|level| {
                let edge = (size >> level).max(1) as usize;
                std::array::from_fn(|face| {
                    (0..edge * edge)
                        .map(|i| {
                            let (x, y) = ((i % edge) as f32, (i / edge) as f32);
                            let alpha: f32 = match i % 7 {
                                0 => 0.0,
                                1 => 1.0,
                                _ => 0.5 + 0.4 * (0.3 * x + 0.1 * t).sin(),
                            };
                            let base = 1.0 + (0.2 * y + face as f32 + 0.05 * t).cos();
                            let noise = rng.gen_range(-1e-3..1e-3f32);
                            let mut texel = [
                                alpha * (base + noise),
                                alpha * (2.0 * base - noise),
                                alpha * (0.5 * base) - 0.01,
                                alpha,
                            ];
                            if i % 11 == 3 {
                                texel[0] = -0.0;
                                texel[1] = f32::MIN_POSITIVE / 8.0;
                            }
                            texel
                        })
                        .collect()
                })
            })
            .collect();
        CubeMap { size, levels }
    }

    /// Bit patterns of every value of `cube`, level by level.
    pub(crate) fn bits(cube: &CubeMap) -> Vec<u32> {
        cube.levels
            .iter()
            .flatten()
            .flatten()
            .flatten()
            .map(|v| v.to_bits())
            .collect()
    }

    #[test]
    fn ordered_integers_order_like_the_floats_and_invert_exactly() {
        let mut rng = Pcg64::seed_from_u64(29);
        let mut values: Vec<f32> = (0..20_000)
            .map(|_| f32::from_bits(rng.r#gen::<u32>()))
            .filter(|v| !v.is_nan())
            .chain([0.0, -0.0, f32::MIN_POSITIVE / 2.0, -f32::MAX, f32::MAX])
            .collect();
        for &v in &values {
            assert_eq!(from_ordered(ordered(v)).to_bits(), v.to_bits());
        }
        // Sorted by total order (−0.0 below +0.0), the integers increase strictly.
        values.sort_by(f32::total_cmp);
        values.dedup_by(|a, b| a.to_bits() == b.to_bits());
        assert!(values.windows(2).all(|w| ordered(w[0]) < ordered(w[1])));
    }

    #[test]
    fn mip_residuals_round_trip_bit_exactly() {
        let mut rng = Pcg64::seed_from_u64(7);
        for size in [1, 2, 4, 16] {
            let cube = drifting_cube(&mut rng, size, 0.0);
            let planes = Planes::intra(&cube, 0);
            assert_eq!(Some(planes.values.len()), plane_len(size));
            let decoded = planes.to_cube_map(0).expect("the right number of values");
            assert_eq!(bits(&decoded), bits(&cube), "size {size}");
        }
    }

    #[test]
    fn a_chain_decimated_from_level0_leaves_zero_residuals() {
        // The paper's scheme predicts every level by decimating level 0: a chain that is exactly
        // that decimation codes to zeros beyond level 0. Texels of whole multiples of 1/4 below
        // 64 average exactly in f32 in any order, so the cube map's own box filter (an
        // independent implementation) makes the very chain the coder predicts.
        let mut rng = Pcg64::seed_from_u64(3);
        let faces: [Vec<[f32; 4]>; 6] = std::array::from_fn(|_| {
            (0..16 * 16)
                .map(|_| {
                    let alpha = f32::from(rng.gen_range(0..=4u8)) / 4.0;
                    let mut colour = || f32::from(rng.gen_range(0..=255u8)) / 4.0 * alpha;
                    [colour(), colour(), colour(), alpha]
                })
                .collect()
        });
        let cube = CubeMap::from_level0(16, faces);
        let planes = Planes::intra(&cube, 0);
        let level0 = 24 * 16 * 16;
        assert!(planes.values[level0..].iter().all(|&r| r == 0));
        assert!(planes.values[..level0].iter().any(|&v| v != 0));
        // And a chain that is not the decimation leaves residuals.
        let noisy = drifting_cube(&mut rng, 16, 1.0);
        assert!(
            Planes::intra(&noisy, 0).values[level0..]
                .iter()
                .any(|&r| r != 0)
        );
    }

    #[test]
    fn differences_between_samples_round_trip_bit_exactly() {
        let mut rng = Pcg64::seed_from_u64(11);
        let maps: Vec<CubeMap> = (0..5)
            .map(|t| drifting_cube(&mut rng, 8, t as f32))
            .collect();
        let intra: Vec<Planes> = maps.iter().map(|m| Planes::intra(m, 0)).collect();
        let mut previous = intra[0].clone();
        for (map, planes) in maps.iter().zip(&intra).skip(1) {
            let delta = planes.delta_from(&previous).unwrap();
            let packed = pack(&delta.values);
            let unpacked = Planes {
                size: 8,
                values: unpack(&packed).unwrap(),
            };
            let restored = unpacked.add_reference(&previous).unwrap();
            assert_eq!(bits(&restored.to_cube_map(0).unwrap()), bits(map));
            previous = restored;
        }
        assert!(unpack(&[1, 2, 3]).is_none());
        assert!(Planes::intra(&maps[0], 0).to_cube_map(0).is_some());
        let short = Planes {
            size: 8,
            values: vec![0; 5],
        };
        assert!(short.to_cube_map(0).is_none());
        assert!(short.delta_from(&intra[0]).is_none());
    }

    #[test]
    fn dropped_bits_bound_the_relative_error() {
        let mut rng = Pcg64::seed_from_u64(5);
        let cube = drifting_cube(&mut rng, 8, 2.0);
        for dropped in [1, 8, 12, 16, MAX_DROPPED_MANTISSA_BITS] {
            let decoded = Planes::intra(&cube, dropped).to_cube_map(dropped).unwrap();
            let pairs = bits(&cube).into_iter().zip(bits(&decoded));
            for (source, value) in pairs.map(|(a, b)| (f32::from_bits(a), f32::from_bits(b))) {
                assert_eq!(value.to_bits(), lossy_value(source, dropped).to_bits());
                // Rounding to 24 − d significant bits: half a unit in the last kept place.
                let bound = source.abs() * 2f32.powi(dropped as i32 - 24) + f32::MIN_POSITIVE;
                assert!(
                    (value - source).abs() <= bound,
                    "{source} → {value} with {dropped} bits dropped"
                );
                assert!(value.is_finite());
            }
        }
        // α stays within [0, 1].
        assert_eq!(lossy_value(1.0, 16), 1.0);
        assert_eq!(lossy_value(0.0, 16), 0.0);
        assert!(lossy_value(0.999_999_9, 20) <= 1.0);
    }
}
