//! The library stands without the command line: no text of `engine/src` or `baker/src` names a
//! command-line flag (front ends word the library's option errors themselves, see
//! `lensmap::options`); every option the library names (its `OptionName`s) is a field the
//! library declares where the name says, and its C ABI word a field of the header's structs (the
//! command line's flags are checked against its own command tree by `tools/src/words.rs`); and no
//! source or manifest in `engine/`, `baker/` or `shaders/` reads a file from `tools/`
//! (`include_str!`, `include_bytes!`, a path from `CARGO_MANIFEST_DIR`, a dependency), so the
//! library builds with `tools/` absent.

use std::path::Path;

use lensmap_tests::source::{rust_files, workspace};

/// The source without its `#[cfg(test)]` items: the text up to the first `#[cfg(test)]` line
/// that opens a test module (test modules sit at the end of a file in this codebase), and whole
/// files that are test modules (`tests.rs`, `…/tests/…`).
fn non_test_source(path: &Path) -> Option<String> {
    if path.file_name().is_some_and(|n| n == "tests.rs")
        || path.components().any(|c| c.as_os_str() == "tests")
    {
        return None;
    }
    let text = std::fs::read_to_string(path).expect("readable source");
    let end = text
        .match_indices("#[cfg(test)]")
        .map(|(i, _)| i)
        .find(|&i| text[i..].lines().nth(1).is_some_and(|l| l.contains("mod ")))
        .unwrap_or(text.len());
    Some(text[..end].to_owned())
}

/// The string literals of `source` (ordinary and raw), with their line numbers; comments are
/// skipped.
fn string_literals(source: &str) -> Vec<(usize, String)> {
    let bytes = source.as_bytes();
    let (mut i, mut line) = (0, 1);
    let mut found = Vec::new();
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => line += 1,
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
                continue;
            }
            b'\'' => {
                // A char literal ('"', '\'', 'x') or a lifetime: step over a quoted char.
                if bytes.get(i + 2) == Some(&b'\'') {
                    i += 3;
                    continue;
                }
                if bytes.get(i + 1) == Some(&b'\\') && bytes.get(i + 3) == Some(&b'\'') {
                    i += 4;
                    continue;
                }
            }
            b'r' if matches!(bytes.get(i + 1), Some(b'#') | Some(b'"'))
                && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_')) =>
            {
                let hashes = bytes[i + 1..].iter().take_while(|&&b| b == b'#').count();
                if bytes.get(i + 1 + hashes) == Some(&b'"') {
                    let start = i + 2 + hashes;
                    let close = format!("\"{}", "#".repeat(hashes));
                    let end = source[start..]
                        .find(&close)
                        .map_or(source.len(), |e| start + e);
                    found.push((line, source[start..end].to_owned()));
                    line += source[start..end].matches('\n').count();
                    i = end + close.len();
                    continue;
                }
            }
            b'"' => {
                let start = i + 1;
                let mut j = start;
                while j < bytes.len() && bytes[j] != b'"' {
                    j += if bytes[j] == b'\\' { 2 } else { 1 };
                }
                let end = j.min(bytes.len());
                found.push((line, source[start..end].to_owned()));
                line += source[start..end].matches('\n').count();
                i = end + 1;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    found
}

/// `--` followed by a letter: a command-line flag.
fn names_a_flag(text: &str) -> bool {
    text.match_indices("--")
        .any(|(i, _)| text[i + 2..].starts_with(|c: char| c.is_ascii_lowercase()))
}

#[test]
fn the_finder_sees_flags_in_strings_and_not_in_comments() {
    let source = "// a comment naming --resume\nlet a = \"give --em-size 7\";\nlet b = r#\"no flag -- here\"#;\nlet c = '\"'; let d = \"x --layers\";\n";
    let flagged: Vec<usize> = string_literals(source)
        .into_iter()
        .filter(|(_, text)| names_a_flag(text))
        .map(|(line, _)| line)
        .collect();
    assert_eq!(flagged, [2, 4]);
}

#[test]
fn no_library_text_names_a_command_line_flag() {
    let root = workspace();
    let mut offenders = Vec::new();
    for dir in ["engine/src", "baker/src"] {
        for path in rust_files(&root.join(dir)) {
            let Some(source) = non_test_source(&path) else {
                continue;
            };
            for (line, text) in string_literals(&source) {
                if names_a_flag(&text) {
                    let place = path.strip_prefix(&root).unwrap_or(&path).display();
                    offenders.push(format!("{place}:{line}: \"{text}\""));
                }
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "library text naming command-line flags (word options through lensmap::options::OptionWords instead):\n{}",
        offenders.join("\n")
    );
}

#[test]
fn nothing_in_the_library_reads_from_tools() {
    let root = workspace();
    let mut offenders = Vec::new();
    for dir in ["engine", "baker", "shaders"] {
        for path in rust_files(&root.join(dir)) {
            let text = std::fs::read_to_string(&path).expect("readable source");
            for (number, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                let reads_a_file = ["include_str!", "include_bytes!", "CARGO_MANIFEST_DIR"]
                    .iter()
                    .any(|reader| code.contains(reader));
                if reads_a_file && code.contains("tools") {
                    let place = path.strip_prefix(&root).unwrap_or(&path).display();
                    offenders.push(format!("{place}:{}: {}", number + 1, line.trim()));
                }
            }
        }
    }
    for manifest in [
        "engine/Cargo.toml",
        "engine/capi/Cargo.toml",
        "baker/Cargo.toml",
    ] {
        let text = std::fs::read_to_string(root.join(manifest)).expect("readable manifest");
        if text.contains("tools") {
            offenders.push(format!("{manifest} names tools"));
        }
    }
    assert!(
        offenders.is_empty(),
        "the library must build with tools/ absent:\n{}",
        offenders.join("\n")
    );
}

/// Every option of the library and the baker, as the messages name it.
fn every_option() -> Vec<lensmap::options::OptionName> {
    let mut all = lensmap::options::names::ALL.to_vec();
    all.extend_from_slice(lensmap_baker::bake::names::ALL);
    all
}

/// The text of the item `pub struct OWNER` or `pub enum OWNER` (its fields or variants), of
/// `pub fn OWNER(` for a function (its parameters), or of `pub fn NAME(` inside `impl TYPE` for
/// an owner `TYPE::NAME`, in the library's sources.
fn owner_text(sources: &[String], owner: &str) -> Option<String> {
    let (within, openings, close) = match owner.split_once("::") {
        Some((ty, function)) => (
            Some(format!("impl {ty} {{")),
            vec![format!("pub fn {function}(")],
            ')',
        ),
        None if owner.starts_with(char::is_lowercase) => {
            (None, vec![format!("pub fn {owner}(")], ')')
        }
        None => (
            None,
            vec![format!("pub struct {owner}"), format!("pub enum {owner}")],
            '}',
        ),
    };
    sources.iter().find_map(|source| {
        let from = match &within {
            Some(block) => source.find(block.as_str())?,
            None => 0,
        };
        // A type's name must end there (`BakeJob<'a>` has generics; `EmSize` is not `Em`).
        let ends = |rest: &str| close == ')' || rest.starts_with([' ', '<']);
        let start = openings
            .iter()
            .filter_map(|opening| {
                let (at, _) = source[from..]
                    .match_indices(opening.as_str())
                    .find(|(i, _)| ends(&source[from + i + opening.len()..]))?;
                Some(from + at + opening.len())
            })
            .min()?;
        let end = source[start..]
            .find(close)
            .map_or(source.len(), |e| start + e);
        Some(source[start..end].to_owned())
    })
}

/// Library → front ends: each option's field is declared where its name says (a field of its
/// struct, or a parameter of its function), and its C ABI field is a member of the header.
#[test]
fn every_option_names_a_field_the_library_declares() {
    let root = workspace();
    let sources: Vec<String> = ["engine/src", "baker/src"]
        .iter()
        .flat_map(|dir| rust_files(&root.join(dir)))
        .filter_map(|path| non_test_source(&path))
        .collect();
    let header =
        std::fs::read_to_string(root.join("engine/capi/include/lensmap.h")).expect("the C header");
    let mut offenders = Vec::new();
    for option in every_option() {
        match owner_text(&sources, option.owner) {
            None => offenders.push(format!("{}: no such struct or function", option.owner)),
            Some(text)
                if !text.contains(&format!("{}:", option.field))
                    && !text.contains(&format!("{}(", option.field)) =>
            {
                offenders.push(format!(
                    "{}.{}: no such field or parameter",
                    option.owner, option.field
                ))
            }
            Some(_) => {}
        }
        if let Some(field) = option.c_field {
            let declared = header.lines().any(|line| {
                let line = line.trim();
                !line.starts_with("//")
                    && (line.ends_with(&format!(" {field};"))
                        || line.ends_with(&format!("*{field};")))
            });
            if !declared {
                offenders.push(format!(
                    "C field {field} (of {}): not in lensmap.h",
                    option.field
                ));
            }
        }
        if let Some(prefix) = option.c_constants
            && !header.contains(&format!("#define {prefix}"))
        {
            offenders.push(format!("C constants {prefix}*: not in lensmap.h"));
        }
    }
    assert!(offenders.is_empty(), "{}", offenders.join("\n"));
}
