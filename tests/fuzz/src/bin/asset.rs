//! Fuzz target: a scene asset: the first byte picks an OBJ mesh, a lat-long sky or a texture (`readers::ASSET_KINDS`), the rest is the file.

use lensmap_fuzz::budget::Budget;
use lensmap_fuzz::readers::{Scratch, asset};

#[global_allocator]
static ALLOCATOR: Budget = Budget::new();

fn main() {
    let scratch = Scratch::new("asset");
    // LENSMAP_FUZZ_SHOW=1: print each input's outcome (to triage a finding by hand).
    let show = std::env::var_os("LENSMAP_FUZZ_SHOW").is_some();
    afl::fuzz!(|data: &[u8]| {
        let outcome = asset(&scratch, data);
        if show {
            eprintln!("{outcome:?}");
        }
    });
}
