//! Scene errors: every way a scene file or one of its assets can be wrong, each rendered as one line
//! `<file>: <field>: <what is wrong>; <fix>` (with `:line:column` after the file for TOML errors).

use std::fmt;
use std::path::{Path, PathBuf};

/// A scene that cannot be loaded. `Display` is always exactly one line naming the file, the field
/// (a dotted path such as `objects[2].sphere.radius`), what is wrong and how to fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself cannot be read (missing, unreadable, not UTF-8) or the name is neither
    /// a built-in scene nor a file.
    #[error("{}: file: {problem}; {fix}", file.display())]
    Read {
        /// The scene file or name as given.
        file: PathBuf,
        /// What went wrong, one line.
        problem: String,
        /// How to fix it.
        fix: String,
    },
    /// The TOML does not parse or does not match the schema (syntax, unknown field, missing field,
    /// wrong type).
    #[error("{}:{line}:{column}: {field}: {problem}; {fix}", file.display())]
    Toml {
        /// The scene file.
        file: PathBuf,
        /// 1-based line of the offending text.
        line: usize,
        /// 1-based column (in characters) of the offending text.
        column: usize,
        /// Dotted path of the offending field, or `document` when none can be named.
        field: String,
        /// The parser's message, on one line.
        problem: String,
        /// How to fix it.
        fix: String,
    },
    /// The TOML is well formed but a value is invalid, or an asset it names (OBJ, EXR, PNG) is
    /// missing or broken.
    #[error("{}: {field}: {problem}; {fix}", file.display())]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// Dotted path of the offending field.
        field: String,
        /// What is wrong, one line.
        problem: String,
        /// How to fix it.
        fix: String,
    },
}

impl SceneError {
    /// An [`SceneError::Invalid`] with every text flattened to one line.
    pub(crate) fn invalid(
        file: &Path,
        field: impl fmt::Display,
        problem: impl fmt::Display,
        fix: impl fmt::Display,
    ) -> Self {
        SceneError::Invalid {
            file: file.to_path_buf(),
            field: one_line(&field.to_string()),
            problem: one_line(&problem.to_string()),
            fix: one_line(&fix.to_string()),
        }
    }

    /// The scene file (or name) the error is about.
    pub fn file(&self) -> &Path {
        match self {
            SceneError::Read { file, .. }
            | SceneError::Toml { file, .. }
            | SceneError::Invalid { file, .. } => file,
        }
    }

    /// The dotted path of the offending field (`file` for read errors).
    pub fn field(&self) -> &str {
        match self {
            SceneError::Read { .. } => "file",
            SceneError::Toml { field, .. } | SceneError::Invalid { field, .. } => field,
        }
    }

    /// The suggested fix.
    pub fn fix(&self) -> &str {
        match self {
            SceneError::Read { fix, .. }
            | SceneError::Toml { fix, .. }
            | SceneError::Invalid { fix, .. } => fix,
        }
    }

    /// Converts a TOML parse or schema error into a one-line error with line, column and field.
    pub(crate) fn from_toml(file: &Path, text: &str, error: &toml::de::Error) -> Self {
        let span = error.span().unwrap_or(0..0);
        let (line, column) = line_column(text, span.start.min(text.len()));
        let problem = one_line(error.message());
        let field = match error.span() {
            Some(span) => field_at(text, span, ErrorKind::of(&problem)),
            None => None,
        }
        .unwrap_or_else(|| "document".to_owned());
        let fix = if problem.starts_with("unknown field") {
            "remove the field or correct its spelling (the schema is in tools/scenes/README.md)"
        } else if problem.starts_with("missing field") {
            "add the field (the schema is in tools/scenes/README.md)"
        } else if problem.starts_with("invalid type") || problem.starts_with("invalid length") {
            "give a value of the expected type (numbers, [x, y, z] arrays, \"strings\")"
        } else {
            "correct the TOML at that position (https://toml.io)"
        };
        SceneError::Toml {
            file: file.to_path_buf(),
            line,
            column,
            field,
            problem,
            fix: fix.to_owned(),
        }
    }
}

/// Joins the lines of a multi-line message with `, ` so that every error stays on one line.
pub(crate) fn one_line(text: &str) -> String {
    text.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .collect::<Vec<_>>()
        .join(", ")
}

/// 1-based line and character column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
    (line, column)
}

/// What kind of TOML error a message describes, which decides how much of the field path the
/// error position names.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ErrorKind {
    /// The key at the error position is itself the problem (`unknown field`).
    UnknownKey,
    /// The value at the error position is wrong (type, length, missing field of an inline table).
    Value,
    /// A syntax error: the keys open up to the error position, nothing more.
    Syntax,
}

impl ErrorKind {
    fn of(message: &str) -> Self {
        if message.starts_with("unknown field") {
            ErrorKind::UnknownKey
        } else if [
            "missing field",
            "invalid type",
            "invalid value",
            "invalid length",
        ]
        .iter()
        .any(|p| message.starts_with(p))
        {
            ErrorKind::Value
        } else {
            ErrorKind::Syntax
        }
    }
}

/// Best-effort dotted field path at a byte offset: the last table header before it (with an index
/// for arrays of tables, counted from the headers seen so far), the keys leading to the offset on
/// its line (through inline tables), and for an unknown key the key itself.
fn field_at(text: &str, span: std::ops::Range<usize>, kind: ErrorKind) -> Option<String> {
    let offset = span.start.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[line_start..]
        .find('\n')
        .map_or(text.len(), |i| line_start + i);
    let current = text[line_start..line_end].trim();

    // Table headers before the offending line, in order, to name the table and count array items.
    let mut header: Option<String> = None;
    let mut counts: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    let mut scan = |line: &str| {
        let line = line.trim();
        if let Some(name) = line.strip_prefix("[[").and_then(|l| l.split("]]").next()) {
            let name = name.trim().to_owned();
            let index = counts.entry(name.clone()).or_insert(0);
            header = Some(format!("{name}[{index}]"));
            *index += 1;
        } else if let Some(name) = line.strip_prefix('[').and_then(|l| l.split(']').next()) {
            let name = name.trim();
            // A sub-table of the latest array item (`[objects.transform]` after `[[objects]]`).
            header = Some(
                match counts
                    .iter()
                    .find(|(k, _)| name.starts_with(&format!("{k}.")))
                {
                    Some((array, count)) => format!(
                        "{array}[{}]{}",
                        count.saturating_sub(1),
                        &name[array.len()..]
                    ),
                    None => name.to_owned(),
                },
            );
        }
    };
    for line in text[..line_start].lines() {
        scan(line);
    }
    if current.starts_with('[') {
        scan(current);
        return header;
    }
    let mut path: Vec<String> = header.into_iter().collect();
    path.extend(keys_before(&text[line_start..offset]));
    if kind == ErrorKind::UnknownKey {
        let key = text.get(span).unwrap_or("").trim().trim_matches('"');
        if !key.is_empty() {
            path.push(key.to_owned());
        }
    }
    (!path.is_empty()).then(|| path.join("."))
}

/// The keys still open at the end of `prefix` (the start of a line up to an error position):
/// `transform = { scale = ` gives `transform`, `scale`; keys of finished values are dropped.
fn keys_before(prefix: &str) -> Vec<String> {
    let mut open: Vec<(usize, String)> = Vec::new();
    let mut depth = 0usize;
    let mut token = String::new();
    let mut quote: Option<char> = None;
    for c in prefix.chars() {
        if let Some(q) = quote {
            if c == q {
                quote = None;
            } else {
                token.push(c);
            }
            continue;
        }
        match c {
            '"' | '\'' => quote = Some(c),
            '=' => {
                open.retain(|(d, _)| *d < depth);
                open.push((depth, token.trim().to_owned()));
                token.clear();
            }
            '{' | '[' => {
                depth += 1;
                token.clear();
            }
            '}' | ']' => {
                depth = depth.saturating_sub(1);
                token.clear();
            }
            ',' => {
                open.retain(|(d, _)| *d < depth);
                token.clear();
            }
            _ => token.push(c),
        }
    }
    open.into_iter()
        .map(|(_, key)| key)
        .filter(|key| !key.is_empty())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_paths_name_tables_and_array_items() {
        let text =
            "name = \"x\"\n[camera]\nfov = 3\n[[objects]]\nname = \"a\"\n[[objects]]\nspheer = 1\n";
        let offset = text.find("spheer").unwrap_or(0);
        let span = offset..offset + 6;
        assert_eq!(
            field_at(text, span, ErrorKind::UnknownKey).as_deref(),
            Some("objects[1].spheer")
        );
        let offset = text.find('3').unwrap_or(0);
        assert_eq!(
            field_at(text, offset..offset + 1, ErrorKind::Value).as_deref(),
            Some("camera.fov")
        );
        assert_eq!(line_column(text, offset), (3, 7));
        // A syntax error at the start of a line names the table only.
        let offset = text.find("fov").unwrap_or(0);
        assert_eq!(
            field_at(text, offset..offset + 1, ErrorKind::Syntax).as_deref(),
            Some("camera")
        );
    }

    #[test]
    fn keys_follow_inline_tables() {
        assert_eq!(
            keys_before("transform = { scale = "),
            ["transform", "scale"]
        );
        assert_eq!(keys_before("sphere = { radius = 1, "), ["sphere"]);
        assert_eq!(
            keys_before("diffuse = { checker = { a = [1, 2, 3], scale = "),
            ["diffuse", "checker", "scale"]
        );
        assert_eq!(keys_before("a = { b = \"x=y\", c = "), ["a", "c"]);
    }

    #[test]
    fn messages_are_one_line() {
        let error = SceneError::invalid(Path::new("a.toml"), "camera", "bad\nthing", "fix\nit");
        assert_eq!(error.to_string(), "a.toml: camera: bad, thing; fix, it");
    }
}
