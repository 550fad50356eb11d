//! The fuzz targets' inputs in the normal suite: every file of the seed corpus and kept queue
//! (`tests/fuzz/corpus/<target>`) and every minimised finding (`tests/fuzz/regressions/<target>`)
//! fed through the same harness the fuzzer ran (`tests/fuzz/src/readers.rs`: a scene file, a
//! scene asset, a bake directory). Each must end in `Ok` or one clean error line, never a panic;
//! each finding must also be refused naming its file and field.

#[allow(dead_code)] // the harness's `pack` is for the seed tools, not these tests
#[path = "../fuzz/src/readers.rs"]
mod readers;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use readers::Scratch;

/// The fuzz crate's folder.
fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files of `dir`, sorted (none when it does not exist).
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| entries.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    files.retain(|path| path.is_file());
    files.sort();
    files
}

/// Runs `target`'s harness on `file`: no panic, and an error is one non-empty line.
/// Returns the outcome.
fn replay(target: &str, scratch: &Scratch, file: &Path) -> Result<String, String> {
    let harness = readers::by_name(target).expect("a reader target");
    let data = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let outcome = catch_unwind(AssertUnwindSafe(|| harness(scratch, &data)))
        .unwrap_or_else(|_| panic!("{target}: {} panicked (see above)", file.display()));
    if let Err(message) = &outcome {
        assert!(
            !message.is_empty() && !message.contains('\n'),
            "{target}: {}: not one error line: {message:?}",
            file.display()
        );
    }
    outcome
}

/// Replays `target`'s corpus; asserts it is not empty and that some inputs are accepted (a
/// corpus of refusals alone would have stopped reaching the readers' insides).
fn replay_corpus(target: &str) {
    let scratch = Scratch::new(&format!("replay-{target}"));
    let corpus = files(&fuzz_dir().join("corpus").join(target));
    assert!(!corpus.is_empty(), "{target}: no corpus");
    let accepted = corpus
        .iter()
        .filter(|file| replay(target, &scratch, file).is_ok())
        .count();
    assert!(accepted > 0, "{target}: no input of the corpus is accepted");
}

#[test]
fn scene_corpus_loads_or_is_refused_cleanly() {
    replay_corpus("scene");
}

#[test]
fn asset_corpus_loads_or_is_refused_cleanly() {
    replay_corpus("asset");
}

#[test]
fn bake_corpus_reads_or_is_refused_cleanly() {
    replay_corpus("bake");
}

/// Each finding (tests/fuzz/regressions/<target>/<name>): refused with one line holding these
/// words (the file and field it names).
const FINDINGS: &[(&str, &str, &[&str])] = &[
    // An 803-byte EXR whose header claims 8388616×4 texels: the EXR decoder allocated all of
    // them (past the 512 MiB budget) before reading a chunk. As a lat-long sky and as a texture.
    (
        "asset",
        "exr-header-8388616x4-sky",
        &[
            "environment.latlong.path",
            "asset.exr",
            "8388616×4",
            "over the limit",
        ],
    ),
    (
        "asset",
        "exr-header-8388616x4-texture",
        &[
            "materials[1].diffuse.image",
            "asset.png",
            "8388616×4",
            "over the limit",
        ],
    ),
    // A bake whose cube-map EXR has a part header claiming 12124168×8 texels: read (past the
    // budget) before its size was compared with the manifest's.
    (
        "bake",
        "exr-part-header-12124168x8",
        &[
            "lens0-sphere.v000.layer0.exr",
            "level0/+X",
            "12124168×8",
            "8×8",
        ],
    ),
    // A compressed map whose header's payload length is 2⁶⁴ − 1: the message's arithmetic
    // overflowed (a panic).
    (
        "bake",
        "lmz-payload-length-u64-max",
        &[
            "lens0-sphere.v000.layer0.lmz",
            "truncated",
            "18446744073709551615",
        ],
    ),
];

#[test]
fn every_finding_is_refused_naming_its_field() {
    for (target, name, words) in FINDINGS {
        let scratch = Scratch::new(&format!("finding-{target}"));
        let file = fuzz_dir().join("regressions").join(target).join(name);
        let message = match replay(target, &scratch, &file) {
            Ok(outcome) => panic!("{target}/{name}: accepted ({outcome}), expected a refusal"),
            Err(message) => message,
        };
        for word in *words {
            assert!(
                message.contains(word),
                "{target}/{name}: the message does not name {word:?}: {message}"
            );
        }
    }
    // Every file under regressions/ (the reader targets) has its entry above.
    for target in ["scene", "asset", "bake"] {
        for file in files(&fuzz_dir().join("regressions").join(target)) {
            let name = file.file_name().unwrap().to_string_lossy().into_owned();
            assert!(
                FINDINGS.iter().any(|(t, n, _)| *t == target && *n == name),
                "{}: a finding without its entry in FINDINGS",
                file.display()
            );
        }
    }
}
