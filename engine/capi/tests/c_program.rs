//! The C ABI from C and C++: `tests/c/abi_test.c` built with the system compiler under
//! `-Wall -Wextra -Werror` against `include/lensmap.h` and the cdylib cargo built beside this
//! test, then run (two create/render/free cycles and the misuse cases, validation on); and the
//! header compiled as C++17 with the same warnings.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The folder holding this test binary and the crate's `liblensmap_capi.so`.
fn deps_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    exe.parent().expect("a folder").to_path_buf()
}

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn temp_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensmap-capi-c-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a scratch folder");
    dir
}

#[test]
fn a_c_program_builds_without_warnings_and_passes() {
    let deps = deps_dir();
    assert!(
        deps.join("liblensmap_capi.so").is_file(),
        "cargo builds the cdylib beside the tests: {}",
        deps.display()
    );
    let scratch = temp_dir();
    let program = scratch.join("abi_test");
    let build = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(crate_dir().join("include"))
        .arg(crate_dir().join("tests/c/abi_test.c"))
        .arg("-L")
        .arg(&deps)
        .args(["-llensmap_capi", "-lm", "-o"])
        .arg(&program)
        .output()
        .expect("the system C compiler (cc) runs");
    assert!(
        build.status.success(),
        "cc failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
    let run = Command::new(&program)
        .arg("2")
        .env("LD_LIBRARY_PATH", &deps)
        .env("LENSMAP_VALIDATION", "1")
        .output()
        .expect("the C program runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("ok: 2 cycle(s)"), "{stdout}");
    assert!(
        !stderr.contains("validation"),
        "validation messages: {stderr}"
    );

    // The header is valid C++17 too (cpp_compat), warnings as errors.
    let cpp = scratch.join("header.cpp");
    std::fs::write(
        &cpp,
        "#include \"lensmap.h\"\nint main() { return lensmap_abi_version() == LENSMAP_ABI_VERSION ? 0 : 1; }\n",
    )
    .expect("writing header.cpp");
    let build = Command::new("c++")
        .args([
            "-std=c++17",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-fsyntax-only",
            "-I",
        ])
        .arg(crate_dir().join("include"))
        .arg(&cpp)
        .output()
        .expect("the system C++ compiler (c++) runs");
    assert!(
        build.status.success(),
        "c++ failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
    std::fs::remove_dir_all(&scratch).ok();
}
