//! Fuzz target: a scene file (`Scene::load`), with a valid OBJ, EXR and PNG beside it.

use lensmap_fuzz::budget::Budget;
use lensmap_fuzz::readers::{Scratch, scene_file};

#[global_allocator]
static ALLOCATOR: Budget = Budget::new();

fn main() {
    let scratch = Scratch::new("scene");
    // LENSMAP_FUZZ_SHOW=1: print each input's outcome (to triage a finding by hand).
    let show = std::env::var_os("LENSMAP_FUZZ_SHOW").is_some();
    afl::fuzz!(|data: &[u8]| {
        let outcome = scene_file(&scratch, data);
        if show {
            eprintln!("{outcome:?}");
        }
    });
}
