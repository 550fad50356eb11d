//! Fuzz target: a bake directory (`Bake::read`: manifest, EXR or compressed maps), packed as `readers::unpack` reads it.

use lensmap_fuzz::budget::Budget;
use lensmap_fuzz::readers::{Scratch, bake_directory};

#[global_allocator]
static ALLOCATOR: Budget = Budget::new();

fn main() {
    let scratch = Scratch::new("bake");
    // LENSMAP_FUZZ_SHOW=1: print each input's outcome (to triage a finding by hand).
    let show = std::env::var_os("LENSMAP_FUZZ_SHOW").is_some();
    afl::fuzz!(|data: &[u8]| {
        let outcome = bake_directory(&scratch, data);
        if show {
            eprintln!("{outcome:?}");
        }
    });
}
