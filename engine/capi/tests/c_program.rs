//! The C ABI from C and C++: `tests/c/abi_test.c` built with the system compiler under
//! `-Wall -Wextra -Werror` against `include/lensmap.h` and the cdylib cargo built beside this
//! test, then run (two create/render/free cycles and the misuse cases, validation on); and the
//! header compiled as C++17 with the same warnings.

use std::path::Path;
use std::process::Command;

use lensmap_tests::c_abi;
use lensmap_tests::fixtures::temp_dir;

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn a_c_program_builds_without_warnings_and_passes() {
    lensmap_tests::name_the_binarys_driver_on_failure();
    let scratch = temp_dir("capi", "c-program");
    let program = scratch.join("abi_test");
    c_abi::build_host(
        "cc",
        &["-std=c11"],
        &crate_dir().join("tests/c/abi_test.c"),
        &["-lm"],
        &program,
    );
    let run = Command::new(&program)
        .arg("2")
        .env("LD_LIBRARY_PATH", c_abi::library_path())
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
        .arg(c_abi::include_dir())
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
