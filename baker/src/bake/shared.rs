//! Distant layers shared between lens objects (module docs of [`super`]): which clustered lens
//! objects share their farthest layer and on which shell (`share_far_layers`), and one map for
//! all of them in a hybrid scene (`share_maps`).

use std::collections::BTreeSet;

use glam::DVec3;
use lensmap::hybrid::HybridScene;
use lensmap::index::{LayerIndex, LayerRef, LensIndex};
use serde::{Deserialize, Serialize};

use super::plan::{Plan, PlannedLens};

/// One layer shared by several lens objects: one shell, one EM origin, one map per sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharedLayer {
    /// The layer of every lens object holding it (stored as `[lens, layer]`); the first owns
    /// the map (its file name and its EM origin, the first lens object's centroid).
    pub members: Vec<LayerRef>,
    /// The scene objects in it (those of every member's layer), sorted.
    pub objects: Vec<String>,
    /// Per member, the fit measure (RMS relative depth error) of the shared shell over the
    /// member's hits, seen from the shared EM origin.
    pub fit_rms: Vec<f64>,
    /// Per member, the fit measure of the shell it would have had alone.
    pub separate_fit_rms: Vec<f64>,
}

/// A shared shell may fit a member's hits worse than the member's own shell by at most this
/// much RMS relative depth error.
pub const SHARED_FIT_SLACK: f64 = 0.02;

/// Shares the farthest layer between clustered lens objects that see the same distant scene
/// objects there (the hybrid-rendering paper's shared distant layers): lens objects of two or
/// more layers whose farthest layer's objects are a subset or a superset of the first such lens
/// object's (the lid of a teapot sees two of the walls its body sees) form a group with it; one
/// shell is fitted to every member's hits
/// `far_hits[lens]` about the first member's EM origin, and taken when it fits each member
/// within [`SHARED_FIT_SLACK`] of the member's own shell. Rewrites the members' shells and fits.
pub(super) fn share_far_layers(
    lenses: &mut [PlannedLens],
    far_hits: &[Vec<DVec3>],
) -> Vec<SharedLayer> {
    // (members, the first member's far objects, the union of their far objects)
    let mut groups: Vec<(Vec<usize>, BTreeSet<String>, BTreeSet<String>)> = Vec::new();
    for (lens, planned) in lenses.iter().enumerate() {
        // A lens object with one layer has no distant layer of its own to share: its only
        // layer holds what is near it too.
        if planned.objects.len() < 2 || planned.shells.len() != planned.objects.len() {
            continue;
        }
        let Some(objects) = planned.objects.last() else {
            continue;
        };
        if objects.is_empty() || far_hits[lens].is_empty() {
            continue;
        }
        let objects: BTreeSet<String> = objects.iter().cloned().collect();
        match groups
            .iter_mut()
            .find(|(_, owner, _)| objects.is_subset(owner) || owner.is_subset(&objects))
        {
            Some((members, _, union)) => {
                members.push(lens);
                union.extend(objects);
            }
            None => groups.push((vec![lens], objects.clone(), objects)),
        }
    }
    let mut shared = Vec::new();
    for (group, _, objects) in groups.into_iter().filter(|(g, _, _)| g.len() >= 2) {
        let origin = lenses[group[0]].em_origin;
        let relative =
            |lens: usize| -> Vec<DVec3> { far_hits[lens].iter().map(|p| *p - origin).collect() };
        let points: Vec<DVec3> = group.iter().flat_map(|&lens| relative(lens)).collect();
        let (shell, _, _) = crate::placement::fit_shell(origin, &points);
        let fit_rms: Vec<f64> = group
            .iter()
            .map(|&lens| crate::placement::fit_error(&shell, origin, &relative(lens)))
            .collect();
        let separate_fit_rms: Vec<f64> = group
            .iter()
            .map(|&lens| lenses[lens].fit_rms.last().copied().unwrap_or(0.0))
            .collect();
        if fit_rms
            .iter()
            .zip(&separate_fit_rms)
            .any(|(shared, own)| *shared > own + SHARED_FIT_SLACK)
        {
            continue;
        }
        let members: Vec<LayerRef> = group
            .iter()
            .map(|&lens| {
                let farthest = LayerIndex::new(lenses[lens].shells.len() - 1);
                LensIndex::new(lens).layer(farthest)
            })
            .collect();
        for (&LayerRef { lens, layer }, &rms) in members.iter().zip(&fit_rms) {
            let planned = &mut lenses[lens.index()];
            planned.shells[layer.index()] = shell;
            planned.fit_rms[layer.index()] = rms;
        }
        shared.push(SharedLayer {
            objects: objects.into_iter().collect(),
            members,
            fit_rms,
            separate_fit_rms,
        });
    }
    shared
}

/// Gives every shared layer of `plan` in `hybrid` its owner's EM origin and (projected) maps,
/// as the bake will hold them: the owner projected that layer from its own origin.
pub(super) fn share_maps(hybrid: &mut HybridScene, plan: &Plan) {
    for shared in &plan.shared {
        let owner = shared.members[0];
        let owner_layers = &hybrid.lenses()[owner.lens.index()];
        let owner_layer = owner.layer.index();
        let origin = owner_layers.em_origins[owner_layer];
        let maps: Vec<_> = owner_layers
            .maps
            .iter()
            .map(|v| v[owner_layer].clone())
            .collect();
        for &LayerRef { lens, layer } in &shared.members[1..] {
            let mut layers = hybrid.lenses()[lens.index()].clone();
            layers.em_origins[layer.index()] = origin;
            for (v, map) in layers.maps.iter_mut().zip(&maps) {
                v[layer.index()] = map.clone();
            }
            hybrid.set_lens_layers(lens, layers);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::layers::{LayerShell, bake::map_file_name};

    /// Lens object `lens`'s layer `layer`.
    fn at(lens: usize, layer: usize) -> LayerRef {
        LensIndex::new(lens).layer(LayerIndex::new(layer))
    }

    /// Points of a room (an axis-aligned box about the world origin, half extents 10, 4, 10)
    /// seen from `origin` along a Fibonacci sphere of directions.
    fn room_hits(origin: DVec3, half_extents: DVec3) -> Vec<DVec3> {
        let room = LayerShell::Box {
            centre: DVec3::ZERO,
            half_extents,
        };
        crate::placement::shell_points(&room, origin, 800)
    }

    /// A clustered lens object at `origin` whose farthest layer holds `objects` and `hits`.
    fn planned(name: &str, origin: DVec3, objects: &[&str], hits: &[DVec3]) -> PlannedLens {
        let relative: Vec<DVec3> = hits.iter().map(|p| *p - origin).collect();
        let (shell, rms, _) = crate::placement::fit_shell(origin, &relative);
        PlannedLens {
            layering: lensmap::layers::Layering::Distance,
            name: name.into(),
            em_origin: origin,
            shells: vec![
                LayerShell::Sphere {
                    centre: origin,
                    radius: 0.5,
                },
                shell,
            ],
            source: "clustered".into(),
            objects: vec![
                vec!["near".into()],
                objects.iter().map(|o| o.to_string()).collect(),
            ],
            fit_rms: vec![0.1, rms],
            auto_psnr_db: Vec::new(),
        }
    }

    #[test]
    fn lens_objects_seeing_the_same_far_objects_share_one_far_layer() {
        let half = DVec3::new(10.0, 4.0, 10.0);
        let walls = ["ceiling", "wall-left", "wall-right"];
        let (a, b, c, d) = (
            DVec3::new(0.0, 0.3, 0.0),
            DVec3::new(1.3, 0.2, 0.5),
            DVec3::new(-2.0, 0.5, 1.0),
            DVec3::new(0.0, 0.8, 0.0),
        );
        let hits = [
            room_hits(a, half),
            room_hits(b, half),
            room_hits(c, half),
            room_hits(d, half),
        ];
        let mut lenses = vec![
            planned("teapot", a, &walls, &hits[0]),
            planned("cup", b, &walls, &hits[1]),
            planned("vase", c, &["ceiling", "wall-back"], &hits[2]),
            planned("lid", d, &["wall-left", "wall-right"], &hits[3]),
        ];
        let own_cup_shell = lenses[1].shells[1];
        let shared = share_far_layers(&mut lenses, &hits);
        // The teapot and the cup see the same walls, the lid two of them; the vase sees one that
        // they do not (and they see walls it does not): neither set holds the other.
        assert_eq!(shared.len(), 1, "{shared:?}");
        assert_eq!(shared[0].members, vec![at(0, 1), at(1, 1), at(3, 1)]);
        assert_eq!(shared[0].objects, walls);
        assert_eq!(lenses[0].shells[1], lenses[1].shells[1], "one shell");
        assert_ne!(lenses[1].shells[1], own_cup_shell);
        assert_ne!(
            lenses[2].shells[1], lenses[0].shells[1],
            "the vase keeps its own"
        );
        // Both about the teapot's centroid; each member's fit within the slack of its own.
        for (shared_rms, own) in shared[0].fit_rms.iter().zip(&shared[0].separate_fit_rms) {
            assert!(*shared_rms <= own + SHARED_FIT_SLACK, "{shared:?}");
        }
        assert_eq!(lenses[1].fit_rms[1], shared[0].fit_rms[1]);
        let plan = Plan {
            scene: "s".into(),
            scene_hash: String::new(),
            options_hash: String::new(),
            em_size: 16,
            lenses: lenses.clone(),
            shared: shared.clone(),
            terms: None,
        };
        assert_eq!(plan.map_owner(at(1, 1)), at(0, 1));
        assert_eq!(plan.map_owner(at(1, 0)), at(1, 0));
        assert_eq!(plan.layer_origins(LensIndex::new(1)), vec![b, a]);
        assert_eq!(
            plan.map_name(at(1, 1), 7),
            map_file_name(at(0, 1), "teapot", 7)
        );
        assert_eq!(
            plan.map_name(at(1, 0), 7),
            map_file_name(at(1, 0), "cup", 7)
        );
        assert!(plan.is_consistent());
        // A hand-edited staged plan: one lens object twice, a layer that does not exist, one
        // member, another shell: none is resumed.
        for members in [
            vec![at(0, 1), at(0, 1)],
            vec![at(0, 1), at(1, 5)],
            vec![at(0, 1)],
            vec![at(0, 1), at(1, 0)],
        ] {
            let mut edited = plan.clone();
            edited.shared[0].members = members.clone();
            assert!(!edited.is_consistent(), "{members:?}");
        }
        // A lens object of one layer: that layer holds what is near it too, so it is not shared.
        let mut one_layer = lenses.clone();
        for l in &mut one_layer {
            l.shells.remove(0);
            l.objects.remove(0);
            l.fit_rms.remove(0);
        }
        assert!(share_far_layers(&mut one_layer, &hits).is_empty());
        // The same objects, but one member's hits lie where no shell about the owner's origin
        // fits them (a sphere of 1 m about the cup, 1.4 m from the teapot): not shared.
        let small: Vec<DVec3> = room_hits(b, half)
            .iter()
            .map(|p| b + (*p - b).normalize())
            .collect();
        let hits = [hits[0].clone(), small];
        let mut lenses = vec![
            planned("teapot", a, &walls, &hits[0]),
            planned("cup", b, &walls, &hits[1]),
        ];
        let before = lenses.clone();
        assert!(share_far_layers(&mut lenses, &hits).is_empty());
        assert_eq!(lenses, before, "nothing rewritten");
    }
}
