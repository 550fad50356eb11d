//! Layer placement over teapot-room's view space (hybrid-rendering paper §4.2, Figure 5): LBG
//! clustering of the teapot's intersection distances, seen from viewpoints spread over the whole
//! view space, finds the paper's structure — the cup, the ring of columns and the walls in three
//! separate layers — and never splits an environment object across two layers.

use lensmap::{
    layers::projected::em_origin,
    scene::Scene,
    trace::{TraceOptions, world::TraceScene},
};
use lensmap_baker::{
    bake::{BakeOptions, placement_cameras},
    placement::{lens_hits, place_layers},
};

#[test]
fn teapot_layers_are_cup_columns_walls_with_every_object_whole() {
    let scene = Scene::load_named("teapot-room").unwrap();
    let trace = TraceScene::new(&scene).unwrap();
    let lens = trace
        .lenses
        .iter()
        .position(|l| l.name == "teapot")
        .unwrap();
    let origin = em_origin(&scene, lens);
    let cameras = placement_cameras(&scene, &BakeOptions::default());
    assert_eq!(cameras.len(), 8);
    let hits = lens_hits(&trace, lens, &cameras, &TraceOptions::default()).unwrap();
    let placement = place_layers(&scene, "teapot", origin, &hits, 3).unwrap();
    let layers: Vec<&Vec<String>> = placement.layers.iter().map(|l| &l.objects).collect();
    assert_eq!(layers.len(), 3, "{placement:#?}");
    // Every object the teapot sees lies in exactly one layer.
    let mut all: Vec<&String> = layers.iter().flat_map(|l| l.iter()).collect();
    let count = all.len();
    all.sort();
    all.dedup();
    assert_eq!(all.len(), count, "an object in two layers: {layers:?}");
    let layer_of = |name: &str| layers.iter().position(|l| l.iter().any(|o| o == name));
    let cup = layer_of("cup-body").expect("the teapot sees the cup");
    assert_eq!(layer_of("cup-handle").unwrap_or(cup), cup, "{layers:?}");
    let columns: Vec<usize> = (0..8)
        .filter_map(|i| layer_of(&format!("column-{i}")))
        .collect();
    assert!(
        columns.len() >= 4,
        "the teapot sees the columns: {layers:?}"
    );
    assert!(columns.iter().all(|&c| c == columns[0]), "{layers:?}");
    let walls: Vec<usize> = ["wall-back", "wall-front", "wall-left", "wall-right"]
        .iter()
        .filter_map(|w| layer_of(w))
        .collect();
    assert!(!walls.is_empty(), "{layers:?}");
    assert!(walls.iter().all(|&w| w == walls[0]), "{layers:?}");
    // Nearest first: cup, columns, walls.
    assert_eq!((cup, columns[0], walls[0]), (0, 1, 2), "{layers:?}");
    // Each shell fits its layer: RMS relative depth error well under 1 (e^±0.5).
    for layer in &placement.layers {
        assert!(layer.rms_relative_error < 0.5, "{layer:?}");
    }
}
