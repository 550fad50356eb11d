//! Layer placement over a view space (hybrid-rendering paper §4.2): the intersection records of
//! a lens object at several viewpoints are clustered by distance ([`crate::clustering`]: whole
//! objects, continued rays, coherent over the view space because every viewpoint's records go
//! into one clustering), and each layer gets the shell that fits its hits best.
//!
//! **The fit measure.** A layer's hits are the front-most hit of every continued ray in that
//! layer (as the clustering's shell distance uses them). For a candidate shell, each hit `p`
//! seen from the EM origin `o` along `d = (p − o)/|p − o|` is compared with where the shell puts
//! that direction, `t_shell(d)`: the error is `ln(t_shell / |p − o|)`, the relative depth error,
//! which is what parallax between viewpoints grows with (a wall 1 m off at 10 m misleads the
//! lookup as much as a cup 0.1 m off at 1 m). The measure is the root mean square of that error
//! over the layer's hits (a direction the shell does not cover counts as error 1, e.g. past an
//! infinite cylinder's axis). Candidates, all centred on the EM origin: a sphere (radius: the
//! mean distance), a vertical cylinder (radius: the mean horizontal distance), an axis-aligned
//! ellipsoid (least squares on x²/a² + y²/b² + z²/c² = 1) and an axis-aligned box (half extents
//! refined by assigning each hit to the face its direction reaches first), both capped at
//! [`MAX_SHELL_STRETCH`] × the farthest hit (a floor alone fits an unbounded one). The smallest RMS
//! wins, except that the simplest kind (in that order) within [`SIMPLER_SHELL_MARGIN`] of it is
//! preferred.
//! Quads are not fitted: a lens object surrounded by a sparse layer is better served by the
//! scene naming it.

use std::collections::HashMap;

use glam::DVec3;
use lensmap::{
    layers::LayerShell,
    scene::{Camera, Scene},
    trace::{TraceError, TraceOptions, compile_records, world::TraceScene},
};

use crate::clustering::{ClusteringError, DistanceRecord, cluster_layers};

/// A more complex shell kind must beat a simpler one's RMS by this fraction to be chosen.
pub const SIMPLER_SHELL_MARGIN: f64 = 0.05;

/// A fitted ellipsoid's radii and box's half extents are at most this multiple of the layer's
/// farthest hit distance.
pub const MAX_SHELL_STRETCH: f64 = 2.0;

/// One placed layer.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlacedLayer {
    /// The fitted shell.
    pub shell: LayerShell,
    /// The fit measure of the chosen shell (RMS relative depth error, see the module docs).
    pub rms_relative_error: f64,
    /// The fit measure of every candidate kind, `(kind, rms)`, in the order tried.
    pub candidates: Vec<(&'static str, f64)>,
    /// Names of the scene objects that lie (whole) in this layer, sorted.
    pub objects: Vec<String>,
    /// Hits (front-most per ray) the fit used.
    pub hits: usize,
    /// Those hits, world space, metres (what a shell shared with another lens object is fitted
    /// to, with theirs).
    #[serde(skip)]
    pub points: Vec<DVec3>,
}

/// The layers of one lens object, nearest first.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Placement {
    /// The layers.
    pub layers: Vec<PlacedLayer>,
    /// LBG iterations.
    pub iterations: usize,
}

/// Why placement failed.
#[derive(Debug, thiserror::Error)]
pub enum PlacementError {
    /// Tracing the records failed.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The clustering refused its input.
    #[error("lens \"{lens}\": {source}")]
    Clustering {
        /// Lens name.
        lens: String,
        /// The clustering's error.
        source: ClusteringError,
    },
}

/// The environment hits lens object `lens` sees from `cameras` (each at its own resolution and
/// supersampling): every hit of every continued outgoing ray, as points, with the object hit and
/// a ray id unique over all cameras.
pub fn lens_hits(
    trace: &TraceScene,
    lens: usize,
    cameras: &[Camera],
    options: &TraceOptions,
) -> Result<Vec<(DVec3, u32, u64)>, TraceError> {
    let mut hits = Vec::new();
    let mut ray = 0u64;
    for camera in cameras {
        let set = compile_records(trace, camera, options)?;
        let Some(records) = set.lenses.get(lens) else {
            continue;
        };
        for record in &records.records {
            if record.truncated {
                continue;
            }
            let outgoing = record.outgoing_ray;
            for hit in records.hits_of(record) {
                let point = outgoing.origin + hit.distance * outgoing.direction;
                hits.push((point, hit.object as u32, ray));
            }
            ray += 1;
        }
    }
    Ok(hits)
}

/// Places `k` layers (at most; empty clusters are dropped) for the lens object named `name` of
/// `scene`, EM origin `origin`, from its `hits` ([`lens_hits`]), each with its best-fitting shell.
pub fn place_layers(
    scene: &Scene,
    name: &str,
    origin: DVec3,
    hits: &[(DVec3, u32, u64)],
    k: usize,
) -> Result<Placement, PlacementError> {
    let records: Vec<DistanceRecord> = hits
        .iter()
        .map(|&(point, object, ray)| DistanceRecord {
            distance: point.distance(origin),
            object,
            ray,
        })
        .collect();
    let layers = cluster_layers(&records, k).map_err(|source| PlacementError::Clustering {
        lens: name.to_owned(),
        source,
    })?;
    // Front-most hit per (ray, layer), as the clustering's shell distances use them.
    let mut front: HashMap<(u64, usize), (f64, DVec3)> = HashMap::new();
    for (record, &(point, _, _)) in records.iter().zip(hits) {
        let layer = layers.object_layer[&record.object];
        let entry = front
            .entry((record.ray, layer))
            .or_insert((record.distance, point));
        if record.distance < entry.0 {
            *entry = (record.distance, point);
        }
    }
    let mut points: Vec<Vec<DVec3>> = vec![Vec::new(); layers.distances.len()];
    let mut keys: Vec<_> = front.into_iter().collect();
    keys.sort_by_key(|entry| entry.0); // fixed order: bit-identical fits
    for ((_, layer), (_, point)) in keys {
        points[layer].push(point - origin);
    }
    let mut objects: Vec<Vec<String>> = vec![Vec::new(); layers.distances.len()];
    for (&object, &layer) in &layers.object_layer {
        objects[layer].push(
            scene
                .objects
                .get(object as usize)
                .map_or_else(|| format!("object {object}"), |o| o.name.clone()),
        );
    }
    let placed = points
        .iter()
        .zip(objects)
        .map(|(points, mut objects)| {
            objects.sort();
            let (shell, rms, candidates) = fit_shell(origin, points);
            PlacedLayer {
                shell,
                rms_relative_error: rms,
                candidates,
                objects,
                hits: points.len(),
                points: points.iter().map(|p| *p + origin).collect(),
            }
        })
        .collect();
    Ok(Placement {
        layers: placed,
        iterations: layers.iterations,
    })
}

/// The RMS relative depth error of `shell` (centred on the EM origin) over `points` (relative to
/// the EM origin).
pub fn fit_error(shell: &LayerShell, origin: DVec3, points: &[DVec3]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let sum: f64 = points
        .iter()
        .map(|p| {
            let distance = p.length();
            let direction = *p / distance;
            match shell.intersect(origin, direction) {
                Some(hit) if hit.t > 0.0 && distance > 0.0 => (hit.t / distance).ln().powi(2),
                _ => 1.0,
            }
        })
        .sum();
    (sum / points.len() as f64).sqrt()
}

/// The best-fitting shell for `points` (relative to `origin`), its RMS and every candidate's.
pub fn fit_shell(origin: DVec3, points: &[DVec3]) -> (LayerShell, f64, Vec<(&'static str, f64)>) {
    let n = points.len().max(1) as f64;
    let mean = |f: &dyn Fn(&DVec3) -> f64| points.iter().map(f).sum::<f64>() / n;
    let radius = mean(&|p| p.length()).max(1e-3);
    let horizontal = mean(&|p| p.x.hypot(p.z)).max(1e-3);
    let mut candidates = vec![
        LayerShell::Sphere {
            centre: origin,
            radius,
        },
        LayerShell::Cylinder {
            centre: origin,
            axis: DVec3::Y,
            radius: horizontal,
            half_height: None,
        },
    ];
    // A plane's points fit an ellipsoid or box that is unbounded along it; such a shell is
    // capped at MAX_SHELL_STRETCH × the farthest hit, which changes nothing where the layer has
    // content and keeps the shell finite where it has none.
    let farthest = points.iter().map(|p| p.length()).fold(1e-3, f64::max);
    let cap = DVec3::splat(MAX_SHELL_STRETCH * farthest);
    // Fitted in units of the mean distance, so the singularity test does not depend on scale.
    let scaled: Vec<DVec3> = points.iter().map(|p| *p / radius).collect();
    if let Some(radii) = fit_ellipsoid(&scaled) {
        candidates.push(LayerShell::Ellipsoid {
            centre: origin,
            radii: (radii * radius).min(cap),
        });
    }
    candidates.push(LayerShell::Box {
        centre: origin,
        half_extents: fit_box(points, radius).min(cap),
    });
    let errors: Vec<(&'static str, f64)> = candidates
        .iter()
        .map(|shell| (shell.kind(), fit_error(shell, origin, points)))
        .collect();
    // The simplest kind within the margin of the best fit.
    let lowest = errors.iter().map(|(_, e)| *e).fold(f64::INFINITY, f64::min);
    let best = errors
        .iter()
        .position(|(_, e)| *e * (1.0 - SIMPLER_SHELL_MARGIN) <= lowest)
        .unwrap_or(0);
    (candidates[best], errors[best].1, errors)
}

/// Least squares for `x²·u + y²·v + z²·w = 1` (radii `1/√u…`); `None` when the system is singular
/// or a coefficient is not positive (the points do not surround the origin on every axis).
fn fit_ellipsoid(points: &[DVec3]) -> Option<DVec3> {
    let mut m = glam::DMat3::ZERO;
    let mut rhs = DVec3::ZERO;
    for p in points {
        let q = *p * *p;
        m += glam::DMat3::from_cols(q * q.x, q * q.y, q * q.z);
        rhs += q;
    }
    if m.determinant().abs() < 1e-12 {
        return None;
    }
    let uvw = m.inverse() * rhs;
    (uvw.min_element() > 0.0 && uvw.is_finite()).then(|| DVec3::ONE / uvw.map(f64::sqrt))
}

/// An axis-aligned box about the origin: start from a cube of half edge `start`, assign every
/// point to the face its direction reaches first, set each half extent to the mean |coordinate|
/// of its points; ten rounds.
fn fit_box(points: &[DVec3], start: f64) -> DVec3 {
    let mut half = DVec3::splat(start);
    for _ in 0..10 {
        let mut sums = DVec3::ZERO;
        let mut counts = DVec3::ZERO;
        for p in points {
            let reach = p.abs() / half;
            let axis = if reach.x >= reach.y && reach.x >= reach.z {
                0
            } else if reach.y >= reach.z {
                1
            } else {
                2
            };
            sums[axis] += p.abs()[axis];
            counts[axis] += 1.0;
        }
        for axis in 0..3 {
            if counts[axis] > 0.0 {
                half[axis] = (sums[axis] / counts[axis]).max(1e-3);
            }
        }
    }
    half
}

/// Where `n` rays from `origin` along a Fibonacci sphere of directions meet `shell` (tests' hits).
#[cfg(test)]
pub(crate) fn shell_points(shell: &LayerShell, origin: DVec3, n: usize) -> Vec<DVec3> {
    (0..n)
        .filter_map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let a = i as f64 * 2.399_963_229_728_653;
            let d = DVec3::new(r * a.cos(), y, r * a.sin());
            shell.intersect(origin, d).map(|hit| hit.point)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on_shell(shell: &LayerShell) -> Vec<DVec3> {
        shell_points(shell, DVec3::ZERO, 2000)
    }

    #[test]
    fn each_kind_is_recovered_from_points_on_it() {
        let shells = [
            LayerShell::Sphere {
                centre: DVec3::ZERO,
                radius: 3.0,
            },
            LayerShell::Box {
                centre: DVec3::ZERO,
                half_extents: DVec3::new(4.0, 2.0, 6.0),
            },
            LayerShell::Ellipsoid {
                centre: DVec3::ZERO,
                radii: DVec3::new(2.0, 5.0, 3.0),
            },
        ];
        for shell in shells {
            let points = on_shell(&shell);
            let (fitted, rms, candidates) = fit_shell(DVec3::ZERO, &points);
            assert_eq!(fitted.kind(), shell.kind(), "{candidates:?}");
            assert!(rms < 1e-6, "{shell:?}: {rms} {candidates:?}");
        }
        // A cylinder's points (within a band, as a ring of columns is seen).
        let cylinder = LayerShell::Cylinder {
            centre: DVec3::ZERO,
            axis: DVec3::Y,
            radius: 3.5,
            half_height: None,
        };
        let points: Vec<DVec3> = on_shell(&cylinder)
            .into_iter()
            .filter(|p| p.y.abs() < 2.0)
            .collect();
        let (fitted, rms, candidates) = fit_shell(DVec3::ZERO, &points);
        assert_eq!(fitted.kind(), "cylinder", "{candidates:?}");
        assert!(rms < 1e-6, "{rms}");
    }

    #[test]
    fn the_measure_is_the_relative_depth_error() {
        let sphere = LayerShell::Sphere {
            centre: DVec3::ZERO,
            radius: 2.0,
        };
        // Points at 2·e^0.1 and 2·e^−0.1: RMS of ln(t/d) is exactly 0.1.
        let points = [
            DVec3::X * 2.0 * 0.1f64.exp(),
            DVec3::Y * 2.0 * (-0.1f64).exp(),
        ];
        assert!((fit_error(&sphere, DVec3::ZERO, &points) - 0.1).abs() < 1e-12);
    }
}
