//! The C ABI fuzz target's inputs in the normal suite: every file of its seed corpus and kept
//! queue (`tests/fuzz/corpus/capi`) and every minimised finding (`tests/fuzz/regressions/capi`)
//! run through the same harness the fuzzer ran (`tests/fuzz/src/capi.rs`), on one context with
//! validation on: no call returns `LENSMAP_RESULT_PANIC`, every failure says one line, no
//! validation message, and frames read back are finite (the harness asserts each).

#[path = "../../../tests/fuzz/src/capi.rs"]
mod capi;

use std::path::{Path, PathBuf};

use lensmap_capi::LensmapResult;

/// The files of `dir`, sorted (none when it does not exist).
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| entries.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    files.retain(|path| path.is_file());
    files.sort();
    files
}

#[test]
fn capi_corpus_and_findings_replay_cleanly() {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fuzz");
    let corpus = files(&fuzz.join("corpus/capi"));
    assert!(!corpus.is_empty(), "no C ABI corpus");
    let harness = capi::Harness::new(true);
    let mut succeeded = 0;
    for file in corpus.iter().chain(&files(&fuzz.join("regressions/capi"))) {
        let data = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        eprintln!("{}", file.display());
        let results = harness.run(&data);
        succeeded += results.iter().filter(|&&r| r == LensmapResult::Ok).count();
    }
    assert!(succeeded > 0, "no call of the corpus succeeded");
}
