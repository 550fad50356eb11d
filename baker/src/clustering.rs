//! Layer placement by LBG clustering of intersection distances (hybrid-rendering paper §4.2).
//!
//! The intersection records of the outgoing rays (every front-facing environment hit along each
//! ray, over all viewpoint samples at once so the layers are coherent across the view space) are
//! clustered by their distance to the lens object's centroid. LBG in one dimension: start from k
//! distances, assign every record to the nearest, move each centre to its cluster's mean, repeat
//! until no record changes cluster. Then, so that no object tears across two shells, each
//! environment object goes whole to the cluster holding most of its records; and a shell sits at
//! the mean distance of its records, where a continued ray counts only with its front-most record
//! in that cluster.
//!
//! The paper starts LBG from random distances; lensmap starts from evenly spaced quantiles of the
//! sorted distances, which is deterministic (the same inputs always give the same bake, whatever
//! the thread count) and never starts a centre outside the data.

use std::collections::HashMap;

/// One intersection record as the clustering sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceRecord {
    /// Distance from the EM origin (the lens object's centroid) to the hit, metres, finite ≥ 0.
    pub distance: f64,
    /// The environment object that was hit.
    pub object: u32,
    /// The outgoing ray the hit lies on (records of one ray are its continuation hits).
    pub ray: u64,
}

/// The layers found.
#[derive(Clone, Debug, PartialEq)]
pub struct Layers {
    /// Shell distances, nearest first (at most k; clusters left empty are dropped).
    pub distances: Vec<f64>,
    /// Which layer each environment object belongs to (index into `distances`).
    pub object_layer: HashMap<u32, usize>,
    /// LBG iterations until no record was reassigned.
    pub iterations: usize,
}

/// Errors in the clustering's input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClusteringError {
    /// No records, or k = 0.
    #[error(
        "layer clustering needs at least one intersection record and k ≥ 1 (got {records} records, k = {k})"
    )]
    Empty {
        /// Number of records.
        records: usize,
        /// Requested layers.
        k: usize,
    },
    /// A distance is NaN, infinite or negative.
    #[error(
        "intersection record {index} has distance {distance}; distances must be finite and ≥ 0"
    )]
    BadDistance {
        /// Record index.
        index: usize,
        /// The value.
        distance: f64,
    },
}

fn nearest(centres: &[f64], distance: f64) -> usize {
    // Ties go to the nearer (lower) centre: centres are sorted, so the first minimum.
    let mut best = 0;
    for (i, c) in centres.iter().enumerate() {
        if (distance - c).abs() < (distance - centres[best]).abs() {
            best = i;
        }
    }
    best
}

/// Clusters the records into at most `k` layers.
pub fn cluster_layers(records: &[DistanceRecord], k: usize) -> Result<Layers, ClusteringError> {
    if records.is_empty() || k == 0 {
        return Err(ClusteringError::Empty {
            records: records.len(),
            k,
        });
    }
    if let Some((index, r)) = records
        .iter()
        .enumerate()
        .find(|(_, r)| !r.distance.is_finite() || r.distance < 0.0)
    {
        return Err(ClusteringError::BadDistance {
            index,
            distance: r.distance,
        });
    }
    let mut sorted: Vec<f64> = records.iter().map(|r| r.distance).collect();
    sorted.sort_by(f64::total_cmp);
    let mut centres: Vec<f64> = (0..k)
        .map(|i| sorted[((2 * i + 1) * sorted.len()) / (2 * k)])
        .collect();
    centres.dedup();

    // LBG: assign, re-centre, until no record moves. Each pass lowers the within-cluster squared
    // error or leaves the assignment unchanged, so this terminates; the cap guards against
    // oscillation between equal-error assignments caused by rounding.
    let mut assignment: Vec<usize> = records
        .iter()
        .map(|r| nearest(&centres, r.distance))
        .collect();
    let mut iterations = 1;
    loop {
        let mut sums = vec![(0.0, 0usize); centres.len()];
        for (r, &a) in records.iter().zip(&assignment) {
            sums[a].0 += r.distance;
            sums[a].1 += 1;
        }
        for (c, (sum, count)) in centres.iter_mut().zip(&sums) {
            if *count > 0 {
                *c = sum / *count as f64;
            }
        }
        let next: Vec<usize> = records
            .iter()
            .map(|r| nearest(&centres, r.distance))
            .collect();
        if next == assignment || iterations >= 1000 {
            break;
        }
        assignment = next;
        iterations += 1;
    }

    // Whole objects: each goes to the cluster holding most of its records (ties: the nearer).
    let mut votes: HashMap<u32, Vec<usize>> = HashMap::new();
    for (r, &a) in records.iter().zip(&assignment) {
        votes
            .entry(r.object)
            .or_insert_with(|| vec![0; centres.len()])[a] += 1;
    }
    let object_cluster: HashMap<u32, usize> = votes
        .iter()
        .map(|(&object, counts)| {
            let best = (0..counts.len())
                .fold(0, |best, i| if counts[i] > counts[best] { i } else { best });
            (object, best)
        })
        .collect();

    // Shell distance: mean over the cluster's records, one per (ray, cluster): the front-most.
    let mut front: HashMap<(u64, usize), f64> = HashMap::new();
    for r in records {
        let cluster = object_cluster[&r.object];
        front
            .entry((r.ray, cluster))
            .and_modify(|d| *d = d.min(r.distance))
            .or_insert(r.distance);
    }
    let mut sums = vec![(0.0, 0usize); centres.len()];
    let mut keys: Vec<_> = front.into_iter().collect();
    keys.sort_by_key(|entry| entry.0); // fixed summation order: bit-identical results
    for ((_, cluster), distance) in keys {
        sums[cluster].0 += distance;
        sums[cluster].1 += 1;
    }
    let kept: Vec<usize> = (0..centres.len()).filter(|&c| sums[c].1 > 0).collect();
    let distances: Vec<f64> = kept.iter().map(|&c| sums[c].0 / sums[c].1 as f64).collect();
    let mut order: Vec<usize> = (0..kept.len()).collect();
    order.sort_by(|&a, &b| distances[a].total_cmp(&distances[b]));
    let renumber: HashMap<usize, usize> = order
        .iter()
        .enumerate()
        .map(|(new, &old)| (kept[old], new))
        .collect();
    Ok(Layers {
        distances: order.iter().map(|&i| distances[i]).collect(),
        object_layer: object_cluster
            .into_iter()
            .map(|(o, c)| (o, renumber[&c]))
            .collect(),
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(distance: f64, object: u32, ray: u64) -> DistanceRecord {
        DistanceRecord {
            distance,
            object,
            ray,
        }
    }

    #[test]
    fn separated_groups_give_their_means() {
        // Three objects at 2, 5 and 20 m with symmetric spread: the shells sit at the means.
        let mut records = Vec::new();
        let mut ray = 0;
        for (object, centre) in [(0, 2.0), (1, 5.0), (2, 20.0)] {
            for offset in [-0.3, -0.1, 0.0, 0.1, 0.3] {
                records.push(record(centre + offset, object, ray));
                ray += 1;
            }
        }
        let layers = cluster_layers(&records, 3).unwrap();
        assert_eq!(layers.distances.len(), 3);
        for (got, want) in layers.distances.iter().zip([2.0, 5.0, 20.0]) {
            assert!((got - want).abs() < 1e-12, "{:?}", layers.distances);
        }
        assert_eq!(layers.object_layer[&0], 0);
        assert_eq!(layers.object_layer[&2], 2);
    }

    #[test]
    fn an_object_is_never_split_across_layers() {
        // Object 1 spans 3..9 m; most of its records are near 8, so all of it joins the far
        // layer even though its near records would be closer to the 3 m layer.
        let mut records = vec![record(3.0, 0, 0), record(3.1, 0, 1), record(2.9, 0, 2)];
        records.extend(
            [3.4, 8.0, 8.1, 8.2, 7.9, 8.05]
                .iter()
                .enumerate()
                .map(|(i, &d)| record(d, 1, 10 + i as u64)),
        );
        let layers = cluster_layers(&records, 2).unwrap();
        assert_eq!(layers.object_layer[&0], 0);
        assert_eq!(layers.object_layer[&1], 1);
        // The far shell is the mean of object 1's records, the 3.4 m one included.
        let mean = (3.4 + 8.0 + 8.1 + 8.2 + 7.9 + 8.05) / 6.0;
        assert!(
            (layers.distances[1] - mean).abs() < 1e-12,
            "{:?}",
            layers.distances
        );
    }

    #[test]
    fn a_continued_ray_counts_once_per_layer_with_its_front_most_hit() {
        // Ray 7 passes through two surfaces of the same layer (4 and 6 m): only 4 counts.
        let records = vec![
            record(4.0, 0, 7),
            record(6.0, 0, 7),
            record(5.0, 0, 8),
            record(30.0, 1, 7),
        ];
        let layers = cluster_layers(&records, 2).unwrap();
        assert!(
            (layers.distances[0] - 4.5).abs() < 1e-12,
            "{:?}",
            layers.distances
        );
        assert!((layers.distances[1] - 30.0).abs() < 1e-12);
    }

    #[test]
    fn more_layers_than_distinct_distances_drops_empty_ones() {
        let records = vec![record(1.0, 0, 0), record(1.0, 0, 1), record(1.0, 0, 2)];
        let layers = cluster_layers(&records, 4).unwrap();
        assert_eq!(layers.distances, vec![1.0]);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            cluster_layers(&[], 2),
            Err(ClusteringError::Empty { .. })
        ));
        assert!(matches!(
            cluster_layers(&[record(1.0, 0, 0)], 0),
            Err(ClusteringError::Empty { .. })
        ));
        let e = cluster_layers(&[record(f64::NAN, 0, 0)], 1).unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
    }

    #[test]
    fn lbg_matches_brute_force_on_random_data() {
        // A second method: for k = 2 in 1D the optimal split is a threshold; LBG from quantiles
        // must reach a local optimum whose error is no worse than 1.05× the best threshold's.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for _ in 0..20 {
            let records: Vec<_> = (0..200)
                .map(|i| {
                    let centre = if rng.gen_bool(0.4) { 3.0 } else { 9.0 };
                    record(centre + rng.gen_range(-1.0..1.0), i, i as u64)
                })
                .collect();
            let layers = cluster_layers(&records, 2).unwrap();
            let error = |centres: &[f64]| -> f64 {
                records
                    .iter()
                    .map(|r| {
                        centres
                            .iter()
                            .map(|c| (r.distance - c).powi(2))
                            .fold(f64::INFINITY, f64::min)
                    })
                    .sum()
            };
            let mut sorted: Vec<f64> = records.iter().map(|r| r.distance).collect();
            sorted.sort_by(f64::total_cmp);
            let best = (1..sorted.len())
                .map(|s| {
                    let a = sorted[..s].iter().sum::<f64>() / s as f64;
                    let b = sorted[s..].iter().sum::<f64>() / (sorted.len() - s) as f64;
                    error(&[a, b])
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                error(&layers.distances) <= best * 1.05 + 1e-9,
                "{} vs {best}",
                error(&layers.distances)
            );
        }
    }
}
