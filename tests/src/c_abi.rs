//! Building C and C++ host programs against the C ABI: its header (`engine/capi/include`) and
//! the `liblensmap_capi.so` cargo builds beside a test binary whose crate depends on
//! lensmap-capi.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The folder of the running test binary, where cargo also puts `liblensmap_capi.so`.
pub fn deps_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test binary's path");
    exe.parent().expect("a folder").to_path_buf()
}

/// `LD_LIBRARY_PATH` for a host program: [`deps_dir`] (for `liblensmap_capi.so`) before the
/// test's own, so that a driver chosen through the environment (a privately installed one,
/// whose libraries `LD_LIBRARY_PATH` names) is still the one the host loads.
pub fn library_path() -> std::ffi::OsString {
    let mut path = deps_dir().into_os_string();
    if let Some(own) = std::env::var_os("LD_LIBRARY_PATH").filter(|p| !p.is_empty()) {
        path.push(":");
        path.push(own);
    }
    path
}

/// The repository's root folder.
pub fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is in the repository")
        .to_path_buf()
}

/// The C ABI's header folder.
pub fn include_dir() -> PathBuf {
    repository().join("engine/capi/include")
}

/// Compiles `source` into `program` with `compiler` and `flags`, warnings as errors
/// (`-Wall -Wextra -Werror`), against the C ABI's header, linked with the `liblensmap_capi.so`
/// beside this test binary and then `libraries` (`-lm`, `-lvulkan`, …). Fails the test, with the
/// compiler's errors, if the library is missing or the build fails.
pub fn build_host(
    compiler: &str,
    flags: &[&str],
    source: &Path,
    libraries: &[&str],
    program: &Path,
) {
    let deps = deps_dir();
    assert!(
        deps.join("liblensmap_capi.so").is_file(),
        "cargo builds the cdylib (a dependency of the test's crate) beside the tests: {}",
        deps.display()
    );
    let build = Command::new(compiler)
        .args(flags)
        .args(["-Wall", "-Wextra", "-Werror", "-I"])
        .arg(include_dir())
        .arg(source)
        .arg("-L")
        .arg(&deps)
        .arg("-llensmap_capi")
        .args(libraries)
        .arg("-o")
        .arg(program)
        .output()
        .unwrap_or_else(|e| panic!("the system compiler ({compiler}) does not run: {e}"));
    assert!(
        build.status.success(),
        "{compiler} failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
}
