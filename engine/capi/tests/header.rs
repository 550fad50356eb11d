//! The checked-in `include/lensmap.h` is what cbindgen generates from the source today: CI runs
//! this test, so a change to the ABI that forgets the header fails. `LENSMAP_BLESS=1` rewrites it.

use std::path::Path;

#[test]
fn the_checked_in_header_is_what_cbindgen_generates() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config =
        cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml parses");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("the header is UTF-8");
    let path = crate_dir.join("include/lensmap.h");
    if std::env::var("LENSMAP_BLESS").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &generated).expect("writing include/lensmap.h");
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "include/lensmap.h differs from what cbindgen generates from src/lib.rs; regenerate it with \
         LENSMAP_BLESS=1 cargo test -p lensmap-capi --test header"
    );
    // Every item is documented: each constant, type and function follows a comment.
    let mut previous = "";
    for line in generated.lines() {
        let is_constant = line.starts_with("#define LENSMAP_") && line.split(' ').count() == 3;
        let is_type =
            line.starts_with("typedef struct Lensmap") || line.starts_with("enum Lensmap");
        let is_function = !line.starts_with(' ')
            && !line.starts_with("//")
            && line
                .split_once(" lensmap_")
                .or_else(|| line.split_once("*lensmap_"))
                .is_some_and(|(_, rest)| rest.contains('('));
        if is_constant || is_type || is_function {
            assert!(
                previous.starts_with("//"),
                "undocumented item in lensmap.h: {line}"
            );
        }
        if !line.trim().is_empty() {
            previous = line.trim_start();
        }
    }
}
