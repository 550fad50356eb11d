//! Fuzz target: the C ABI's entry points on one context per process (`capi::Harness`), with
//! the Khronos validation layer on. The context is made inside the loop, after afl's fork
//! server has forked: a Vulkan device's driver threads do not survive a fork.

use std::cell::OnceCell;

use lensmap_fuzz::budget::Budget;
use lensmap_fuzz::capi::Harness;

#[global_allocator]
static ALLOCATOR: Budget = Budget::new();

thread_local! {
    static HARNESS: OnceCell<Harness> = const { OnceCell::new() };
}

fn main() {
    afl::fuzz!(|data: &[u8]| {
        HARNESS.with(|harness| {
            let results = harness.get_or_init(|| Harness::new(true)).run(data);
            if std::env::var_os("LENSMAP_FUZZ_SHOW").is_some() {
                eprintln!("{results:?}");
            }
        });
    });
}
