//! lensmap's fuzz targets (run by `tools/scripts/fuzz.sh` with `cargo afl`, on stable Rust).
//! Each binary in `src/bin` feeds afl's inputs to one harness here; the harnesses call the
//! library's real entry points and are shared, by `#[path]`, with the regression tests that
//! replay the corpus and every finding in the normal suite
//! (`tests/tests/fuzz_regressions.rs`, `engine/capi/tests/fuzz_regressions.rs`).

pub mod budget;
pub mod capi;
pub mod readers;
