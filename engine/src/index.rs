//! Typed indices for a scene's lens objects and their layers, so that a lens index and a layer
//! index cannot be swapped where they travel together (a shared layer's members, a bake's map
//! files, the compositor's draws, the baker's solves).
//!
//! Both are plain positions: [`LensIndex`] into a scene's lens objects, [`LayerIndex`] into one
//! lens object's layers; [`LayerRef`] names one layer of one lens object. They print as their
//! numbers (`Display` and `Debug`), serialize as them (a [`LayerRef`] as the pair
//! `[lens, layer]`), and index a slice through [`LensIndex::index`] and [`LayerIndex::index`].

use std::fmt;

use serde::{Deserialize, Serialize};

/// The index of a lens object: its position among a scene's lens objects in
/// [`crate::trace::world::TraceScene`] order (the order of `HybridScene::lenses`, a bake's lenses
/// and a frame's lens objects).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct LensIndex(usize);

/// The index of a layer of one lens object: layer 0 is the nearest shell, the last the farthest.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct LayerIndex(usize);

impl LensIndex {
    /// Lens object `index`.
    pub const fn new(index: usize) -> LensIndex {
        LensIndex(index)
    }

    /// The position, for indexing a per-lens-object list.
    pub const fn index(self) -> usize {
        self.0
    }

    /// Every lens object of a scene of `count`, in order.
    pub fn all(count: usize) -> impl DoubleEndedIterator<Item = LensIndex> + Clone {
        (0..count).map(LensIndex)
    }

    /// Layer `layer` of this lens object.
    pub const fn layer(self, layer: LayerIndex) -> LayerRef {
        LayerRef { lens: self, layer }
    }
}

impl LayerIndex {
    /// Layer `index` (0 = nearest).
    pub const fn new(index: usize) -> LayerIndex {
        LayerIndex(index)
    }

    /// The position, for indexing a per-layer list.
    pub const fn index(self) -> usize {
        self.0
    }

    /// Every layer of a lens object of `count` layers, nearest first.
    pub fn all(count: usize) -> impl DoubleEndedIterator<Item = LayerIndex> + Clone {
        (0..count).map(LayerIndex)
    }
}

/// One layer of one lens object: lens object `lens`'s layer `layer`.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(from = "(LensIndex, LayerIndex)", into = "(LensIndex, LayerIndex)")]
pub struct LayerRef {
    /// The lens object.
    pub lens: LensIndex,
    /// Its layer.
    pub layer: LayerIndex,
}

impl LayerRef {
    /// Lens object `lens`'s layer `layer`.
    pub const fn new(lens: LensIndex, layer: LayerIndex) -> LayerRef {
        LayerRef { lens, layer }
    }
}

impl From<(LensIndex, LayerIndex)> for LayerRef {
    fn from((lens, layer): (LensIndex, LayerIndex)) -> LayerRef {
        LayerRef { lens, layer }
    }
}

impl From<LayerRef> for (LensIndex, LayerIndex) {
    fn from(at: LayerRef) -> (LensIndex, LayerIndex) {
        (at.lens, at.layer)
    }
}

impl fmt::Display for LensIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl fmt::Debug for LensIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.0, f)
    }
}

impl fmt::Display for LayerIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl fmt::Debug for LayerIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&self.0, f)
    }
}

/// `lens 1, layer 0`.
impl fmt::Display for LayerRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "lens {}, layer {}", self.lens, self.layer)
    }
}

/// `(1, 0)`: the `(lens, layer)` pair.
impl fmt::Debug for LayerRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:?}, {:?})", self.lens, self.layer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_print_and_serialize_as_their_numbers() {
        let at = LensIndex::new(2).layer(LayerIndex::new(1));
        assert_eq!(at, LayerRef::new(LensIndex::new(2), LayerIndex::new(1)));
        assert_eq!((at.lens.index(), at.layer.index()), (2, 1));
        assert_eq!(format!("{} {:?}", at.lens, at.layer), "2 1");
        assert_eq!(format!("{at}"), "lens 2, layer 1");
        assert_eq!(format!("{:?}", vec![at]), "[(2, 1)]");
        let json = serde_json::to_string(&vec![at]).unwrap();
        assert_eq!(json, "[[2,1]]");
        assert_eq!(
            serde_json::from_str::<Vec<LayerRef>>(&json).unwrap(),
            vec![at]
        );
        assert_eq!(
            serde_json::to_string(&LayerIndex::new(3)).unwrap(),
            serde_json::to_string(&3usize).unwrap()
        );
        let lenses: Vec<usize> = LensIndex::all(3).map(LensIndex::index).collect();
        assert_eq!(lenses, [0, 1, 2]);
        assert!(LayerIndex::all(2).eq([LayerIndex::new(0), LayerIndex::new(1)]));
        assert!(
            LayerRef::new(LensIndex::new(0), LayerIndex::new(5)) < at,
            "lens first"
        );
    }
}
