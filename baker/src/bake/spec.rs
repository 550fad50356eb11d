//! Which samples a bake takes: sample lists (`all`, `I,J,K`, `A..B`, `A..=B`) and shards
//! (`I/N`: every N-th sample, starting at the I-th), for a scheduler's array job.

use lensmap::options::OptionError;

use super::failure::{BakeFailure, BakeInputError};
use super::names;

/// The view-space indices `spec` names for a view space of `count` samples: `all`, `I,J,K` or
/// `A..B` (B excluded) or `A..=B`; sorted, without repeats. A spec that names none of scene
/// `scene`'s samples is a [`BakeInputError::SampleList`].
pub fn parse_samples(spec: &str, count: usize, scene: &str) -> Result<Vec<usize>, BakeFailure> {
    let fix = |problem: String| {
        BakeFailure::from(BakeInputError::SampleList {
            spec: spec.to_owned(),
            problem,
            scene: scene.to_owned(),
            count,
        })
    };
    let index = |text: &str| -> Result<usize, BakeFailure> {
        let i: usize = text
            .trim()
            .parse()
            .map_err(|_| fix(format!("'{}' is not a sample index", text.trim())))?;
        if i >= count {
            return Err(fix(format!("sample {i} does not exist")));
        }
        Ok(i)
    };
    let mut samples: Vec<usize> = if spec.trim() == "all" {
        (0..count).collect()
    } else if let Some((a, b)) = spec.split_once("..") {
        let (inclusive, b) = match b.strip_prefix('=') {
            Some(b) => (true, b),
            None => (false, b),
        };
        let start = index(a)?;
        let end: usize = b
            .trim()
            .parse()
            .map_err(|_| fix(format!("'{}' is not a sample index", b.trim())))?;
        let end = if inclusive {
            end.checked_add(1)
                .ok_or_else(|| fix(format!("sample {end} does not exist")))?
        } else {
            end
        };
        if end > count {
            return Err(fix(format!("sample {} does not exist", end - 1)));
        }
        if end <= start {
            return Err(fix("the range is empty".into()));
        }
        (start..end).collect()
    } else {
        spec.split(',').map(index).collect::<Result<_, _>>()?
    };
    samples.sort_unstable();
    samples.dedup();
    Ok(samples)
}

/// One shard of a bake split `count` ways: the `index`-th (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// 1 ≤ index ≤ count.
    pub index: usize,
    /// The shards in all.
    pub count: usize,
}

/// `I/N`: shard I (1-based) of N. A spec that is not is an [`OptionError`] for option `shard`.
pub fn parse_shard(spec: &str) -> Result<Shard, BakeFailure> {
    let bad = || {
        BakeFailure::from(OptionError::new(
            names::SHARD,
            spec,
            "give I/N with 1 ≤ I ≤ N, e.g. 1/4 for the first of four shards",
        ))
    };
    let (i, n) = spec.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i == 0 || i > n {
        return Err(bad());
    }
    Ok(Shard { index: i, count: n })
}

/// The samples `shard` bakes: every count-th of `samples`, starting at the index-th.
pub fn shard_samples(samples: &[usize], shard: Shard) -> Vec<usize> {
    samples
        .iter()
        .enumerate()
        .filter(|(position, _)| position % shard.count == shard.index - 1)
        .map(|(_, &s)| s)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_lists_and_shards_parse_or_say_the_fix() {
        assert_eq!(parse_samples("all", 4, "s").unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(parse_samples("3,1,1", 4, "s").unwrap(), vec![1, 3]);
        assert_eq!(parse_samples("1..3", 4, "s").unwrap(), vec![1, 2]);
        assert_eq!(parse_samples("1..=3", 4, "s").unwrap(), vec![1, 2, 3]);
        for bad in ["4", "1..5", "2..2", "x", "1,,2"] {
            let BakeFailure::Input(e) = parse_samples(bad, 4, "s").unwrap_err() else {
                panic!("{bad}: not an input error");
            };
            let e = e.to_string();
            assert!(e.starts_with(&format!("`BakeJob.samples` = {bad}:")), "{e}");
            assert!(e.contains("0..4"), "{e}");
        }
        assert_eq!(parse_shard("2/3").unwrap(), Shard { index: 2, count: 3 });
        for bad in ["3/2", "0/0", "0/2", "1", "a/b"] {
            let BakeFailure::Option(e) = parse_shard(bad).unwrap_err() else {
                panic!("{bad}: not an option error");
            };
            assert_eq!((e.option, e.value.as_str()), (names::SHARD, bad));
        }
        let all: Vec<usize> = (0..7).collect();
        let shards: Vec<Vec<usize>> = (1..=3)
            .map(|i| shard_samples(&all, Shard { index: i, count: 3 }))
            .collect();
        assert_eq!(shards, vec![vec![0, 3, 6], vec![1, 4], vec![2, 5]]);
    }
}
