//! Schlick's fifth-order term `(1 − cos θ)⁵` through a 1D texture, as the PEM paper does (§5: "We
//! make use of a 1D texture map to better interpolate the fifth order polynomial"), and the
//! largest error that costs against Schlick evaluated exactly and against exact dielectric
//! Fresnel.
//!
//! The per-vertex stages run on the CPU, so the "texture" is a [`SchlickTable`] that the vertex
//! code samples exactly as a Vulkan linear sampler with clamp-to-edge addressing samples a 1D
//! `R32_SFLOAT` image: texel values stored in f32, texel centres at `(i + ½) / N`, the weight
//! `α = frac(u·N − ½)` and the two texels clamped to `[0, N − 1]` (Vulkan spec, "Texel
//! Filtering"). A GPU quantizes `α` to `subTexelPrecisionBits` (8 on lavapipe and most hardware);
//! the table keeps the exact weight (see [`SchlickTable::sample`]).
//!
//! **Where the error comes from.** Sampled at `u = cos θ`, the half texels at either end are
//! clamped: near grazing incidence the table returns `f(h/2)` for `f(0) = 1`, a first-order error
//! of about `5/(2N)`. So the coordinate is scaled and biased ([`SchlickTable::coordinate`]) to put
//! the first and last texel centres on `cos θ = 0` and `cos θ = 1`: the texels hold `f(i·h)` with
//! `h = 1/(N − 1)`, and between two of them the sampler returns the linear interpolant. For
//! `f(c) = (1 − c)⁵`, `f''(c) = 20(1 − c)³`, at most 20 (at `c = 0`), and the interpolation error
//! on `[c_i, c_i + h]` is `f''(ξ)(c − c_i)(c_i + h − c)/2 ≤ max|f''|·h²/8`, so over 0–90°
//!
//! `|T(c) − (1 − c)⁵| ≤ 20·h²/8 = 2.5/(N − 1)²` ([`SchlickTable::error_bound`]).
//!
//! `f` is convex, so on the first interval (where `f''` is largest) the error at its midpoint is
//! `f''(ξ)·h²/8` for some ξ in `[0, h]`, at least `20(1 − h)³·h²/8`: the bound is attained to a
//! factor `(1 − h)³` (0.81 at N = 16, 0.99 at N = 256; [`SchlickTable::error_attained`]).

use super::fresnel::{self, Real};
use super::path::Interface;
use crate::options::OptionError;

/// The fewest texels a table may have: two, the ends.
pub const MIN_TEXELS: u32 = 2;

/// The most texels a table may have: 4096, the least `maxImageDimension1D` Vulkan guarantees, so
/// that the table fits a 1D image on any device when the per-vertex stages move to the GPU.
pub const MAX_TEXELS: u32 = 4096;

/// How the per-vertex paths evaluate Fresnel coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FresnelModel {
    /// Mirrors: Schlick's approximation evaluated; glass: exact unpolarized dielectric Fresnel.
    /// What the reference ray tracer computes.
    #[default]
    Exact,
    /// Schlick's approximation with its fifth-order term looked up in a [`SchlickTable`] of
    /// `texels` texels (in [`MIN_TEXELS`, `MAX_TEXELS`]): mirrors get `R₀ + (1 − R₀)·T(cos θ)`
    /// per channel; glass gets the same with `R₀ = ((n − 1)/(n + 1))²` and the cosine on the
    /// air side ([`fresnel::dielectric_schlick`]).
    Table {
        /// Texels of the 1D table.
        texels: u32,
    },
}

impl FresnelModel {
    /// Checks the table's size: in [`MIN_TEXELS`, `MAX_TEXELS`].
    pub fn validate(&self) -> Result<(), OptionError> {
        match *self {
            FresnelModel::Exact => Ok(()),
            FresnelModel::Table { texels } => OptionError::require(
                (MIN_TEXELS..=MAX_TEXELS).contains(&texels),
                crate::options::names::FRESNEL,
                self.name(),
                "give a table of 2 to 4096 texels, e.g. table:64, or exact",
            ),
        }
    }

    /// The model as the front ends write it: `exact` or `table:N`.
    pub fn name(&self) -> String {
        match self {
            FresnelModel::Exact => "exact".to_owned(),
            FresnelModel::Table { texels } => format!("table:{texels}"),
        }
    }

    /// The table this model looks the fifth-order term up in (`None` for [`FresnelModel::Exact`]);
    /// an error for a size out of range.
    pub fn table(&self) -> Result<Option<SchlickTable>, OptionError> {
        self.validate()?;
        Ok(match *self {
            FresnelModel::Exact => None,
            FresnelModel::Table { texels } => Some(SchlickTable::of_size(texels)),
        })
    }
}

/// `(1 − c)⁵` tabulated at `c = i/(N − 1)`, `i = 0 … N − 1`, in f32 (a 1D `R32_SFLOAT` texture),
/// sampled with linear filtering and clamp-to-edge addressing.
#[derive(Clone, Debug, PartialEq)]
pub struct SchlickTable {
    texels: Box<[f32]>,
}

impl SchlickTable {
    /// The table of `texels` texels (in [`MIN_TEXELS`, `MAX_TEXELS`]).
    pub fn new(texels: u32) -> Result<SchlickTable, OptionError> {
        FresnelModel::Table { texels }.validate()?;
        Ok(SchlickTable::of_size(texels))
    }

    /// The table of a size already checked.
    fn of_size(texels: u32) -> SchlickTable {
        let last = f64::from(texels.max(MIN_TEXELS) - 1);
        SchlickTable {
            texels: (0..=last as u32)
                .map(|i| (1.0 - f64::from(i) / last).powi(5) as f32)
                .collect(),
        }
    }

    /// The texel values, `(1 − i/(N − 1))⁵` rounded to f32.
    pub fn texels(&self) -> &[f32] {
        &self.texels
    }

    /// The texel spacing in `cos θ`, `h = 1/(N − 1)`.
    pub fn spacing(&self) -> f64 {
        1.0 / (self.texels.len() - 1) as f64
    }

    /// The texture coordinate of `cos θ` (clamped to [0, 1]; NaN reads as 0): `(c·(N − 1) + ½)/N`,
    /// which puts `c = 0` and `c = 1` on the centres of the first and last texels.
    pub fn coordinate<R: Real>(&self, cos_theta: R) -> R {
        let cos = if cos_theta.is_nan() {
            R::ZERO
        } else {
            cos_theta.clamp(R::ZERO, R::ONE)
        };
        let n = R::of(self.texels.len() as f64);
        (cos * (n - R::ONE) + R::of(0.5)) / n
    }

    /// The table at normalized texture coordinate `u`, as a Vulkan linear sampler with
    /// clamp-to-edge addressing returns it: `i₀ = ⌊u·N − ½⌋`, `α = u·N − ½ − i₀`, both texels
    /// clamped to `[0, N − 1]`, `(1 − α)·T[i₀] + α·T[i₀ + 1]`. The weight is exact here; a GPU
    /// rounds it to `subTexelPrecisionBits` bits (b), which adds up to `max|f'|·h·2^−(b+1)`
    /// (`5h/512` for b = 8).
    pub fn sample<R: Real>(&self, u: R) -> R {
        let u = if u.is_finite() { u } else { R::ZERO };
        let x = u * R::of(self.texels.len() as f64) - R::of(0.5);
        let floor = x.to_f64().floor();
        let alpha = x - R::of(floor);
        let last = self.texels.len() as f64 - 1.0;
        let texel = |i: f64| R::of(f64::from(self.texels[i.clamp(0.0, last) as usize]));
        (R::ONE - alpha) * texel(floor) + alpha * texel(floor + 1.0)
    }

    /// `(1 − cos θ)⁵` through the table: [`SchlickTable::sample`] at
    /// [`SchlickTable::coordinate`].
    pub fn fifth_power<R: Real>(&self, cos_theta: R) -> R {
        self.sample(self.coordinate(cos_theta))
    }

    /// The bound on `|T(c) − (1 − c)⁵|` over `c ∈ [0, 1]`: `max|f''|·h²/8 = 2.5 h²` (module
    /// docs), before the f32 rounding of the texels (at most 2⁻²⁴ each).
    pub fn error_bound(&self) -> f64 {
        2.5 * self.spacing().powi(2)
    }

    /// A lower bound on the largest error: `20(1 − h)³·h²/8`, the least the first interval's
    /// midpoint is off (module docs).
    pub fn error_attained(&self) -> f64 {
        (1.0 - self.spacing()).powi(3) * self.error_bound()
    }
}

/// Cosines `c` spanning 0–90° densely: uniform in θ and uniform in `c`, `samples` each, so every
/// texel interval (near grazing too, where the error is largest) gets many.
fn sweep(samples: u32) -> impl Iterator<Item = f64> {
    let steps = f64::from(samples.max(1));
    (0..=samples).flat_map(move |k| {
        let t = f64::from(k) / steps;
        [(t * std::f64::consts::FRAC_PI_2).cos(), t]
    })
}

/// The largest `|T(c) − (1 − c)⁵|` of `table` over 0–90° (`samples` cosines uniform in θ and as
/// many uniform in `c`), in f64.
pub fn interpolation_error(table: &SchlickTable, samples: u32) -> f64 {
    sweep(samples)
        .map(|c| (table.fifth_power(c) - (1.0 - c).powi(5)).abs())
        .fold(0.0, f64::max)
}

/// The largest errors of Fresnel through a [`SchlickTable`] at one interface over incidence
/// 0–90° (largest channel), against each reference.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct InterfaceErrors {
    /// Against Schlick's approximation evaluated exactly with the same `R₀` (the table's own
    /// share).
    pub against_schlick: f64,
    /// Glass: against exact dielectric Fresnel, light entering the glass from air and leaving
    /// it (incidence inside, total internal reflection past the critical angle). `None` for a
    /// mirror.
    pub against_dielectric: Option<[f64; 2]>,
    /// Glass: Schlick evaluated exactly against exact dielectric Fresnel, entering and leaving
    /// (the approximation's own share, whatever the table). `None` for a mirror.
    pub schlick_against_dielectric: Option<[f64; 2]>,
}

/// The largest errors of Fresnel through `table` at `interface` over incidence 0–90° (`samples`
/// cosines uniform in θ and as many uniform in cos θ, each side of glass).
pub fn interface_errors(
    table: &SchlickTable,
    interface: Interface,
    samples: u32,
) -> InterfaceErrors {
    let exact_fifth = |c: f64| (1.0 - c).powi(5);
    let table_fifth = |c: f64| table.fifth_power(c);
    match interface {
        Interface::Mirror { reflectance } => InterfaceErrors {
            against_schlick: sweep(samples)
                .map(|c| {
                    let table = fresnel::schlick_by(reflectance, c, table_fifth);
                    (table - fresnel::schlick(reflectance, c))
                        .abs()
                        .max_element()
                })
                .fold(0.0, f64::max),
            against_dielectric: None,
            schlick_against_dielectric: None,
        },
        Interface::Dielectric { ior, .. } => {
            let sides = [(1.0, ior), (ior, 1.0)];
            let worst = |approximate: &dyn Fn(f64, f64, f64) -> f64,
                         reference: &dyn Fn(f64, f64, f64) -> f64| {
                sides.map(|(n1, n2)| {
                    sweep(samples)
                        .map(|c| (approximate(c, n1, n2) - reference(c, n1, n2)).abs())
                        .fold(0.0, f64::max)
                })
            };
            let through_table =
                |c, n1, n2| fresnel::dielectric_schlick(c, n1, n2, table_fifth).reflectance;
            let schlick =
                |c, n1, n2| fresnel::dielectric_schlick(c, n1, n2, exact_fifth).reflectance;
            let dielectric = |c, n1, n2| fresnel::dielectric(c, n1, n2).reflectance;
            let [entering, leaving] = worst(&through_table, &schlick);
            InterfaceErrors {
                against_schlick: entering.max(leaving),
                against_dielectric: Some(worst(&through_table, &dielectric)),
                schlick_against_dielectric: Some(worst(&schlick, &dielectric)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    /// The derived bound holds (to the f32 rounding of the texels) and is nearly attained, at
    /// every size a user is likely to pick and at the ends of the range.
    #[test]
    fn the_table_meets_the_interpolation_bound_and_nearly_attains_it() {
        for texels in [2, 3, 8, 16, 32, 64, 100, 256, 1024, 4096] {
            let table = SchlickTable::new(texels).expect("a size in range");
            let error = interpolation_error(&table, 1 << 16);
            let (bound, attained) = (table.error_bound(), table.error_attained());
            // Each texel is rounded to f32 (≤ 2⁻²⁴ off, values ≤ 1) and the filter runs in f64.
            assert!(
                error <= bound + 1e-7,
                "N = {texels}: error {error:e} over the bound {bound:e}"
            );
            assert!(
                error >= attained * (1.0 - 1e-3) - 1e-7,
                "N = {texels}: error {error:e} under the derived least {attained:e}"
            );
        }
    }

    /// The texture laid out the obvious way (texel i holds `f((i + ½)/N)`, sampled at
    /// `u = cos θ`) clamps the half texel at grazing incidence: a first-order error
    /// `1 − f(1/(2N)) ≈ 5/(2N)`, far over the bound. This is why the table's texels are spaced
    /// `1/(N − 1)` and [`SchlickTable::coordinate`] is not `cos θ`.
    #[test]
    fn the_obvious_layout_breaks_the_bound_at_grazing_incidence() {
        for texels in [16u32, 64, 256] {
            let n = f64::from(texels);
            let obvious = SchlickTable {
                texels: (0..texels)
                    .map(|i| (1.0 - (f64::from(i) + 0.5) / n).powi(5) as f32)
                    .collect(),
            };
            let at_grazing = (obvious.sample(0.0f64) - 1.0).abs();
            let expected = 1.0 - (1.0 - 0.5 / n).powi(5);
            assert!((at_grazing - expected).abs() < 1e-6, "N = {texels}");
            let table = SchlickTable::new(texels).expect("a size in range");
            assert!(
                at_grazing > 10.0 * table.error_bound(),
                "N = {texels}: {at_grazing:e}"
            );
        }
    }

    /// The sampler against a hand computation: between texels the linear blend, at the ends the
    /// clamped texel, at a texel centre the texel.
    #[test]
    fn the_sampler_filters_like_a_vulkan_linear_clamp_to_edge_sampler() {
        let table = SchlickTable::new(5).expect("in range");
        let t: Vec<f64> = table.texels().iter().map(|&v| f64::from(v)).collect();
        let n = 5.0;
        for (i, &texel) in t.iter().enumerate() {
            assert_eq!(table.sample((i as f64 + 0.5) / n), texel);
        }
        // A quarter of the way from texel 1's centre to texel 2's.
        let u = (1.5 + 0.25) / n;
        assert!((table.sample(u) - (0.75 * t[1] + 0.25 * t[2])).abs() < 1e-15);
        // Beyond the end centres, clamp to edge.
        assert_eq!(table.sample(0.01), t[0]);
        assert_eq!(table.sample(0.99), t[4]);
        assert_eq!(table.sample(-3.0), t[0]);
        assert_eq!(table.sample(f64::NAN), t[0]);
        // The coordinate puts cos θ = 0 and 1 on the end centres.
        assert_eq!(table.fifth_power(0.0), 1.0);
        assert_eq!(table.fifth_power(1.0), 0.0);
        assert!(table.fifth_power(f32::NAN).is_finite());
    }

    #[test]
    fn sizes_out_of_range_are_refused_with_the_fix() {
        for texels in [0, 1, 4097, u32::MAX] {
            let error = SchlickTable::new(texels).expect_err("out of range");
            assert_eq!(error.option, crate::options::names::FRESNEL);
            assert_eq!(error.value, format!("table:{texels}"));
            assert!(error.fix.text.contains("2 to 4096"));
        }
        assert_eq!(FresnelModel::Exact.table(), Ok(None));
    }

    /// For a mirror, the error against exact Schlick is the table's own scaled by `1 − R₀`.
    #[test]
    fn a_mirror_inherits_the_table_error_scaled_by_one_minus_r0() {
        let table = SchlickTable::new(32).expect("in range");
        let reflectance = DVec3::new(0.95, 0.5, 0.04);
        let errors = interface_errors(&table, Interface::Mirror { reflectance }, 1 << 15);
        let own = interpolation_error(&table, 1 << 15);
        assert!((errors.against_schlick - (1.0 - 0.04) * own).abs() < 1e-9 * own.max(1e-9) + 1e-7);
        assert!(errors.against_dielectric.is_none());
    }
}
