//! The EM solve (hybrid-rendering paper §4.3, eq. 1; PEM paper, "EM MIPMAPs"): all MIP levels of
//! one layer's cube map at once, minimising
//!
//! ```text
//! Σ_terms ‖C_t (A_t x − b_t)‖²  +  λ ‖G x‖²
//! ```
//!
//! with C_t the confidence images, A_t the rendering matrices ([`crate::matrix`]) and G the
//! smoothness operator ([`Smoothness`]): one row per pair of neighbouring texels — within a face,
//! across cube-face seams, and between a texel and its parent one MIP level up — so texels no pixel
//! sees are filled smoothly from their neighbours, while a constant EM costs nothing (it is in G's
//! null space). λ is relative: `smoothness × mean diagonal of Σ A_tᵀC_t²A_t` over seen texels, so
//! it does not depend on the image size. The four channels share the matrix (premultiplied
//! texels) and are solved together.
//!
//! Conjugate gradient on the normal equations with a Jacobi preconditioner (the default), or LSQR
//! on the least-squares system ([`SolveMethod`]), both written here (short, matrix-free over
//! `sprs` matrices) because neither `sprs` nor `faer` provides them for several right-hand sides
//! without forming AᵀA; forming it would cost more than the solve.
//! Afterwards texels are put in range (premultiplied: rgb ≥ 0, 0 ≤ α ≤ 1).

use std::time::Instant;

use lensmap::cubemap::face::texel_source;
use rayon::prelude::*;
use sprs::CsMat;

use crate::matrix::{Texel, TexelLayout, multiply};

/// The default relative smoothness weight (see the module documentation).
pub const DEFAULT_SMOOTHNESS: f64 = 1e-3;

/// Solver options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveOptions {
    /// The iterative method.
    pub method: SolveMethod,
    /// Relative smoothness weight, ≥ 0.
    pub smoothness: f64,
    /// Stop when ‖residual‖ ≤ this × ‖right-hand side‖ (of the normal equations), per channel.
    pub tolerance: f64,
    /// Most CG iterations.
    pub max_iterations: usize,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            method: SolveMethod::ConjugateGradient,
            smoothness: DEFAULT_SMOOTHNESS,
            tolerance: 1e-4,
            max_iterations: 400,
        }
    }
}

/// The iterative method of the solve; both see the same Jacobi scaling and give the same
/// solution (a unit test checks it). Measured on teapot-room at 640×480 (`lensmap bench infer
/// --solver cg|lsqr`, 400-iteration cap): CG reached a normal-equation residual below 1e-4 in
/// 225–280 iterations and 2.4–3.0 s per layer; LSQR was still at 8e-4–2.5e-3 after 400 iterations
/// and 7.3–8.9 s. CG is the default.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SolveMethod {
    /// Preconditioned conjugate gradient on the normal equations (CGNR).
    ConjugateGradient,
    /// LSQR (Paige & Saunders) on the least-squares system itself, column-scaled.
    Lsqr,
}

/// One term's equations: A, the target b and the confidence per display pixel.
pub struct Equations<'a> {
    /// Rendering matrix (display pixels × texels), CSR.
    pub a: &'a CsMat<f64>,
    /// Target per display pixel, premultiplied RGBA.
    pub b: &'a [[f64; 4]],
    /// Confidence per display pixel, in [0, 1].
    pub confidence: &'a [f64],
}

/// Why a solve cannot run.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    /// Inconsistent sizes or values; names what and the fix.
    #[error("solve: {0}")]
    BadInput(String),
    /// No texel has any weighted equation: nothing to fit.
    #[error(
        "solve: no equation has weight: the confidence is zero wherever the rendering matrices have entries (or they are empty); check the targets' camera and the confidence angle"
    )]
    NoData,
}

/// What a solve did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SolveReport {
    /// CG iterations run.
    pub iterations: usize,
    /// Final ‖residual‖ / ‖rhs‖ of the normal equations, worst channel.
    pub relative_residual: f64,
    /// Wall time, ms.
    pub ms: f64,
    /// Texels with data (non-zero diagonal of Σ AᵀC²A).
    pub seen_texels: usize,
    /// Texels changed by putting them in range.
    pub clamped_texels: usize,
}

/// The smoothness operator G as a list of neighbour pairs (a, b): (G x)_e = x_a − x_b.
#[derive(Clone, Debug)]
pub struct Smoothness {
    pairs: Vec<(usize, usize)>,
}

impl Smoothness {
    /// Every pair of 4-neighbours within a face and across seams (each pair once), and every
    /// texel with its parent one level up.
    pub fn new(layout: &TexelLayout) -> Smoothness {
        let mut pairs = Vec::new();
        for level in 0..layout.levels() {
            let edge = layout.edge(level);
            for column in layout.level_columns(level) {
                let texel = layout.texel(column);
                for (dx, dy) in [(1i64, 0i64), (0, 1), (-1, 0), (0, -1)] {
                    let Some((face, x, y)) = texel_source(
                        texel.face,
                        edge,
                        i64::from(texel.x) + dx,
                        i64::from(texel.y) + dy,
                    ) else {
                        continue;
                    };
                    let other = layout.column(Texel { level, face, x, y });
                    // Seen from both sides; kept once. A 1×1 face is its own neighbour's
                    // neighbour only across faces, never itself.
                    if other > column {
                        pairs.push((column, other));
                    }
                }
                if level + 1 < layout.levels() {
                    let parent = layout.column(Texel {
                        level: level + 1,
                        face: texel.face,
                        x: texel.x / 2,
                        y: texel.y / 2,
                    });
                    pairs.push((column, parent));
                }
            }
        }
        Smoothness { pairs }
    }

    /// Number of pairs (rows of G).
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether G has no rows (never, for a real layout).
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// ‖G x‖² per channel.
    pub fn energy(&self, x: &[[f64; 4]]) -> [f64; 4] {
        let mut sum = [0.0; 4];
        for &(a, b) in &self.pairs {
            for c in 0..4 {
                sum[c] += (x[a][c] - x[b][c]).powi(2);
            }
        }
        sum
    }

    /// The graph Laplacian GᵀG x: per texel, Σ over its neighbours of (x_texel − x_neighbour).
    /// Zero at a texel no pixel sees once the solve has converged (the fill is harmonic there).
    pub fn laplacian(&self, x: &[[f64; 4]]) -> Vec<[f64; 4]> {
        let mut y = vec![[0.0; 4]; x.len()];
        self.add_normal(1.0, x, &mut y);
        y
    }

    /// y += weight · GᵀG x.
    fn add_normal(&self, weight: f64, x: &[[f64; 4]], y: &mut [[f64; 4]]) {
        for &(a, b) in &self.pairs {
            for c in 0..4 {
                let d = weight * (x[a][c] - x[b][c]);
                y[a][c] += d;
                y[b][c] -= d;
            }
        }
    }

    /// diag(GᵀG): the number of pairs each texel is in.
    fn degree(&self, n: usize) -> Vec<f64> {
        let mut degree = vec![0.0; n];
        for &(a, b) in &self.pairs {
            degree[a] += 1.0;
            degree[b] += 1.0;
        }
        degree
    }
}

/// How far outside the range a texel may drift (rounding in CG) before it is pinned.
const RANGE_SLACK: f64 = 1e-6;

/// x ↦ N x, the normal equations' operator.
type NormalOperator<'a> = dyn Fn(&[[f64; 4]]) -> Vec<[f64; 4]> + 'a;

/// One term's rows scaled by its confidence: C A, its transpose (CSR), and C b.
struct WeightedTerm {
    ca: CsMat<f64>,
    at: CsMat<f64>,
    cb: Vec<[f64; 4]>,
}

/// Rounds of the range active set.
const MAX_RANGE_ROUNDS: usize = 6;

/// A premultiplied texel put in range: rgb ≥ 0, 0 ≤ α ≤ 1.
fn in_range(texel: [f64; 4]) -> [f64; 4] {
    [
        texel[0].max(0.0),
        texel[1].max(0.0),
        texel[2].max(0.0),
        texel[3].clamp(0.0, 1.0),
    ]
}

/// Texels per chunk of [`dot`]'s parallel partial sums.
const DOT_CHUNK: usize = 4096;

/// `Σ a·b` per channel. Partial sums over fixed chunks, added in chunk order: rayon's own
/// `reduce` splits where work is stolen, so its rounding (and every CG iterate after it) would
/// change from run to run, and a bake must give the same bytes every time.
fn dot(a: &[[f64; 4]], b: &[[f64; 4]]) -> [f64; 4] {
    let partial: Vec<[f64; 4]> = a
        .par_chunks(DOT_CHUNK)
        .zip(b.par_chunks(DOT_CHUNK))
        .map(|(a, b)| {
            let mut sum = [0.0; 4];
            for (a, b) in a.iter().zip(b) {
                for c in 0..4 {
                    sum[c] += a[c] * b[c];
                }
            }
            sum
        })
        .collect();
    partial
        .iter()
        .fold([0.0; 4], |s, t| std::array::from_fn(|c| s[c] + t[c]))
}

/// Preconditioned CG on the free entries of `x` (the `fixed` ones keep their value), the four
/// channels as independent systems sharing the operator. Returns the iterations and the final
/// worst relative residual.
fn conjugate_gradient(
    normal: &NormalOperator<'_>,
    rhs: &[[f64; 4]],
    preconditioner: &[f64],
    fixed: &[[bool; 4]],
    x: &mut [[f64; 4]],
    tolerance: f64,
    max_iterations: usize,
) -> (usize, f64) {
    let n = x.len();
    let free = |v: &mut Vec<[f64; 4]>| {
        for (e, f) in v.iter_mut().zip(fixed) {
            for c in 0..4 {
                if f[c] {
                    e[c] = 0.0;
                }
            }
        }
    };
    let mut rhs_free = rhs.to_vec();
    free(&mut rhs_free);
    let rhs_norm = dot(&rhs_free, &rhs_free).map(|v| if v > 0.0 { v.sqrt() } else { 1.0 });
    let relative = |r: &[[f64; 4]]| {
        let rr = dot(r, r);
        (0..4)
            .map(|c| rr[c].sqrt() / rhs_norm[c])
            .fold(0.0, f64::max)
    };
    let nx = normal(x);
    let mut r: Vec<[f64; 4]> = rhs
        .iter()
        .zip(&nx)
        .map(|(b, a)| std::array::from_fn(|c| b[c] - a[c]))
        .collect();
    free(&mut r);
    let precondition = |r: &[[f64; 4]]| -> Vec<[f64; 4]> {
        r.iter()
            .zip(preconditioner)
            .map(|(r, m)| r.map(|v| v * m))
            .collect()
    };
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut iterations = 0;
    let mut residual = relative(&r);
    while residual > tolerance && iterations < max_iterations {
        let mut q = normal(&p);
        free(&mut q);
        let pq = dot(&p, &q);
        let alpha: [f64; 4] =
            std::array::from_fn(|c| if pq[c] > 0.0 { rz[c] / pq[c] } else { 0.0 });
        for i in 0..n {
            for c in 0..4 {
                x[i][c] += alpha[c] * p[i][c];
                r[i][c] -= alpha[c] * q[i][c];
            }
        }
        z = precondition(&r);
        let rz_next = dot(&r, &z);
        let beta: [f64; 4] =
            std::array::from_fn(|c| if rz[c] > 0.0 { rz_next[c] / rz[c] } else { 0.0 });
        for i in 0..n {
            for c in 0..4 {
                p[i][c] = z[i][c] + beta[c] * p[i][c];
            }
        }
        rz = rz_next;
        iterations += 1;
        residual = relative(&r);
    }
    (iterations, residual)
}

/// Scales every entry's channel c by `by[c]`.
fn normalize(v: &mut [[f64; 4]], by: [f64; 4]) {
    for e in v {
        for (value, factor) in e.iter_mut().zip(by) {
            *value *= factor;
        }
    }
}

/// ‖rhs − N x‖ / ‖rhs‖ over the free entries, worst channel: the stopping test of both methods.
fn normal_residual(
    normal: &NormalOperator<'_>,
    rhs: &[[f64; 4]],
    fixed: &[[bool; 4]],
    x: &[[f64; 4]],
) -> f64 {
    let nx = normal(x);
    let mut r = vec![[0.0; 4]; x.len()];
    let mut b = vec![[0.0; 4]; x.len()];
    for i in 0..x.len() {
        for c in 0..4 {
            if !fixed[i][c] {
                r[i][c] = rhs[i][c] - nx[i][c];
                b[i][c] = rhs[i][c];
            }
        }
    }
    let (rr, bb) = (dot(&r, &r), dot(&b, &b));
    (0..4)
        .map(|c| {
            if bb[c] > 0.0 {
                (rr[c] / bb[c]).sqrt()
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// The operator LSQR works on: M = [C₁A₁; …; √λ G] with its columns scaled by S (the Jacobi
/// scaling CG uses), the `fixed` entries held (their columns zero in the adjoint). Its row space
/// is each term's pixels, then the smoothness pairs.
struct ScaledOperator<'a> {
    terms: &'a [WeightedTerm],
    smoothness: &'a Smoothness,
    root_lambda: f64,
    scale: Vec<f64>,
    fixed: &'a [[bool; 4]],
}

impl<'a> ScaledOperator<'a> {
    /// The operator of `terms` and the smoothness pairs weighted by `lambda`, scaled by the
    /// square roots of `preconditioner`, with the `fixed` entries held.
    fn new(
        terms: &'a [WeightedTerm],
        smoothness: &'a Smoothness,
        lambda: f64,
        preconditioner: &[f64],
        fixed: &'a [[bool; 4]],
    ) -> ScaledOperator<'a> {
        ScaledOperator {
            terms,
            smoothness,
            root_lambda: lambda.sqrt(),
            scale: preconditioner.iter().map(|p| p.sqrt()).collect(),
            fixed,
        }
    }

    /// M S v, per row block.
    fn forward(&self, v: &[[f64; 4]]) -> Vec<Vec<[f64; 4]>> {
        let scaled: Vec<[f64; 4]> = v
            .iter()
            .zip(&self.scale)
            .map(|(v, s)| v.map(|e| e * s))
            .collect();
        let mut parts: Vec<Vec<[f64; 4]>> = self
            .terms
            .iter()
            .map(|t| multiply(&t.ca, &scaled))
            .collect();
        parts.push(
            self.smoothness
                .pairs
                .iter()
                .map(|&(a, b)| {
                    std::array::from_fn(|c| self.root_lambda * (scaled[a][c] - scaled[b][c]))
                })
                .collect(),
        );
        parts
    }

    /// (M S)ᵀ u, zero on the fixed entries.
    fn adjoint(&self, u: &[Vec<[f64; 4]>]) -> Vec<[f64; 4]> {
        let mut v = vec![[0.0; 4]; self.scale.len()];
        for (t, part) in self.terms.iter().zip(u) {
            for (v, p) in v.iter_mut().zip(multiply(&t.at, part)) {
                for c in 0..4 {
                    v[c] += p[c];
                }
            }
        }
        if let Some(pairs) = u.get(self.terms.len()) {
            for (&(a, b), e) in self.smoothness.pairs.iter().zip(pairs) {
                for c in 0..4 {
                    v[a][c] += self.root_lambda * e[c];
                    v[b][c] -= self.root_lambda * e[c];
                }
            }
        }
        for ((v, s), f) in v.iter_mut().zip(&self.scale).zip(self.fixed) {
            for c in 0..4 {
                v[c] = if f[c] { 0.0 } else { v[c] * s };
            }
        }
        v
    }

    /// S⁻¹ x: a point of texel space in the operator's scaled coordinates.
    fn unscaled(&self, x: &[[f64; 4]]) -> Vec<[f64; 4]> {
        x.iter()
            .zip(&self.scale)
            .map(|(x, s)| x.map(|e| if *s > 0.0 { e / s } else { 0.0 }))
            .collect()
    }
}

/// Per channel, the norm of a vector of the row space (all blocks).
fn parts_norm(parts: &[Vec<[f64; 4]>]) -> [f64; 4] {
    let mut s = [0.0; 4];
    for part in parts {
        let d = dot(part, part);
        for c in 0..4 {
            s[c] += d[c];
        }
    }
    s.map(f64::sqrt)
}

/// Scales channel c of every entry of every block by `by[c]`.
fn scale_parts(parts: &mut [Vec<[f64; 4]>], by: [f64; 4]) {
    for part in parts {
        normalize(part, by);
    }
}

/// 1/v per channel, 0 where v is 0.
fn inverse(v: [f64; 4]) -> [f64; 4] {
    v.map(|e| if e > 0.0 { 1.0 / e } else { 0.0 })
}

/// LSQR (Paige & Saunders 1982) on min ‖M δ − d‖ with `operator` M S (M = [C₁A₁; …; √λ G], S =
/// diag(Σ AᵀC²A + λGᵀG)^(−½), the same Jacobi scaling CG uses), d the residual at `x`, the
/// operator's fixed entries held; per channel, the four channels at once. Stops when its
/// estimate of ‖(MS)ᵀ r‖ falls below `tolerance` × its start. Returns the iterations.
fn lsqr(
    operator: &ScaledOperator<'_>,
    x: &mut [[f64; 4]],
    tolerance: f64,
    max_iterations: usize,
) -> usize {
    let n = x.len();
    let terms = operator.terms;
    // d = [C b − C A x; −√λ G x].
    let at_x = operator.forward(&operator.unscaled(x));
    let mut u: Vec<Vec<[f64; 4]>> = terms
        .iter()
        .zip(&at_x)
        .map(|(t, ax)| {
            t.cb.iter()
                .zip(ax)
                .map(|(b, a)| std::array::from_fn(|c| b[c] - a[c]))
                .collect()
        })
        .collect();
    u.push(at_x[terms.len()].iter().map(|e| e.map(|v| -v)).collect());
    let mut beta = parts_norm(&u);
    scale_parts(&mut u, inverse(beta));
    let mut v = operator.adjoint(&u);
    let mut alpha = dot(&v, &v).map(f64::sqrt);
    normalize(&mut v, inverse(alpha));
    let mut w = v.clone();
    let mut y = vec![[0.0f64; 4]; n];
    let mut phi_bar = beta;
    let mut rho_bar = alpha;
    let start: [f64; 4] = std::array::from_fn(|c| alpha[c] * beta[c]);
    let mut iterations = 0;
    while iterations < max_iterations {
        // β u ← M v − α u
        let mv = operator.forward(&v);
        for (part, m) in u.iter_mut().zip(&mv) {
            for (e, m) in part.iter_mut().zip(m) {
                for c in 0..4 {
                    e[c] = m[c] - alpha[c] * e[c];
                }
            }
        }
        beta = parts_norm(&u);
        scale_parts(&mut u, inverse(beta));
        // α v ← Mᵀ u − β v
        let mtu = operator.adjoint(&u);
        for (e, m) in v.iter_mut().zip(&mtu) {
            for c in 0..4 {
                e[c] = m[c] - beta[c] * e[c];
            }
        }
        alpha = dot(&v, &v).map(f64::sqrt);
        normalize(&mut v, inverse(alpha));
        let mut estimate = 0.0f64;
        for c in 0..4 {
            let rho = (rho_bar[c] * rho_bar[c] + beta[c] * beta[c]).sqrt();
            if rho == 0.0 {
                continue;
            }
            let (cs, sn) = (rho_bar[c] / rho, beta[c] / rho);
            let theta = sn * alpha[c];
            rho_bar[c] = -cs * alpha[c];
            let phi = cs * phi_bar[c];
            phi_bar[c] *= sn;
            for i in 0..n {
                y[i][c] += (phi / rho) * w[i][c];
                w[i][c] = v[i][c] - (theta / rho) * w[i][c];
            }
            if start[c] > 0.0 {
                estimate = estimate.max((phi_bar[c] * alpha[c] * cs).abs() / start[c]);
            }
        }
        iterations += 1;
        if estimate <= tolerance {
            break;
        }
    }
    for ((x, y), s) in x.iter_mut().zip(&y).zip(&operator.scale) {
        for c in 0..4 {
            x[c] += y[c] * s;
        }
    }
    iterations
}

/// Each term of `equations` with its rows scaled by its confidence (C A, C b) and C A
/// transposed, after checking that its sizes agree with each other and with the `n` texels,
/// that its target is finite and its confidence in [0, 1].
fn weighted_terms(equations: &[Equations<'_>], n: usize) -> Result<Vec<WeightedTerm>, SolveError> {
    let mut weighted: Vec<WeightedTerm> = Vec::new();
    for (t, e) in equations.iter().enumerate() {
        let rows = e.a.rows();
        if e.a.cols() != n || e.b.len() != rows || e.confidence.len() != rows {
            return Err(SolveError::BadInput(format!(
                "term {t}: A is {}×{}, b has {} pixels, confidence {}; they must agree with each other and with the {n} texels",
                rows,
                e.a.cols(),
                e.b.len(),
                e.confidence.len()
            )));
        }
        if e.b.iter().flatten().any(|v| !v.is_finite())
            || e.confidence
                .iter()
                .any(|c| !c.is_finite() || !(0.0..=1.0).contains(c))
        {
            return Err(SolveError::BadInput(format!(
                "term {t}: the target has non-finite values or the confidence is outside [0, 1]"
            )));
        }
        let mut ca = e.a.to_owned();
        for (row, mut values) in ca.outer_iterator_mut().enumerate() {
            values.map_inplace(|v| v * e.confidence[row]);
        }
        let cb =
            e.b.iter()
                .zip(e.confidence)
                .map(|(b, c)| b.map(|v| v * c))
                .collect();
        let transposed = ca.transpose_view().to_csr();
        weighted.push(WeightedTerm {
            ca,
            at: transposed,
            cb,
        });
    }
    Ok(weighted)
}

/// Solves for one layer's texels (see the module documentation); `x0` is the starting guess (the
/// projected EM, say), `layout` the columns.
pub fn solve(
    equations: &[Equations<'_>],
    layout: &TexelLayout,
    smoothness: &Smoothness,
    x0: &[[f64; 4]],
    options: &SolveOptions,
) -> Result<(Vec<[f64; 4]>, SolveReport), SolveError> {
    let start = Instant::now();
    let n = layout.len();
    if x0.len() != n {
        return Err(SolveError::BadInput(format!(
            "starting guess has {} texels, the layout {n}",
            x0.len()
        )));
    }
    if !(options.smoothness.is_finite() && options.smoothness >= 0.0) {
        return Err(SolveError::BadInput(format!(
            "smoothness {}; give a finite weight ≥ 0, e.g. {DEFAULT_SMOOTHNESS}",
            options.smoothness
        )));
    }
    let weighted = weighted_terms(equations, n)?;
    // Diagonal of Σ AᵀC²A: squared column norms.
    let mut data_diagonal = vec![0.0f64; n];
    for term in &weighted {
        for (column, row) in term.at.outer_iterator().enumerate() {
            data_diagonal[column] += row.data().iter().map(|v| v * v).sum::<f64>();
        }
    }
    let seen: Vec<f64> = data_diagonal.iter().copied().filter(|d| *d > 0.0).collect();
    let seen_texels = seen.len();
    if seen_texels == 0 {
        return Err(SolveError::NoData);
    }
    let mean_seen = if seen.is_empty() {
        1.0
    } else {
        seen.iter().sum::<f64>() / seen.len() as f64
    };
    let lambda = options.smoothness * mean_seen;
    let degree = smoothness.degree(n);
    let preconditioner: Vec<f64> = data_diagonal
        .iter()
        .zip(&degree)
        .map(|(d, g)| {
            let diagonal = d + lambda * g;
            if diagonal > 0.0 { 1.0 / diagonal } else { 1.0 }
        })
        .collect();
    // The normal operator N x = Σ AᵀC²A x + λ GᵀG x, and its right-hand side Σ AᵀC²b.
    let normal = |x: &[[f64; 4]]| -> Vec<[f64; 4]> {
        let mut y = vec![[0.0; 4]; n];
        for term in &weighted {
            let ax = multiply(&term.ca, x);
            let part = multiply(&term.at, &ax);
            y.par_iter_mut().zip(part).for_each(|(y, p)| {
                for c in 0..4 {
                    y[c] += p[c];
                }
            });
        }
        smoothness.add_normal(lambda, x, &mut y);
        y
    };
    let mut rhs = vec![[0.0; 4]; n];
    for term in &weighted {
        for (r, p) in rhs.iter_mut().zip(multiply(&term.at, &term.cb)) {
            for c in 0..4 {
                r[c] += p[c];
            }
        }
    }
    // Range by an active set: solve on the free texels, pin the ones that leave the range at
    // their bound, and solve again for the rest (at most a few rounds: few texels are pinned).
    let mut x: Vec<[f64; 4]> = x0.iter().map(|t| in_range(*t)).collect();
    let mut fixed = vec![[false; 4]; n];
    let mut iterations = 0;
    let mut residual = 0.0;
    for _round in 0..MAX_RANGE_ROUNDS {
        let budget = options.max_iterations.saturating_sub(iterations).max(1);
        let (used, reached) = match options.method {
            SolveMethod::ConjugateGradient => conjugate_gradient(
                &normal,
                &rhs,
                &preconditioner,
                &fixed,
                &mut x,
                options.tolerance,
                budget,
            ),
            SolveMethod::Lsqr => {
                let operator =
                    ScaledOperator::new(&weighted, smoothness, lambda, &preconditioner, &fixed);
                let used = lsqr(&operator, &mut x, options.tolerance, budget);
                (used, normal_residual(&normal, &rhs, &fixed, &x))
            }
        };
        iterations += used;
        residual = reached;
        let mut pinned = 0;
        for (texel, fix) in x.iter_mut().zip(&mut fixed) {
            let bounded = in_range(*texel);
            for c in 0..4 {
                // Overshoots within rounding are clamped at the end, not pinned.
                if (bounded[c] - texel[c]).abs() > RANGE_SLACK {
                    texel[c] = bounded[c];
                    fix[c] = true;
                    pinned += 1;
                }
            }
        }
        if pinned == 0 {
            break;
        }
    }
    let clamped_texels = fixed.iter().filter(|f| f.contains(&true)).count();
    // Whatever remains out of range after the last round (none, unless the rounds ran out).
    for texel in &mut x {
        *texel = in_range(*texel);
    }
    Ok((
        x,
        SolveReport {
            iterations,
            relative_residual: residual,
            ms: start.elapsed().as_secs_f64() * 1e3,
            seen_texels,
            clamped_texels,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sprs::TriMat;

    #[test]
    fn a_constant_em_is_in_the_null_space_of_the_smoothness() {
        let layout = TexelLayout::new(8);
        let g = Smoothness::new(&layout);
        assert!(g.len() > 3 * layout.len() / 2);
        let x = vec![[0.3, 0.2, 0.1, 0.7]; layout.len()];
        assert_eq!(g.energy(&x), [0.0; 4]);
        // …and nothing else is: a single changed texel costs.
        let mut y = x.clone();
        y[5][0] = 1.0;
        assert!(g.energy(&y)[0] > 0.0);
    }

    #[test]
    fn every_texel_has_four_neighbours_in_its_level() {
        // Within faces and across seams (corners have 4 too: the cube is a closed surface).
        let layout = TexelLayout::new(4);
        let g = Smoothness::new(&layout);
        let mut within = vec![0usize; layout.len()];
        for &(a, b) in &g.pairs {
            if layout.texel(a).level == layout.texel(b).level {
                within[a] += 1;
                within[b] += 1;
            }
        }
        assert!(within.iter().all(|&d| d == 4), "{within:?}");
    }

    #[test]
    fn a_single_seen_texel_spreads_smoothly() {
        // One pixel sees one texel of level 0 at value 1: the solution reproduces it there and
        // fills every other texel with a smooth, bounded field that decays with distance.
        let layout = TexelLayout::new(8);
        let g = Smoothness::new(&layout);
        let seen = layout.column(Texel {
            level: 0,
            face: lensmap::cubemap::CubeFace::PositiveZ,
            x: 3,
            y: 4,
        });
        let mut tri = TriMat::new((1, layout.len()));
        tri.add_triplet(0, seen, 1.0);
        let a = tri.to_csr();
        let b = vec![[1.0, 0.5, 0.25, 1.0]];
        let (x, report) = solve(
            &[Equations {
                a: &a,
                b: &b,
                confidence: &[1.0],
            }],
            &layout,
            &g,
            &vec![[0.0; 4]; layout.len()],
            &SolveOptions {
                tolerance: 1e-9,
                max_iterations: 10_000,
                ..SolveOptions::default()
            },
        )
        .unwrap();
        assert!(report.relative_residual <= 1e-9, "{report:?}");
        assert!((x[seen][0] - 1.0).abs() < 1e-2, "{:?}", x[seen]);
        assert!(x.iter().flatten().all(|v| v.is_finite()));
        // The harmonic fill of a closed surface with one pinned value is the constant: every
        // texel converges to the seen one (no NaN, no overshoot).
        for t in &x {
            assert!((t[0] - 1.0).abs() < 1e-2 && t[0] <= 1.0 + 1e-6, "{t:?}");
        }
    }

    #[test]
    fn lsqr_and_cg_reach_the_same_solution() {
        use rand::{Rng, SeedableRng};
        let layout = TexelLayout::new(4);
        let g = Smoothness::new(&layout);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0x15e5);
        let rows = 300;
        let mut tri = TriMat::new((rows, layout.len()));
        for row in 0..rows {
            for _ in 0..4 {
                tri.add_triplet(row, rng.gen_range(0..layout.len()), rng.gen_range(0.0..0.5));
            }
        }
        let a = tri.to_csr();
        let b: Vec<[f64; 4]> = (0..rows)
            .map(|_| std::array::from_fn(|_| rng.gen_range(0.2..0.8)))
            .collect();
        let confidence: Vec<f64> = (0..rows).map(|_| rng.gen_range(0.5..1.0)).collect();
        let solve_with = |method| {
            solve(
                &[Equations {
                    a: &a,
                    b: &b,
                    confidence: &confidence,
                }],
                &layout,
                &g,
                &vec![[0.5; 4]; layout.len()],
                &SolveOptions {
                    method,
                    tolerance: 1e-11,
                    max_iterations: 20_000,
                    ..SolveOptions::default()
                },
            )
            .unwrap()
        };
        let (x_cg, cg) = solve_with(SolveMethod::ConjugateGradient);
        let (x_lsqr, lsqr) = solve_with(SolveMethod::Lsqr);
        println!("CG {cg:?}\nLSQR {lsqr:?}");
        for (p, q) in x_cg.iter().zip(&x_lsqr) {
            for c in 0..4 {
                assert!((p[c] - q[c]).abs() < 1e-5, "{p:?} vs {q:?}");
            }
        }
    }
}
